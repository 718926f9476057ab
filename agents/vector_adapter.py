"""``VectorEnvAdapter``: a Gymnasium ``VectorEnv`` in ``AutoresetMode.SAME_STEP`` (SB3's autoreset convention) as a
Stable-Baselines3 ``VecEnv``, so PPO trains on a native vector env as on a ``DummyVecEnv``."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from stable_baselines3.common.env_util import is_wrapped
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

MASKS_METHOD = "action_masks"  # what sb3-contrib's get_action_masks / is_masking_supported look for
SAME_STEP_HINT = (
    "ask for it with gym.make_vec(env_id, num_envs=N, vectorization_mode='sync' (or 'async'), "
    "vector_kwargs={'autoreset_mode': AutoresetMode.SAME_STEP}); a native infonav vector env takes "
    "gym.make_vec(env_id, num_envs=N, autoreset_mode=AutoresetMode.SAME_STEP)"
)


class VectorEnvAdapter(VecEnv):
    """A Gymnasium ``VectorEnv`` in ``AutoresetMode.SAME_STEP`` seen as an SB3 ``VecEnv`` (else ``ValueError``).

    Seeding as SB3's ``DummyVecEnv`` (``seed(s)``: sub-env ``i`` gets ``s + i`` at the next reset). A step's ``infos``
    hold only what SB3 reads (a dict per key and sub-env would cost more than a native step at 64+ envs): at an
    episode's end ``terminal_observation``, ``TimeLimit.truncated`` and the ``info_keywords`` of its final info.
    ``get_attr`` / ``set_attr`` / ``env_method`` reach the sub-envs of a sync / async vector env; a native one has none
    (use ``adapter.vector_env``). Misses raise ``AttributeError``, other refusals ``ValueError``.
    """

    def __init__(self, vector_env: VectorEnv, info_keywords: Sequence[str] = ()):
        if not isinstance(vector_env, VectorEnv):
            raise ValueError(f"VectorEnvAdapter wraps a gymnasium.vector.VectorEnv, got {type(vector_env).__name__}")
        mode = vector_env.metadata.get("autoreset_mode")
        if mode not in (AutoresetMode.SAME_STEP, AutoresetMode.SAME_STEP.value):
            raise ValueError(
                f"VectorEnvAdapter needs a vector env that resets a sub-env in the step its episode ends "
                f"(AutoresetMode.SAME_STEP, SB3's convention), but {type(vector_env.unwrapped).__name__} has "
                f"metadata['autoreset_mode'] = {mode!r}: {SAME_STEP_HINT}"
            )
        self.vector_env = vector_env
        self.info_keywords = tuple(info_keywords)
        self._base = vector_env.unwrapped  # Gymnasium's vector wrappers do not forward get_attr, call, envs
        self._info: dict[str, Any] = {}
        self._actions = None
        super().__init__(vector_env.num_envs, vector_env.single_observation_space, vector_env.single_action_space)
        self.metadata = dict(vector_env.metadata)

    def reset(self):
        """Reset every sub-env with the seeds of ``seed()`` and the options of ``set_options()``, once."""
        observations, self._info = self.vector_env.reset(seed=self._common_seed(), options=self._common_options())
        self._reset_seeds()
        self._reset_options()
        return observations

    def _common_seed(self) -> int | list | None:
        """``seed()``'s ``s, s + 1, ...`` as Gymnasium's ``reset(seed=s)``; other seeds as a list; None for none."""
        seeds = self._seeds
        if all(seed is None for seed in seeds):
            return None
        first = seeds[0]
        if first is not None and seeds == list(range(first, first + self.num_envs)):
            return first
        return list(seeds)

    def _common_options(self) -> dict | None:
        """The one options dict a Gymnasium vector env takes for all its sub-envs; None for none."""
        first = self._options[0]
        if any(options != first for options in self._options):
            raise ValueError(
                f"VectorEnvAdapter: a Gymnasium vector env takes one options dict for all sub-envs, but "
                f"set_options gave them different ones: {self._options}"
            )
        return first or None

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        """One step of every sub-env: observations, float32 rewards, dones and the infos of the class."""
        observations, rewards, terminated, truncated, self._info = self.vector_env.step(self._actions)
        dones = np.logical_or(terminated, truncated)
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        ended = np.flatnonzero(dones)
        if ended.size:
            final_observations = self._final_entry(self._info, "final_obs", ended)
            final_info = self._final_entry(self._info, "final_info", ended) if self.info_keywords else {}
            for index in ended.tolist():
                infos[index]["terminal_observation"] = final_observations[index]
                infos[index]["TimeLimit.truncated"] = bool(truncated[index] and not terminated[index])
                for key in self.info_keywords:
                    infos[index][key] = self._final_value(final_info, key, index)
        return observations, np.asarray(rewards, dtype=np.float32), dones, infos

    def _final_entry(self, info: dict, key: str, ended: np.ndarray):
        """``info[key]`` (``final_obs`` or ``final_info``), which every sub-env in ``ended`` must have."""
        present = np.asarray(info.get(f"_{key}", np.zeros(self.num_envs, dtype=bool)), dtype=bool)
        missing = ended[~present[ended]]
        if missing.size:
            raise ValueError(
                f"sub-env {int(missing[0])} of {type(self._base).__name__} ended its episode but the step's info "
                f"has no {key!r} for it (info['_{key}'] is False): a SAME_STEP vector env must return it"
            )
        return info[key]

    def _final_value(self, final_info: dict, key: str, index: int):
        if key not in final_info or not final_info.get(f"_{key}", np.ones(self.num_envs, dtype=bool))[index]:
            raise ValueError(
                f"info keyword {key!r} is not in the final info of sub-env {index} of {type(self._base).__name__} "
                f"(its keys: {sorted(name for name in final_info if not name.startswith('_'))})"
            )
        return final_info[key][index]

    def close(self) -> None:
        self.vector_env.close()

    def action_masks(self) -> np.ndarray:
        """Valid actions (N, n) bool: the vector env's ``action_masks()``, else the last ``info["action_mask"]`` (a row
        without a valid action: all ``True``)."""
        own = getattr(self._base, MASKS_METHOD, None)
        if callable(own):
            return self._checked_masks(np.asarray(own(), dtype=bool), "action_masks()")
        if not isinstance(self.action_space, gym.spaces.Discrete):
            raise ValueError(
                f"VectorEnvAdapter makes masks from info['action_mask'] for a Discrete action space only; "
                f"{type(self._base).__name__} has {self.action_space} and no action_masks()"
            )
        if "action_mask" not in self._info:
            return np.ones((self.num_envs, int(self.action_space.n)), dtype=bool)
        masks = self._checked_masks(np.asarray(self._info["action_mask"], dtype=bool), "info['action_mask']")
        present = np.asarray(self._info.get("_action_mask", np.ones(self.num_envs, dtype=bool)), dtype=bool)
        masks[~(present & masks.any(axis=1))] = True
        return masks

    def _checked_masks(self, masks: np.ndarray, source: str) -> np.ndarray:
        if isinstance(self.action_space, gym.spaces.Discrete):
            expected = (self.num_envs, int(self.action_space.n))
            if masks.shape != expected:
                raise ValueError(
                    f"{source} of {type(self._base).__name__} has shape {masks.shape}, expected {expected} "
                    "(one row of valid actions per sub-env)"
                )
        return masks.copy()

    def _rows(self, indices) -> list[int]:
        rows = list(self._get_indices(indices))
        outside = [row for row in rows if not 0 <= row < self.num_envs]
        if outside:
            raise ValueError(f"sub-env indices {outside} are outside 0..{self.num_envs - 1}")
        return rows

    def _all_rows(self, indices, what: str) -> None:
        if self._rows(indices) != list(range(self.num_envs)):
            raise ValueError(
                f"{what} of a Gymnasium vector env acts on every sub-env: pass indices=None, got {indices!r}"
            )

    def _native_refusal(self, what: str, name: str) -> str:
        return (
            f"{type(self._base).__name__} is a native vector env without sub-env objects: it has no per-sub-env "
            f"{what} {name!r}; use adapter.vector_env.{name}"
        )

    def has_attr(self, attr_name: str) -> bool:
        """``True`` for ``action_masks`` (the adapter gives ``MaskablePPO`` masks), else as ``get_attr`` finds it."""
        return attr_name == MASKS_METHOD or super().has_attr(attr_name)

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """Attribute ``attr_name`` of each sub-env asked for (``render_mode``: the vector env's)."""
        rows = self._rows(indices)
        if attr_name == "render_mode":
            return [self.vector_env.render_mode] * len(rows)
        if not callable(getattr(self._base, "get_attr", None)):
            raise AttributeError(self._native_refusal("attribute", attr_name))
        values = self._base.get_attr(attr_name)
        return [values[row] for row in rows]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        """Set ``attr_name`` to ``value`` in every sub-env (Gymnasium sets all at once: indices must be None)."""
        if not callable(getattr(self._base, "set_attr", None)):
            raise ValueError(self._native_refusal("attribute", attr_name))
        self._all_rows(indices, f"set_attr({attr_name!r})")
        self._base.set_attr(attr_name, [value] * self.num_envs)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs):
        """``action_masks``: the rows asked for, one (len, n) array; any other method: called on every sub-env."""
        if method_name == MASKS_METHOD:
            return self.action_masks()[self._rows(indices)]
        if not callable(getattr(self._base, "call", None)):
            raise ValueError(self._native_refusal("method", method_name))
        self._all_rows(indices, f"env_method({method_name!r})")
        return list(self._base.call(method_name, *method_args, **method_kwargs))

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices=None) -> list[bool]:
        """Whether each sub-env is wrapped in ``wrapper_class`` (native: never; async: unknown, ``ValueError``)."""
        rows = self._rows(indices)
        envs = getattr(self._base, "envs", None)
        if envs is not None:
            return [is_wrapped(envs[row], wrapper_class) for row in rows]
        if callable(getattr(self._base, "call", None)):
            raise ValueError(
                f"{type(self._base).__name__} keeps its sub-envs in worker processes: their wrappers are unknown here"
            )
        return [False] * len(rows)

    def get_images(self) -> Sequence[np.ndarray | None]:
        """One frame per sub-env from the vector env's ``render()`` (``render_mode="rgb_array"``), for SB3's tiling."""
        if self.render_mode != "rgb_array":
            warnings.warn(f"The render mode is {self.render_mode}, but get_images needs 'rgb_array'", stacklevel=2)
            return [None] * self.num_envs
        frames = self.vector_env.render()
        if frames is None or len(frames) != self.num_envs:
            count = None if frames is None else len(frames)
            raise ValueError(
                f"{type(self._base).__name__}.render() gave {count} frames, expected one per sub-env ({self.num_envs})"
            )
        return list(frames)


def monitored_vec_env(vector_env: VectorEnv, seed: int | None, info_keywords: Sequence[str] = ()) -> VecMonitor:
    """``vector_env`` as an SB3 ``VecEnv`` under ``VecMonitor``; sub-env ``i`` seeded ``seed + i``."""
    adapter = VectorEnvAdapter(vector_env, info_keywords)
    if seed is not None:
        adapter.seed(seed)
    return VecMonitor(adapter, info_keywords=tuple(info_keywords))
