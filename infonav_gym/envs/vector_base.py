"""``InfoNavVectorEnv``: what the native vector envs share (seeds per sub-env, action checks, masks, the API).

Every env is written once on batched arrays: it declares ``default_config()``; its constructor (fixed here) calls
``_setup`` (the shared arguments and keys), then the env's ``_build`` hook (its own keys, its parts, its spaces with
``_set_spaces``); its single env is the N = 1 view (``envs.single_view``) and ``render()`` draws its copy 0 from
``_scene_frame()``. It keeps the current decision in ``self._decision`` (with an ``action_mask`` (N, A)), starts
episodes in ``_reset_copies`` (returning their static geometry, or None) with their first outputs from
``_reset_outputs`` (``_outputs`` after no step: ``_no_step_record``), and fills ``step``'s two hooks: ``_act`` (the
transition of the copies acting) and ``_outputs`` (observations and infos after it). ``reset`` and ``step`` are
fixed here, with the seeding, the action checks, ``_elapsed`` (each copy's steps, against ``horizon``) and the
resets of ``autoreset_mode`` (the team envs run on ``envs.driver.Driver``).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from infonav_gym.compiled import kernel
from infonav_gym.config import check_choice, check_config, merge_config
from infonav_gym.envs.base import EPISODE_STEPS, INVALID_ACTION_MODES, RENDER_SIZE_PX, accepts_action, shared_config
from infonav_gym.envs.traits import traits_of
from infonav_gym.envs.vector_infos import autoreset_mode_of, final_step_infos, set_rows
from infonav_gym.memory import check_memory


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

    ``autoreset_mode`` is one of ``AUTORESET_MODES`` per instance (``metadata["autoreset_mode"]``). With a
    ``render_mode``, ``render()`` draws sub-env 0 from the env's ``_scene_frame()``.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}
    AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED)
    _renderer = None  # made by the first ``render()``
    _owner: str | None = None  # the single env's name, in the errors of its copy (``one_copy``)

    @classmethod
    def default_config(cls) -> dict:
        """A fresh dict of every config key with its default; the constructor's keywords override it."""
        return shared_config()

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **config,
    ):
        """The shared arguments and keys checked (``_setup``), then the env's own (``_build``)."""
        self._setup(num_envs, render_mode, autoreset_mode, config)
        self._build()

    def _build(self) -> None:
        """Hook: check the env's own config keys, set its spaces (``_set_spaces``), build its parts
        and allocate its stacked state for ``num_envs`` copies."""
        raise NotImplementedError(f"{type(self).__name__} must implement _build()")

    @classmethod
    def one_copy(cls, owner: str, render_mode: str | None, config: dict) -> InfoNavVectorEnv:
        """One copy that never restarts by itself, its errors naming ``owner``: what ``SingleEnvView`` steps."""
        env = cls.__new__(cls)
        env._owner = owner
        env.__init__(num_envs=1, render_mode=render_mode, autoreset_mode=AutoresetMode.DISABLED, **config)
        return env

    @property
    def owner_name(self) -> str:
        """The env named in errors: the class, or the single env of a copy made by ``one_copy``."""
        return self._owner or type(self).__name__

    def use_generator(self, copy: int, generator: np.random.Generator) -> None:
        """Sub-env ``copy`` draws its next episodes from ``generator`` (``reset()`` without a seed keeps it)."""
        self._np_randoms[copy] = generator

    def _setup(self, num_envs: int, render_mode: str | None, autoreset_mode, config: dict) -> None:
        """Check the vector arguments and the config (``default_config()`` merged with ``config``).

        Sets ``config``; the env checks its own keys after, then calls ``_set_spaces``.

        Raises:
            ValueError: for ``num_envs`` that is not an int >= 1, a render mode outside ``metadata``, an autoreset
                mode other than ``AUTORESET_MODES``, an unknown config key, or a bad shared key.
        """
        owner = self.owner_name
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.config = merge_config(self.default_config(), config, owner)
        check_choice(self.config, "invalid_action", INVALID_ACTION_MODES, owner)
        shared = {"render_size_px": RENDER_SIZE_PX, "horizon": EPISODE_STEPS}  # a team env counts "max_cycles"
        check_config(self.config, owner, {key: interval for key, interval in shared.items() if key in self.config})
        self._start_copies(num_envs, render_mode, autoreset_mode)

    def copy_kb(self) -> float:
        """The memory a copy takes at this config [kB]: the traits' ``kb_per_copy``. An env whose copies grow with a
        config key adds to it, reading the key up to its range's end (its range check comes later, in ``_build``)."""
        return traits_of(self).kb_per_copy

    def _set_spaces(self, single_observation_space: gym.Space, single_action_space: gym.Space) -> None:
        """Set the spaces of one sub-env and their batched versions."""
        self.single_observation_space = single_observation_space
        self.single_action_space = single_action_space
        self.observation_space = batch_space(single_observation_space, self.num_envs)
        self.action_space = batch_space(single_action_space, self.num_envs)

    def _start_copies(self, num_envs: int, render_mode: str | None, autoreset_mode) -> None:
        """Set the copies' bookkeeping, after checking ``num_envs`` and the memory its copies need (``copy_kb``),
        before any array of them is allocated."""
        owner = self.owner_name
        if type(num_envs) is not int or num_envs < 1:
            raise ValueError(f"num_envs of {owner} must be an int >= 1, got {num_envs!r}")
        kb = self.copy_kb()
        check_memory(num_envs * kb * 1024, f"num_envs={num_envs} of {owner} (about {kb:.4g} kB a copy)")
        self.autoreset_mode = autoreset_mode_of(autoreset_mode, self.AUTORESET_MODES, owner)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        self.num_envs = num_envs
        self.render_mode = render_mode
        self._np_randoms: list[np.random.Generator | None] = [None] * num_envs
        self._everyone = np.arange(num_envs)  # every copy's index, for steps that touch all of them
        self._elapsed = np.zeros(num_envs, dtype=int)  # each copy's steps in its episode
        self._decision = self._geometry = None
        self._prev_done = np.zeros(num_envs, dtype=bool)

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset every sub-env: seed ``s`` gives sub-env ``i`` the seed ``s + i``; a list gives one seed (or None) each.

        Raises:
            ValueError: for a seed that is not None, an int >= 0 or a list of N ints / None, or any options.
        """
        self._seed_sub_envs(seed, options)
        everyone = np.arange(self.num_envs)
        self._elapsed[:] = 0
        self._geometry = self._reset_copies(everyone)
        self._prev_done[:] = False
        return self._rendered(self._reset_outputs(everyone, self._geometry))

    def step(self, actions):
        """Act in every sub-env, with ``autoreset_mode``'s resets (errors: ``_begin_step``). Fixed: an env fills
        ``_act`` and ``_outputs``."""
        acting, chosen = self._begin_step(actions)
        record, rewards, terminated = self._act(acting, chosen)
        truncated, ended = counted_steps(self._elapsed, acting, terminated, self.config["horizon"])
        observation, info = self._finish_step(
            ended, lambda copies, geometry: self._outputs(copies, geometry, acting, chosen, record)
        )
        return observation, rewards, terminated, truncated, info

    def _reset_copies(self, copies: np.ndarray):
        """Hook: start a new episode in each of ``copies`` (their ``_elapsed`` is 0) from its own generator; return
        their static geometry (an object with ``with_copies(copies, replacement)``), or None if the env keeps none."""
        raise NotImplementedError(f"{self.owner_name} must implement _reset_copies()")

    def _reset_outputs(self, copies: np.ndarray, geometry) -> tuple[np.ndarray, dict]:
        """The observations (n, ...) and reset infos of ``copies``, just reset (``geometry``: theirs): ``_outputs``
        after no step (none acting, no action, ``_no_step_record``)."""
        n = len(copies)
        return self._outputs(copies, geometry, np.zeros(n, dtype=bool), np.full(n, -1), self._no_step_record(n))

    def _no_step_record(self, n: int):
        """Hook: the record ``_outputs`` reads for ``n`` copies that took no step (their reset)."""
        raise NotImplementedError(f"{self.owner_name} must implement _no_step_record()")

    def _act(self, acting: np.ndarray, chosen: np.ndarray) -> tuple:
        """Hook: the ``acting`` copies (N,) bool take their ``chosen`` actions (N,) (-1: the no-op).

        Returns:
            ``(record, rewards (N,), terminated (N,) bool)``: what ``_outputs`` reads of the step, 0 and False
            for the copies not acting.
        """
        raise NotImplementedError(f"{self.owner_name} must implement _act()")

    def _outputs(self, copies: np.ndarray, geometry, acting: np.ndarray, chosen: np.ndarray, record) -> tuple:
        """Hook: the observations (n, ...) and infos of ``copies`` at their new decisions (set with
        ``_set_decision``), after the step ``_act`` made (its ``acting``, ``chosen`` and ``record``)."""
        raise NotImplementedError(f"{self.owner_name} must implement _outputs()")

    def _begin_step(self, actions) -> tuple[np.ndarray, np.ndarray]:
        """``(acting, chosen)``: which sub-envs act in this step (with ``NEXT_STEP``, not those starting again) and
        the action each takes, -1 for a no-op (a masked action, per ``invalid_action``).

        Raises:
            RuntimeError: before the first ``reset``.
            ValueError: for actions that are not N integers of the action space, or, with
                ``invalid_action="raise"``, a masked action of a sub-env that has a valid one (each naming its sub-env).
        """
        actions, mask = self._checked_actions(actions), self._decision.action_mask
        chosen, outside = accepted_actions(actions.astype(np.int64, copy=False), mask, self._prev_done)
        if outside >= 0:
            raise outside_action_space(actions[outside], f"sub-env {outside}", self.single_action_space)
        acting = ~self._prev_done
        if self.config["invalid_action"] == "raise":  # with "noop" a masked action is the no-op, silently
            for copy in np.flatnonzero(acting & (chosen < 0)).tolist():
                sub_env = None if self._owner else f"sub-env {copy}"  # a single env has no sub-envs to name
                accepts_action(int(actions[copy]), mask[copy], "raise", 'info["action_mask"]', sub_env)
        return acting, chosen

    def _finish_step(self, ended: np.ndarray, step_outputs) -> tuple[np.ndarray, dict]:
        """The observations and infos of a step in which the sub-envs ``ended`` (N,) bool ended their episodes.

        ``step_outputs(copies, geometry)`` gives the observations and infos of ``copies`` at their new decisions.
        ``NEXT_STEP``: the sub-envs that ended at the last step start again now, then all decide. ``SAME_STEP``: all
        decide, then those that ended start again, their last observation and info in ``final_obs`` / ``final_info``.
        """
        everyone = self._everyone
        if self.autoreset_mode == AutoresetMode.DISABLED:
            # a sub-env that ended goes on stepping (no autoreset) until reset() is called
            return self._rendered(step_outputs(everyone, self._geometry))
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            resetting = np.flatnonzero(self._prev_done)
            if resetting.size:
                self._new_episodes(resetting)
            self._prev_done = ended
            return self._rendered(step_outputs(everyone, self._geometry))
        observation, info = step_outputs(everyone, self._geometry)
        copies = np.flatnonzero(ended)
        if copies.size:
            final_infos = final_step_infos(observation, info, ended)
            geometry = self._new_episodes(copies)
            reset_observation, reset_info = self._reset_outputs(copies, geometry)
            observation[copies] = reset_observation
            set_rows(info, copies, reset_info)
            info.update(final_infos)
        return self._rendered((observation, info))

    def _new_episodes(self, copies: np.ndarray):
        """Start a new episode in each of ``copies`` (``_reset_copies``); their geometry, merged into ``_geometry``."""
        self._elapsed[copies] = 0
        geometry = self._reset_copies(copies)
        if geometry is not None:
            self._geometry = self._geometry.with_copies(copies, geometry)
        return geometry

    def _rows(self, copies: np.ndarray):
        """The index of ``copies`` (ascending) into the (N, ...) arrays: all rows as a slice (views, no copies) when
        they are every copy."""
        return slice(None) if len(copies) == self.num_envs else copies

    def _set_decision(self, copies: np.ndarray, decision) -> None:
        """Keep ``decision`` (a named tuple of arrays (n, ...)) as the decision of ``copies`` (n,), the others' kept."""
        if len(copies) == self.num_envs:
            self._decision = decision
        else:
            rows = (set_rows(full, copies, part) for full, part in zip(self._decision, decision))
            self._decision = type(decision)(*rows)

    def _rendered(self, outputs: tuple) -> tuple:
        """``outputs`` of a reset or step, after drawing sub-env 0 in ``"human"`` mode."""
        if self.render_mode == "human":
            self.render()
        return outputs

    @property
    def np_randoms(self) -> list[np.random.Generator | None]:
        """Each sub-env's generator (the single env's ``np_random``), None before its first reset."""
        return list(self._np_randoms)

    def _seed_sub_envs(self, seed, options: dict | None) -> None:
        """Seed each sub-env's generator per ``sub_env_seeds``; a None seed keeps a generator it already has.

        Raises:
            ValueError: for a bad seed (see ``sub_env_seeds``) or any options.
        """
        owner = self.owner_name
        if options:
            raise ValueError(f"{owner}.reset takes no options, got {sorted(options)}")
        for copy, copy_seed in enumerate(sub_env_seeds(seed, self.num_envs, owner)):
            if copy_seed is not None or self._np_randoms[copy] is None:
                self._np_randoms[copy] = seeding.np_random(copy_seed)[0]

    def _checked_actions(self, actions) -> np.ndarray:
        """The actions as an integer array (N,), one per sub-env (``_begin_step`` checks that they are in the space).

        Raises:
            RuntimeError: before the first ``reset``.
            ValueError: for another shape or a non-integer dtype.
        """
        owner = self.owner_name
        if self._decision is None:
            raise RuntimeError(f"{owner}: call reset() before step()")
        array = np.asarray(actions)
        if array.shape != (self.num_envs,) or array.dtype.kind not in "iu":
            raise ValueError(
                f"actions of {owner} must be an integer array of shape ({self.num_envs},), one per sub-env, in "
                f"[0, {self.single_action_space.n - 1}]; got {array.dtype} of shape {array.shape}"
            )
        return array

    def action_masks(self) -> np.ndarray:
        """The valid actions of each sub-env as bool (N, A); all ``True`` where none is valid (each is the no-op)."""
        if self._decision is None:
            raise RuntimeError(f"{self.owner_name}: call reset() before action_masks()")
        mask = self._decision.action_mask.astype(bool)
        mask[~mask.any(axis=1)] = True
        return mask

    def render(self):
        """Sub-env 0's frame (an RGB array for ``"rgb_array"``), drawn from ``_scene_frame()``; None without a mode."""
        owner = self.owner_name
        if self.render_mode is None:
            gym.logger.warn(f'{owner}.render() called without a render_mode; use render_mode="rgb_array"')
            return None
        if self._decision is None:
            raise RuntimeError(f"{owner}: call reset() before render()")
        if self._renderer is None:
            from infonav_gym.rendering import Renderer  # pygame only when drawing

            self._renderer = Renderer(self.render_mode, self.config["render_size_px"], self.metadata["render_fps"])
        return self._renderer.draw(self._scene_frame())

    def _scene_frame(self):
        """Hook: the ``infonav_gym.scene.SceneFrame`` of sub-env 0 now (it must not change the env)."""
        raise NotImplementedError(f"{self.owner_name} must implement _scene_frame() to render")

    def close_extras(self, **kwargs) -> None:
        self._decision = None
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state.pop("_renderer", None)  # a pygame window or surface does not pickle; the copy draws anew
        return state


def outside_action_space(action, where: str, space) -> ValueError:
    """The error for ``action`` of ``where`` (a sub-env, an agent in one) outside the ``Discrete`` ``space``."""
    return ValueError(
        f"action {action} of {where} is not in the action space {space}: expected an integer in [0, {space.n - 1}]"
    )


@kernel
def accepted_actions(actions, mask, done):
    """Each sub-env's action (N,) where it acts (not ``done``) and its ``mask`` (N, A) allows it, else -1 (the
    no-op); and the first sub-env whose action is outside ``[0, A)``, -1 if none."""
    chosen, outside = np.empty(len(actions), dtype=np.int64), -1
    for copy in range(len(actions)):
        action = actions[copy]
        inside = 0 <= action < mask.shape[1]
        if not inside and outside < 0:
            outside = copy
        chosen[copy] = action if inside and not done[copy] and mask[copy, action] != 0 else -1
    return chosen, outside


@kernel
def counted_steps(elapsed, acting, terminated, horizon):
    """Count the step of each ``acting`` sub-env in ``elapsed`` (N,), in place; ``(truncated, ended)`` (N,) bool: it
    acted, did not terminate and reached ``horizon`` [steps]; it terminated or was truncated."""
    truncated, ended = np.empty(len(elapsed), dtype=np.bool_), np.empty(len(elapsed), dtype=np.bool_)
    for copy in range(len(elapsed)):
        elapsed[copy] += acting[copy]
        truncated[copy] = acting[copy] and not terminated[copy] and elapsed[copy] >= horizon
        ended[copy] = terminated[copy] or truncated[copy]
    return truncated, ended
