"""``TeamVecEnv``: every robot of copies of a PettingZoo parallel env as one slot of a Stable-Baselines3 ``VecEnv``.

PPO on it learns one policy for all robots (parameter sharing): it sees ``n_envs * n_robots``
single-robot envs with the same spaces, each with its robot's own reward and action mask.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

from infonav_gym.registry import PARALLEL, api_of, make_env


class RobotSlot:
    """One slot of a ``TeamVecEnv``, a robot of one copy: its own ``action_masks()``; other attributes its copy's.

    What ``VecEnv.get_attr`` and ``env_method`` reach, as a ``DummyVecEnv`` reaches its envs.
    """

    ROBOT_METHODS = ("action_masks",)  # per robot; every other method is its copy's parallel env's

    def __init__(self, team: TeamVecEnv, index: int):
        self.team, self.index = team, index
        self.copy, robot = divmod(index, team.n_robots)
        self.agent = team.possible_agents[robot]
        self.env = team.envs[self.copy]

    def action_masks(self) -> np.ndarray:
        """The valid actions of the robot now (``infos[agent]["action_mask"]`` of the last step or reset), as bool."""
        return self.team._masks[self.index].copy()

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name == "env":  # not set yet (copying, unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.env, name)


class TeamVecEnv(VecEnv):
    """``n_envs`` copies of a PettingZoo parallel env; slot ``copy * n_robots + k`` is robot ``k`` of ``copy``.

    Copy ``i`` is reset with seed ``seed + i`` the first time and continues its own generator on the
    automatic resets after that, so the seed fixes every rollout. All robots of a copy end their
    episode together (truncation at ``max_cycles``): then each of its slots gets
    ``info["terminal_observation"]`` and ``info["TimeLimit.truncated"]`` and the copy is reset, as
    SB3's ``DummyVecEnv`` does. ``action_masks()`` gives every slot's valid actions to ``MaskablePPO``.

    Args:
        n_envs: copies of the team env.
        seed: seed of copy 0 (copy ``i`` gets ``seed + i``); ``None``: unseeded.
        env_kwargs: the config of every copy (keys of ``CooperativeLocalizationEnv.default_config()``).
        env_id: the registry id of the PettingZoo parallel env to copy.
    """

    def __init__(
        self,
        n_envs: int,
        seed: int | None = 0,
        env_kwargs: dict | None = None,
        env_id: str = "cooperative_localization_v0",
    ):
        if n_envs < 1:
            raise ValueError(f"n_envs must be >= 1, got {n_envs}")
        if api_of(env_id) != PARALLEL:
            raise ValueError(f"TeamVecEnv needs a registered PettingZoo parallel env, got {env_id!r}")
        self.envs = [make_env(env_id, **(env_kwargs or {})) for _ in range(n_envs)]
        team = self.envs[0]
        self.possible_agents = list(team.possible_agents)
        self.n_robots = len(self.possible_agents)
        observation_space = team.observation_space(self.possible_agents[0])
        action_space = team.action_space(self.possible_agents[0])
        for agent in self.possible_agents:
            if team.observation_space(agent) != observation_space or team.action_space(agent) != action_space:
                raise ValueError(
                    f"one policy for every robot needs the same spaces: {agent} has {team.observation_space(agent)} "
                    f"and {team.action_space(agent)}, {self.possible_agents[0]} {observation_space} and {action_space}"
                )
        self.slots = [RobotSlot(self, index) for index in range(n_envs * self.n_robots)]
        super().__init__(len(self.slots), observation_space, action_space)
        self._observations = np.zeros((self.num_envs, *observation_space.shape), dtype=observation_space.dtype)
        self._masks = np.ones((self.num_envs, action_space.n), dtype=bool)
        self._actions = None
        if seed is not None:
            self.seed(seed)

    def seed(self, seed: int | None = None) -> list[int]:
        """Seed copy ``i`` with ``seed + i`` at the next ``reset()`` (``None``: a random ``seed``); each slot's seed."""
        if seed is None:
            seed = int(np.random.randint(0, np.iinfo(np.uint32).max, dtype=np.uint32))
        self._seeds = [seed + slot.copy for slot in self.slots]
        return list(self._seeds)

    def reset(self) -> np.ndarray:
        for copy, env in enumerate(self.envs):
            first = copy * self.n_robots
            observations, infos = env.reset(seed=self._seeds[first], options=self._options[first] or None)
            self._store(copy, observations, infos)
            self.reset_infos[first : first + self.n_robots] = [infos[agent] for agent in self.possible_agents]
        self._reset_seeds()
        self._reset_options()
        return self._observations.copy()

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        if actions.shape != (self.num_envs,):
            raise ValueError(f"expected one action per slot, shape ({self.num_envs},), got shape {actions.shape}")
        self._actions = actions

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        if self._actions is None:
            raise RuntimeError("TeamVecEnv: call step_async(actions) before step_wait()")
        rewards = np.zeros(self.num_envs, dtype=np.float32)
        dones = np.zeros(self.num_envs, dtype=bool)
        slot_infos = [{} for _ in range(self.num_envs)]
        for copy, env in enumerate(self.envs):
            first = copy * self.n_robots
            actions = {agent: int(self._actions[first + k]) for k, agent in enumerate(self.possible_agents)}
            observations, step_rewards, terminations, truncations, infos = env.step(actions)
            for k, agent in enumerate(self.possible_agents):
                slot = first + k
                rewards[slot] = step_rewards[agent]
                dones[slot] = terminations[agent] or truncations[agent]
                truncated = truncations[agent] and not terminations[agent]
                slot_infos[slot] = {**infos[agent], "TimeLimit.truncated": truncated}
            ended = dones[first : first + self.n_robots]
            if ended.any():
                if not ended.all():
                    raise RuntimeError(
                        f"TeamVecEnv needs every robot to end together, but in copy {copy} only "
                        f"{[agent for agent, done in zip(self.possible_agents, ended) if done]} ended"
                    )
                for k, agent in enumerate(self.possible_agents):
                    slot_infos[first + k]["terminal_observation"] = observations[agent]
                observations, infos = env.reset()
                self.reset_infos[first : first + self.n_robots] = [infos[agent] for agent in self.possible_agents]
            self._store(copy, observations, infos)
        self._actions = None
        return self._observations.copy(), rewards, dones, slot_infos

    def _store(self, copy: int, observations: dict, infos: dict) -> None:
        first = copy * self.n_robots
        for k, agent in enumerate(self.possible_agents):
            self._observations[first + k] = observations[agent]
            self._masks[first + k] = infos[agent]["action_mask"]

    def action_masks(self) -> np.ndarray:
        """The valid actions of every slot, ``(num_envs, n_actions)`` bool: each robot's ``action_mask`` now."""
        return self._masks.copy()

    def close(self) -> None:
        for env in self.envs:
            env.close()

    def get_images(self) -> list[np.ndarray | None]:
        """One frame per copy (the whole team) when the copies render ``rgb_array``."""
        if self.render_mode != "rgb_array":
            warnings.warn(f"the render mode is {self.render_mode!r}: frames need render_mode='rgb_array'", stacklevel=2)
            return [None for _ in self.envs]
        return [env.render() for env in self.envs]

    def _slots_at(self, indices) -> list[RobotSlot]:
        return [self.slots[index] for index in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """Each slot's ``attr_name``: ``action_masks`` is the robot's, anything else its copy's parallel env's."""
        return [getattr(slot, attr_name) for slot in self._slots_at(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        """Set ``attr_name`` of the parallel env of every copy the slots belong to."""
        for copy in sorted({slot.copy for slot in self._slots_at(indices)}):
            setattr(self.envs[copy], attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        """Per slot: ``action_masks`` is the robot's; a method of the parallel env runs once per copy and every
        slot of that copy gets its result."""
        results, by_copy = [], {}
        for slot in self._slots_at(indices):
            if method_name in RobotSlot.ROBOT_METHODS:
                results.append(getattr(slot, method_name)(*method_args, **method_kwargs))
                continue
            if slot.copy not in by_copy:
                by_copy[slot.copy] = getattr(slot.env, method_name)(*method_args, **method_kwargs)
            results.append(by_copy[slot.copy])
        return results

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        """Always ``False``: the copies are PettingZoo parallel envs, which Gymnasium wrappers do not wrap."""
        return [False for _ in self._get_indices(indices)]


def make_team_vec_env(
    n_envs: int, seed: int | None = 0, env_kwargs: dict | None = None, env_id: str = "cooperative_localization_v0"
) -> VecMonitor:
    """A ``TeamVecEnv`` under SB3's ``VecMonitor``, which records each robot's episode return and length (the logs)."""
    return VecMonitor(TeamVecEnv(n_envs, seed, env_kwargs, env_id))
