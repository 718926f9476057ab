"""``TeamVecEnv``: every robot of a batched team env as one slot of a Stable-Baselines3 ``VecEnv``, so PPO learns one
policy shared by all robots, each slot with its robot's reward and mask."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from stable_baselines3.common.vec_env import VecMonitor

from agents.learning_curve import METRIC_KEY, EndedEpisodeMetrics, team_view
from agents.vector_adapter import MASKS_METHOD, VectorEnvAdapter
from infonav_gym.envs.traits import main_metric_of
from infonav_gym.registry import PARALLEL, api_of, make_vector_env


class RobotSlots(VectorEnv):
    """A team vector env's robots as sub-envs: slot ``copy * R + k`` is robot ``k`` of copy ``copy``.

    Arrays are the team env's reshaped to (N R, ...); the info holds only ``final_obs`` per slot and the ended
    episodes' main metric (``final_info[METRIC_KEY]``); the team env's whole last info is ``team_info``.
    """

    def __init__(self, team: VectorEnv):
        self.team = team
        self.n_copies, self.n_robots = team.num_envs, len(team.agents)
        self.num_envs = self.n_copies * self.n_robots
        self.single_observation_space = team.single_observation_space
        self.single_action_space = team.single_action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = team.metadata
        self.render_mode = team.render_mode
        self.team_info: dict = {}
        view = team_view(team.agents, team.team_info_keys)
        self.episode_metrics = EndedEpisodeMetrics(main_metric_of(team), self.n_copies, view)

    def reset(self, *, seed=None, options=None):
        """Reset every copy; a list seeds each slot, a copy's robots sharing its seed (else ``ValueError``)."""
        observations, self.team_info = self.team.reset(seed=self._copy_seeds(seed), options=options)
        self.episode_metrics.reset()
        return observations.reshape(self.num_envs, -1), {}

    def _copy_seeds(self, seed):
        if not isinstance(seed, (list, tuple)):
            return seed  # None, or an int: copy i gets seed + i
        by_copy = [list(seed[copy * self.n_robots : (copy + 1) * self.n_robots]) for copy in range(self.n_copies)]
        if len(seed) != self.num_envs or any(seeds != seeds[:1] * self.n_robots for seeds in by_copy):
            raise ValueError(
                f"RobotSlots: one seed per slot ({self.num_envs}), the same for the {self.n_robots} robots of a "
                f"copy, got {seed!r}"
            )
        return [seeds[0] for seeds in by_copy]

    def step(self, actions):
        """Step every copy with the slots' actions (N R,) (``ValueError`` unless one per slot)."""
        actions = np.asarray(actions)
        if actions.shape != (self.num_envs,):
            raise ValueError(f"expected one action per slot, shape ({self.num_envs},), got shape {actions.shape}")
        step = self.team.step(actions.reshape(self.n_copies, self.n_robots))
        observations, rewards, terminations, truncations, self.team_info = step
        info = {}
        ended = np.logical_or(terminations, truncations).any(axis=1)  # a copy's robots end together
        metrics = self.episode_metrics.step(self.team_info, ended)
        if metrics is not None:
            final_obs = np.full(self.num_envs, None, dtype=object)
            for copy in np.flatnonzero(ended).tolist():
                final_obs[copy * self.n_robots : (copy + 1) * self.n_robots] = list(self.team_info["final_obs"][copy])
            slots_ended = np.repeat(ended, self.n_robots)
            final_info = {METRIC_KEY: np.repeat(metrics, self.n_robots), f"_{METRIC_KEY}": slots_ended}
            info = {
                "final_obs": final_obs,
                "_final_obs": slots_ended,
                "final_info": final_info,
                "_final_info": slots_ended,
            }
        per_slot = (array.reshape(self.num_envs) for array in (rewards, terminations, truncations))
        return observations.reshape(self.num_envs, -1), *per_slot, info

    def action_masks(self) -> np.ndarray:
        """Every slot's valid actions (N R, A) bool."""
        return self.team.action_masks().reshape(self.num_envs, -1)

    def close_extras(self, **kwargs) -> None:
        self.team.close()


class TeamVecEnv(VectorEnvAdapter):
    """``n_envs`` copies of a PettingZoo parallel env ``env_id``, batched; slot ``copy * n_robots + k`` is robot ``k``,
    copy ``i`` first reset with seed ``seed + i`` (``ValueError`` for no copy, an id that is not a parallel env with a
    vector env, or a bad config). ``get_attr`` / ``set_attr`` / ``env_method`` act on the team env every slot shares."""

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
        team = make_vector_env(env_id, n_envs, autoreset_mode=AutoresetMode.SAME_STEP, **(env_kwargs or {}))
        self.possible_agents = list(team.agents)
        self.n_robots = len(self.possible_agents)
        super().__init__(RobotSlots(team), (METRIC_KEY,))
        if seed is not None:
            self.seed(seed)

    @property
    def team(self) -> VectorEnv:
        """The team vector env every slot belongs to."""
        return self.vector_env.team

    def seed(self, seed: int | None = None) -> list[int]:
        """Seed copy ``i`` with ``seed + i`` at the next ``reset()`` (``None``: a random ``seed``); each slot's seed."""
        if seed is None:
            seed = int(np.random.randint(0, np.iinfo(np.uint32).max, dtype=np.uint32))
        self._seeds = [seed + slot // self.n_robots for slot in range(self.num_envs)]
        return list(self._seeds)

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """Each slot's ``attr_name``: ``agent`` is its robot's name, anything else the team env's (one for all)."""
        slots = self._rows(indices)
        if attr_name == "agent":
            return [self.possible_agents[slot % self.n_robots] for slot in slots]
        return [getattr(self.team, attr_name)] * len(slots)

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        """Set ``attr_name`` of the team env, which every slot shares (``ValueError`` unless ``indices`` are all)."""
        self._all_rows(indices, f"set_attr({attr_name!r})")
        setattr(self.team, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        """``action_masks``: the slots' rows; another method of the team env runs once, every slot gets its result."""
        if method_name == MASKS_METHOD:
            return super().env_method(method_name, indices=indices)
        return [getattr(self.team, method_name)(*method_args, **method_kwargs)] * len(self._rows(indices))


def make_team_vec_env(
    n_envs: int, seed: int | None = 0, env_kwargs: dict | None = None, env_id: str = "cooperative_localization_v0"
) -> VecMonitor:
    """A ``TeamVecEnv`` under SB3's ``VecMonitor``, which records each robot's episode return and length (the logs)."""
    return VecMonitor(TeamVecEnv(n_envs, seed, env_kwargs, env_id), info_keywords=(METRIC_KEY,))
