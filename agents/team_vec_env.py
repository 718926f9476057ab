"""``TeamVecEnv``: every robot of a batched team env as one slot of a Stable-Baselines3 ``VecEnv``.

PPO on it learns one policy for all robots (parameter sharing): it sees ``n_envs * n_robots``
single-robot envs with the same spaces, each with its robot's own reward and action mask. The copies
run as one native vector env of the team env (``make_vector_env``, e.g. ``CooperativeLocalizationVectorEnv``),
stepped at once on stacked arrays; this view only reshapes its (N, R, ...) arrays to (N R, ...).
"""

from __future__ import annotations

import functools
import warnings
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

from infonav_gym.registry import PARALLEL, api_of, make_vector_env

MASKS_METHOD = "action_masks"  # what MaskablePPO asks every slot for; answered per robot


class TeamVecEnv(VecEnv):
    """``n_envs`` copies of a PettingZoo parallel env, batched; slot ``copy * n_robots + k`` is robot ``k`` of ``copy``.

    Copy ``i`` is reset with seed ``seed + i`` the first time and continues its own generator on the
    automatic resets after that, so the seed fixes every rollout. All robots of a copy end their
    episode together (truncation at ``max_cycles``): the step that ends it resets the copy at once
    (the vector env's ``SAME_STEP`` autoreset) and each of its slots gets ``info["terminal_observation"]``
    and ``info["TimeLimit.truncated"]``, as SB3's ``DummyVecEnv`` does. The other slots' infos are empty:
    the vector env's whole info of the last reset or step is ``batched_infos`` (arrays (N, R, ...)).
    ``action_masks()`` gives every slot's valid actions to ``MaskablePPO``.

    Args:
        n_envs: copies of the team env.
        seed: seed of copy 0 (copy ``i`` gets ``seed + i``); ``None``: unseeded.
        env_kwargs: the config of every copy (keys of ``CooperativeLocalizationEnv.default_config()``).
        env_id: the registry id of a PettingZoo parallel env with a native vector env.

    Raises:
        ValueError: for ``n_envs < 1``, an id that is not a parallel env with a vector env, or a bad config.
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
        self.team = make_vector_env(env_id, n_envs, autoreset_mode=AutoresetMode.SAME_STEP, **(env_kwargs or {}))
        self.possible_agents = list(self.team.agents)
        self.n_envs, self.n_robots = n_envs, len(self.possible_agents)
        super().__init__(n_envs * self.n_robots, self.team.single_observation_space, self.team.single_action_space)
        self.batched_infos: dict | None = None
        self._actions = None
        if seed is not None:
            self.seed(seed)

    def seed(self, seed: int | None = None) -> list[int]:
        """Seed copy ``i`` with ``seed + i`` at the next ``reset()`` (``None``: a random ``seed``); each slot's seed."""
        if seed is None:
            seed = int(np.random.randint(0, np.iinfo(np.uint32).max, dtype=np.uint32))
        self._seeds = [seed + slot // self.n_robots for slot in range(self.num_envs)]
        return list(self._seeds)

    def reset(self) -> np.ndarray:
        """Reset every copy (with the seeds set by ``seed``, then with none); the observations (N R, obs)."""
        options = next((options for options in self._options if options), None)
        observations, self.batched_infos = self.team.reset(seed=self._seeds[:: self.n_robots], options=options)
        self._reset_seeds()
        self._reset_options()
        return observations.reshape(self.num_envs, -1)

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        if actions.shape != (self.num_envs,):
            raise ValueError(f"expected one action per slot, shape ({self.num_envs},), got shape {actions.shape}")
        self._actions = actions

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        if self._actions is None:
            raise RuntimeError("TeamVecEnv: call step_async(actions) before step_wait()")
        actions, self._actions = self._actions.reshape(self.n_envs, self.n_robots), None
        observations, rewards, terminations, truncations, info = self.team.step(actions)
        self.batched_infos = info
        dones = (terminations | truncations).ravel()
        slot_infos = [{} for _ in range(self.num_envs)]
        for slot in np.flatnonzero(dones).tolist():
            copy, robot = divmod(slot, self.n_robots)
            slot_infos[slot] = {
                "terminal_observation": info["final_obs"][copy][robot],
                "TimeLimit.truncated": bool(truncations[copy, robot] and not terminations[copy, robot]),
            }
        return observations.reshape(self.num_envs, -1), rewards.astype(np.float32).ravel(), dones, slot_infos

    def action_masks(self) -> np.ndarray:
        """The valid actions of every slot, ``(num_envs, n_actions)`` bool: each robot's ``action_mask`` now."""
        return self.team.action_masks().reshape(self.num_envs, -1)

    def close(self) -> None:
        self.team.close()

    def get_images(self) -> list[np.ndarray | None]:
        """No frames: the batched team env does not render (render a parallel env)."""
        warnings.warn("TeamVecEnv: the batched team env does not render; render a parallel env", stacklevel=2)
        return [None for _ in range(self.n_envs)]

    def _slot_masks(self, slot: int) -> np.ndarray:
        return self.action_masks()[slot]

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """Each slot's ``attr_name``: ``action_masks`` and ``agent`` (its robot's name) are its robot's, anything else
        the batched env's (one for all)."""
        slots = self._get_indices(indices)
        if attr_name == MASKS_METHOD:
            return [functools.partial(self._slot_masks, slot) for slot in slots]
        if attr_name == "agent":
            return [self.possible_agents[slot % self.n_robots] for slot in slots]
        value = getattr(self.team, attr_name)
        return [value for _ in slots]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        """Set ``attr_name`` of the batched env, which every slot shares: ``indices`` must be None or every slot.

        Raises:
            ValueError: for indices that leave some slot out (one copy cannot differ from the others).
        """
        slots = list(self._get_indices(indices))
        if sorted(slots) != list(range(self.num_envs)):
            raise ValueError(
                f"TeamVecEnv.set_attr({attr_name!r}): all {self.num_envs} slots share one batched env, so set it for "
                f"every slot (indices=None), got indices {slots}"
            )
        setattr(self.team, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        """Per slot: ``action_masks`` is the robot's; another method of the batched env runs once, and every slot
        gets its result."""
        slots = list(self._get_indices(indices))
        if method_name == MASKS_METHOD:
            return list(self.action_masks()[slots])
        result = getattr(self.team, method_name)(*method_args, **method_kwargs)
        return [result for _ in slots]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        """Always ``False``: the slots are robots of a batched env, which Gymnasium wrappers do not wrap."""
        return [False for _ in self._get_indices(indices)]


def make_team_vec_env(
    n_envs: int, seed: int | None = 0, env_kwargs: dict | None = None, env_id: str = "cooperative_localization_v0"
) -> VecMonitor:
    """A ``TeamVecEnv`` under SB3's ``VecMonitor``, which records each robot's episode return and length (the logs)."""
    return VecMonitor(TeamVecEnv(n_envs, seed, env_kwargs, env_id))
