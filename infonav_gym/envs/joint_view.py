"""``JointTeamEnv``: a team env (PettingZoo parallel) as one Gymnasium env, the whole team one agent, so that tools
made for Gymnasium (Minari's ``DataCollector`` and ``recover_environment``) record and recreate a team episode as one
episode. ``joint_spec`` is its ``EnvSpec``: ``gym.make(joint_spec(env_id, **config))`` needs no registration, in any
process, and a dataset keeps the spec as JSON."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec

from infonav_gym.registry import PARALLEL, api_of, make_env

JOINT_ID = "infonav/JointTeam-v0"  # the id of every joint spec; its kwargs name the team env
ENTRY_POINT = "infonav_gym.envs.joint_view:JointTeamEnv"
REWARDS_KEY = "rewards"  # info: every robot's reward of the step (R,), zeros at reset


def joint_spec(env_id: str, **config) -> EnvSpec:
    """The spec ``gym.make`` turns into the ``JointTeamEnv`` of team env ``env_id`` with ``config``."""
    return EnvSpec(JOINT_ID, entry_point=ENTRY_POINT, kwargs={"env_id": env_id, **config}, disable_env_checker=True)


class JointTeamEnv(gym.Env):
    """The team env ``env_id`` (``team``, its PettingZoo parallel env) seen whole: robot ``k`` is row ``k``.

    Observation (R, D) float32: each robot's observation. Action: ``MultiDiscrete``, one action per robot. Reward: the
    sum of the robots' rewards. The episode ends when the team's does. Info: ``{robot: that robot's info}`` and
    ``"rewards"`` (R,), each robot's reward. ``reset(seed=s)`` is the team env's ``reset(seed=s)``.
    """

    def __init__(self, env_id: str, render_mode: str | None = None, **config):
        if api_of(env_id) != PARALLEL:
            raise ValueError(f"JointTeamEnv views a team (PettingZoo parallel) env, and {env_id!r} is not one")
        self.team = make_env(env_id, render_mode=render_mode, **config)
        self.robots = list(self.team.possible_agents)
        robot_space = self.team.observation_space(self.robots[0])
        rows = (len(self.robots), 1)
        self.observation_space = spaces.Box(
            np.tile(robot_space.low, rows), np.tile(robot_space.high, rows), dtype=robot_space.dtype
        )
        self.action_space = spaces.MultiDiscrete([self.team.action_space(robot).n for robot in self.robots])
        self.metadata = self.team.metadata
        self.render_mode = render_mode
        self.config = self.team.config

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        observations, infos = self.team.reset(seed=seed, options=options)
        return self._stacked(observations), {**infos, REWARDS_KEY: np.zeros(len(self.robots))}

    def step(self, action):
        observations, rewards, terminations, truncations, infos = self.team.step(
            {robot: int(chosen) for robot, chosen in zip(self.robots, np.asarray(action).reshape(-1))}
        )
        rewards = np.array([rewards[robot] for robot in self.robots])
        terminated = all(terminations.values())
        truncated = not terminated and all(truncations.values())
        return self._stacked(observations), float(rewards.sum()), terminated, truncated, {**infos, REWARDS_KEY: rewards}

    def render(self):
        return self.team.render()

    def close(self):
        self.team.close()

    def _stacked(self, observations: dict) -> np.ndarray:
        return np.stack([observations[robot] for robot in self.robots])


def recorded_env(spec: EnvSpec) -> tuple[str, dict]:
    """The env id and config a spec makes (``joint_spec``'s: the team env's), as ``make_env`` takes them."""
    config = dict(spec.kwargs)
    if spec.id == JOINT_ID:
        return config.pop("env_id"), config
    config.pop("render_mode", None)
    return spec.id, config
