"""``InfoNavVectorEnv``: what the native vector envs share (seeds per sub-env, action checks, masks, the API).

A subclass builds its single env (which checks the config) and calls ``_configure``; it keeps the current
decision in ``self._decision`` (with an ``action_mask`` (N, A)), starts episodes in ``_reset_copies`` (returning
their static geometry) with their first outputs from ``_reset_outputs``, and ends its ``step`` with
``_finish_step``, which makes the resets of its ``autoreset_mode``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from infonav_gym.envs.base import accepts_action
from infonav_gym.envs.vector_infos import autoreset_mode_of, final_step_infos, set_rows
from infonav_gym.envs.vector_view import FirstCopyView


def is_seed(value) -> bool:
    """Whether ``value`` is a seed of one sub-env: None, or an int >= 0 (not a bool)."""
    return value is None or (isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 0)


def sub_env_seeds(seed, num_envs: int, owner: str) -> list[int | None]:
    """One seed per sub-env: ``s`` gives sub-env ``i`` the seed ``s + i``; a list gives one seed (or None) each.

    Raises:
        ValueError: naming ``owner``, for a seed that is not None, an int >= 0 or a list of ``num_envs`` of them.
    """
    if is_seed(seed):
        return [None if seed is None else int(seed) + copy for copy in range(num_envs)]
    seeds = list(seed) if isinstance(seed, (list, tuple)) else []
    if len(seeds) != num_envs or not all(is_seed(item) for item in seeds):
        raise ValueError(
            f"seed of {owner}.reset must be None, an int >= 0 or a list of {num_envs} such seeds (one per sub-env), "
            f"got {seed!r}"
        )
    return [None if item is None else int(item) for item in seeds]


class InfoNavVectorEnv(VectorEnv):
    """Base of the native vector envs: N sub-envs of one single env, each with its own generator.

    ``autoreset_mode`` is ``NEXT_STEP`` or ``SAME_STEP`` per instance (``metadata["autoreset_mode"]``). With a
    ``render_mode``, ``render()`` draws sub-env 0 as its single env does (``FirstCopyView``): the subclass calls
    ``_view_restarts`` when sub-env 0 starts an episode and ``_view_steps`` when it acts.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}
    AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
    single_env: type  # the env class a subclass batches: ``class MyVectorEnv(InfoNavVectorEnv, single_env=MyEnv)``
    _view: FirstCopyView | None = None  # set by ``_configure``; None before, so a half-built env closes cleanly

    def __init_subclass__(cls, single_env: type | None = None, **kwargs):
        super().__init_subclass__(**kwargs)
        if single_env is not None:  # its render modes and fps, NEXT_STEP autoreset by default
            cls.single_env = single_env
            cls.metadata = {
                **InfoNavVectorEnv.metadata,
                **{key: single_env.metadata[key] for key in ("render_modes", "render_fps")},
            }

    def _configure(self, num_envs: int, render_mode: str | None, autoreset_mode, config: dict) -> gym.Env:
        """Check the vector arguments; take the config (and a ``gym.Env``'s spaces) of ``single_env(**config)``.

        Returns:
            That single env (it checked the config as it always does).

        Raises:
            ValueError: for ``num_envs`` that is not an int >= 1, a render mode the single env does not have,
                an autoreset mode other than ``AUTORESET_MODES``, or a config the single env rejects.
        """
        owner = type(self).__name__
        if type(num_envs) is not int or num_envs < 1:
            raise ValueError(f"num_envs of {owner} must be an int >= 1, got {num_envs!r}")
        self.autoreset_mode = autoreset_mode_of(autoreset_mode, self.AUTORESET_MODES, owner)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        single_env = type(self).single_env
        single = single_env(**config)
        self._view = None if render_mode is None else FirstCopyView(single_env(render_mode, **config))
        self.config = single.config
        self.num_envs = num_envs
        self.render_mode = render_mode
        if isinstance(single, gym.Env):  # a parallel env's subclass sets its own (N, R, ...) spaces
            self.single_observation_space = single.observation_space
            self.single_action_space = single.action_space
            self.observation_space = batch_space(self.single_observation_space, num_envs)
            self.action_space = batch_space(self.single_action_space, num_envs)
        self._np_randoms: list[np.random.Generator | None] = [None] * num_envs
        self._decision = self._geometry = None
        self._prev_done = np.zeros(num_envs, dtype=bool)
        return single

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset every sub-env: seed ``s`` gives sub-env ``i`` the seed ``s + i``; a list gives one seed (or None) each.

        Raises:
            ValueError: for a seed that is not None, an int >= 0 or a list of N ints / None, or any options.
        """
        self._seed_sub_envs(seed, options)
        everyone = np.arange(self.num_envs)
        self._geometry = self._reset_copies(everyone)
        self._prev_done[:] = False
        return self._reset_outputs(everyone, self._geometry)

    def _begin_step(self, actions) -> tuple[np.ndarray, np.ndarray]:
        """``(acting, chosen)``: which sub-envs act in this step (with ``NEXT_STEP``, not those starting again) and
        the action each takes, -1 for a no-op (a masked action, per ``invalid_action``).

        Raises:
            RuntimeError: before the first ``reset``.
            ValueError: for actions that are not N integers of the action space, or, with
                ``invalid_action="raise"``, a masked action (each naming its sub-env).
        """
        actions = self._checked_actions(actions)
        acting = ~self._prev_done
        chosen = self._accepted_actions(actions, acting)
        self._view_steps(actions, acting)
        return acting, chosen

    def _finish_step(self, ended: np.ndarray, step_outputs) -> tuple[np.ndarray, dict]:
        """The observations and infos of a step in which the sub-envs ``ended`` (N,) bool ended their episodes.

        ``step_outputs(copies, geometry)`` gives the observations and infos of ``copies`` at their new decisions.
        ``NEXT_STEP``: the sub-envs that ended at the last step start again now, then all decide. ``SAME_STEP``: all
        decide, then those that ended start again, their last observation and info in ``final_obs`` / ``final_info``.
        """
        everyone = np.arange(self.num_envs)
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            resetting = np.flatnonzero(self._prev_done)
            if resetting.size:
                self._geometry = self._geometry.with_copies(resetting, self._reset_copies(resetting))
            self._prev_done = ended
            return step_outputs(everyone, self._geometry)
        observation, info = step_outputs(everyone, self._geometry)
        copies = np.flatnonzero(ended)
        if copies.size:
            final_infos = final_step_infos(observation, info, ended)
            geometry = self._reset_copies(copies)
            self._geometry = self._geometry.with_copies(copies, geometry)
            reset_observation, reset_info = self._reset_outputs(copies, geometry)
            observation[copies] = reset_observation
            set_rows(info, copies, reset_info)
            info.update(final_infos)
        return observation, info

    def _view_restarts(self, copies) -> None:
        """Copies ``copies`` start an episode (before drawing from their generators): sub-env 0's view follows."""
        if self._view is not None and 0 in copies:
            self._view.restart(self._np_randoms[0])

    def _view_steps(self, actions: np.ndarray, acting: np.ndarray) -> None:
        """The sub-envs ``acting`` take ``actions``: sub-env 0's view replays its action."""
        if self._view is not None and acting[0]:
            self._view.step(int(actions[0]))

    @property
    def np_randoms(self) -> list[np.random.Generator | None]:
        """Each sub-env's generator (the single env's ``np_random``), None before its first reset."""
        return list(self._np_randoms)

    def _seed_sub_envs(self, seed, options: dict | None) -> None:
        """Seed each sub-env's generator per ``sub_env_seeds``; a None seed keeps a generator it already has.

        Raises:
            ValueError: for a bad seed (see ``sub_env_seeds``) or any options.
        """
        owner = type(self).__name__
        if options:
            raise ValueError(f"{owner}.reset takes no options, got {sorted(options)}")
        for copy, copy_seed in enumerate(sub_env_seeds(seed, self.num_envs, owner)):
            if copy_seed is not None or self._np_randoms[copy] is None:
                self._np_randoms[copy] = seeding.np_random(copy_seed)[0]

    def _checked_actions(self, actions) -> np.ndarray:
        """The actions as an int array (N,), one index of the ``Discrete`` single action space per sub-env.

        Raises:
            RuntimeError: before the first ``reset``.
            ValueError: for another shape, a non-integer dtype, or an action outside the space (naming its sub-env).
        """
        owner, space = type(self).__name__, self.single_action_space
        if self._decision is None:
            raise RuntimeError(f"{owner}: call reset() before step()")
        array, top = np.asarray(actions), space.n - 1
        if array.shape != (self.num_envs,) or array.dtype.kind not in "iu":
            raise ValueError(
                f"actions of {owner} must be an integer array of shape ({self.num_envs},), one per sub-env, in "
                f"[0, {top}]; got {array.dtype} of shape {array.shape}"
            )
        outside = np.flatnonzero((array < 0) | (array > top))
        if outside.size:
            copy = int(outside[0])
            raise ValueError(
                f"action {array[copy]} of sub-env {copy} is not in the action space {space}: expected an integer "
                f"in [0, {top}]"
            )
        return array.astype(int)

    def _accepted_actions(self, actions: np.ndarray, acting: np.ndarray) -> np.ndarray:
        """Each acting sub-env's action where its mask allows it, else -1 (the no-op), per ``invalid_action``.

        Raises:
            ValueError: with ``invalid_action="raise"``, for a masked action of a sub-env that has a valid one.
        """
        mask = self._decision.action_mask
        valid = acting & mask[np.arange(self.num_envs), actions].astype(bool)
        for copy in np.flatnonzero(acting & ~valid).tolist():
            accepts_action(
                int(actions[copy]), mask[copy], self.config["invalid_action"], 'info["action_mask"]', f"sub-env {copy}"
            )
        return np.where(valid, actions, -1)

    def action_masks(self) -> np.ndarray:
        """The valid actions of each sub-env as bool (N, A); all ``True`` where none is valid (each is the no-op)."""
        if self._decision is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before action_masks()")
        mask = self._decision.action_mask.astype(bool)
        mask[~mask.any(axis=1)] = True
        return mask

    def render(self):
        """Sub-env 0's frame as its single env draws it (an RGB array for ``"rgb_array"``); None without a mode."""
        owner = type(self).__name__
        if self._view is None:
            gym.logger.warn(f'{owner}.render() called without a render_mode; use render_mode="rgb_array"')
            return None
        if self._decision is None:
            raise RuntimeError(f"{owner}: call reset() before render()")
        return self._view.render()

    def close_extras(self, **kwargs) -> None:
        self._decision = None
        if self._view is not None:
            self._view.close()
