"""``InfoNavEnv``: the fixed reset/step cycle every single-agent infonav env shares, and the hooks it calls.

Subclasses never override ``reset`` or ``step``; they implement the hooks declared
(with their contracts) as abstract methods below: ``_reset_episode``, ``_next_decision``,
``_apply_action``, ``_observation`` and ``_scene_frame``; ``_advance``, ``_extra_info``
and ``_is_terminated`` have documented defaults. One step runs::

    action -> validate (decision.action_mask) -> _apply_action(action, decision) -> _advance()
    -> decision = _next_decision() -> _is_terminated(), _observation(), info (+ _extra_info())
"""

from __future__ import annotations

import abc
import operator
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

from infonav_gym.config import Interval, check_choice, check_config, merge_config

INVALID_ACTION_MODES = ("noop", "raise")
MIN_RENDER_SIZE_PX = 64
RENDER_SIZE_PX = Interval(MIN_RENDER_SIZE_PX, 4096, integer=True)  # the allowed frame sizes [px]
MAX_EPISODE_STEPS = 10**7
EPISODE_STEPS = Interval(1, MAX_EPISODE_STEPS, integer=True)  # the allowed horizons (``horizon``, ``max_cycles``)


def shared_config() -> dict:
    """A fresh dict of the config keys every single-agent env has, with their defaults."""
    return {
        "horizon": 200,  # episode length [steps]; the episode is truncated after it
        "invalid_action": "noop",  # a masked action: "noop" (reward 0) or "raise" (ValueError)
        "render_size_px": 600,  # longer side of rendered frames [px]
    }


class Decision(NamedTuple):
    """What an env offers at one decision, computed once at the prior by ``_next_decision``.

    Immutable (a named tuple: cheap to build every step), and the base makes its arrays read-only
    (``Decision.frozen``): acting on a decision never changes it.

    Attributes:
        action_mask: int8, 1 = valid, per action.
        action_information_gain: float64, expected mutual information of each action [nats], 0 where masked.
        payload: what the env's ``_apply_action`` needs to act on this decision (e.g. the predicted
            measurements, their Jacobians ``H`` and noise ``R``, the prior's log-determinant); env-specific.
    """

    action_mask: np.ndarray
    action_information_gain: np.ndarray
    payload: Any = None

    def frozen(self) -> Decision:
        """This decision with its arrays made read-only (the bases call it on every new decision)."""
        self.action_mask.setflags(write=False)
        self.action_information_gain.setflags(write=False)
        return self


def discrete_action_index(action, space: gym.spaces.Discrete, agent: str | None = None) -> int:
    """The action as an int, or ``ValueError`` if it is not one integer of the ``Discrete(n)`` space.

    A Python or numpy integer and an integer array or list of one element (``[0]``, ``np.array([[0]])``)
    are accepted alike; floats, bools, strings, several elements and values outside ``[0, n)`` are not.

    Args:
        action: what the agent passed to ``step``.
        space: the action space.
        agent: the agent whose action it is (team envs), named in the error.
    """
    if type(action) is int and 0 <= action < space.n:  # the common case, first
        return action
    value = action
    if isinstance(value, (list, tuple)):
        try:
            value = np.asarray(value)
        except ValueError:  # ragged nesting
            value = None
    if isinstance(value, np.ndarray):
        value = value.reshape(()) if value.size == 1 and value.dtype.kind in "iu" else None
    if value is not None and not isinstance(value, (bool, np.bool_)):
        try:
            index = operator.index(value)
        except TypeError:
            index = None
        if index is not None and 0 <= index < space.n:
            return index
    owner = "" if agent is None else f" of {agent}"
    raise ValueError(
        f"action {action!r}{owner} is not in the action space {space}: expected one integer in [0, {space.n - 1}] "
        "(a Python or numpy integer, or an integer array of one element)"
    )


def accepts_action(action: int, mask: np.ndarray, invalid_action: str, mask_key: str, agent: str | None = None) -> bool:
    """Whether ``action`` is valid per ``mask``; ``False`` means it becomes the env's no-op.

    When no action is valid, every action is the same no-op and is accepted even with
    ``invalid_action="raise"`` (there is nothing valid to choose instead).

    Args:
        action: an index of the action space.
        mask: the current action mask (int8, 1 = valid).
        invalid_action: the env's ``invalid_action`` config value, ``"noop"`` or ``"raise"``.
        mask_key: where the agent reads ``mask`` (e.g. ``info["action_mask"]``), named in the error.
        agent: the agent whose action it is (team envs), named in the error.

    Raises:
        ValueError: for a masked action with ``invalid_action="raise"`` while some action is valid.
    """
    if mask[action]:
        return True
    if invalid_action == "raise" and mask.any():
        owner = "" if agent is None else f" of {agent}"
        raise ValueError(
            f"action {action}{owner} is not valid now (action_mask {mask.tolist()}); "
            f'pick an action whose {mask_key} entry is 1, or set invalid_action="noop"'
        )
    return False


class SceneRendering(abc.ABC):
    """Config and render mode checks, ``render``, ``close`` and pickling of ``InfoNavEnv``.

    The host has
    ``metadata`` (``render_modes``, ``render_fps``), a ``default_config()`` with
    ``invalid_action`` and ``render_size_px``, calls ``_configure`` in ``__init__``,
    describes frames with ``_scene_frame()`` and counts ``_elapsed_steps`` from reset.
    """

    def _configure(self, render_mode: str | None, config: dict) -> None:
        """Set ``render_mode`` and ``config`` (``default_config()`` merged with ``config``), checking the shared keys.

        Also starts the host's rendering state (no renderer, no episode yet).
        """
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        owner = type(self).__name__
        self.config = merge_config(self.default_config(), config, owner)
        check_choice(self.config, "invalid_action", INVALID_ACTION_MODES, owner)
        check_config(self.config, owner, {"render_size_px": RENDER_SIZE_PX})
        self._renderer = None
        self._elapsed_steps = None

    def render(self):
        if self.render_mode is None:
            gym.logger.warn(
                f"{type(self).__name__}.render() called without a render_mode; "
                'construct the env with render_mode="rgb_array" or "human"'
            )
            return None
        if self._elapsed_steps is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before render()")
        if self._renderer is None:
            from infonav_gym.rendering import Renderer

            self._renderer = Renderer(self.render_mode, self.config["render_size_px"], self.metadata["render_fps"])
        return self._renderer.draw(self._scene_frame())

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    @abc.abstractmethod
    def _scene_frame(self):
        """Hook: the ``infonav_gym.rendering.SceneFrame`` describing the current state, for ``render()``.

        Called after ``reset`` or ``step`` has finished (the current decision is set); must not change the
        env. Import ``infonav_gym.rendering`` inside it: rendering needs the ``render`` extra.
        """

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_renderer"] = None
        return state


class InfoNavEnv(SceneRendering, gym.Env):
    """Base of the single-agent envs: config, action validation, horizon, info keys, rendering."""

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    @classmethod
    def default_config(cls) -> dict:
        """A fresh dict of every config key with its default; ``gym.make`` kwargs override it."""
        return shared_config()

    def __init__(self, render_mode: str | None = None, **config):
        self._configure(render_mode, config)
        check_config(self.config, type(self).__name__, {"horizon": EPISODE_STEPS})
        self._decision = None
        self._chosen_action = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode: seed ``np_random``, ``_reset_episode()``, then the first decision. Do not override."""
        super().reset(seed=seed)
        if options:
            raise ValueError(f"{type(self).__name__}.reset takes no options, got {sorted(options)}")
        self._elapsed_steps = 0
        self._chosen_action = None
        self._reset_episode()
        self._decision = self._next_decision().frozen()
        observation, info = self._observation(), self._info({}, invalid=False)
        if self.render_mode == "human":
            self.render()
        return observation, info

    def step(self, action):
        """Validate ``action``, act on the current decision, advance time, decide again. Do not override.

        Raises:
            ValueError: for an action outside the action space, or a masked one with ``invalid_action="raise"``.
        """
        if self._elapsed_steps is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before step()")
        action = discrete_action_index(action, self.action_space)
        decision = self._decision
        valid = accepts_action(action, decision.action_mask, self.config["invalid_action"], 'info["action_mask"]')
        self._chosen_action = action if valid else None
        reward_terms = self._apply_action(self._chosen_action, decision)
        self._elapsed_steps += 1
        self._advance()
        self._decision = self._next_decision().frozen()
        terminated = self._is_terminated()
        truncated = not terminated and self._elapsed_steps >= self.config["horizon"]
        info = self._info(reward_terms, invalid=not valid)
        if self.render_mode == "human":
            self.render()
        return self._observation(), float(sum(reward_terms.values())), terminated, truncated, info

    def action_masks(self) -> np.ndarray:
        """The valid actions now, as bool (n,): what sb3-contrib's ``MaskablePPO`` asks for.

        ``info["action_mask"]`` of the last ``reset`` or ``step``, except when no action is valid: then
        every action is ``True``, since each is the same no-op (``MaskablePPO`` cannot sample from an
        all-false mask, and ``step`` accepts any action then, even with ``invalid_action="raise"``).
        Found through Gymnasium wrappers with ``env.get_wrapper_attr("action_masks")()``.
        """
        if self._decision is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before action_masks()")
        mask = self._decision.action_mask.astype(bool)
        return mask if mask.any() else np.ones_like(mask)

    @property
    def _action_mask(self) -> np.ndarray:
        """The current decision's action mask (int8, read-only)."""
        return self._decision.action_mask

    def _info(self, reward_terms: dict, invalid: bool) -> dict:
        return {
            "action_mask": self._decision.action_mask.copy(),
            "action_information_gain": self._decision.action_information_gain.copy(),
            "reward_terms": dict(reward_terms),
            "chosen_action": -1 if self._chosen_action is None else self._chosen_action,
            "invalid_action": invalid,
            **self._extra_info(),
        }

    # ------------------------------------------------------------------ the hooks

    @abc.abstractmethod
    def _reset_episode(self) -> None:
        """Hook: start a new episode (world, sensors' generators, estimator), drawing only from ``self.np_random``.

        Called by ``reset`` after seeding, with ``_elapsed_steps == 0``; ``_next_decision`` follows.
        """

    @abc.abstractmethod
    def _next_decision(self) -> Decision:
        """Hook: the ``Decision`` for the next action, at the current state (after ``_reset_episode`` or ``_advance``).

        Must not change the env's state: what acting needs goes into ``Decision.payload``, which the
        base hands to ``_apply_action``. Invalid actions must have gain 0.
        """

    @abc.abstractmethod
    def _apply_action(self, action: int | None, decision: Decision) -> dict:
        """Hook: act on ``decision`` with a valid ``action``, or do the env's no-op when ``action`` is ``None``.

        Called by ``step`` with the decision the agent saw; may change the env's state (world,
        estimator, budgets). ``_elapsed_steps`` still counts the steps before this one.

        Returns:
            The reward terms, a dict of floats whose sum is the reward (``info["reward_terms"]``).
        """

    def _advance(self) -> None:
        """Hook: move time on by one step after ``_apply_action`` (``_elapsed_steps`` already counts it).

        Default: nothing (an env whose ``_apply_action`` does the whole transition).
        """

    @abc.abstractmethod
    def _observation(self) -> np.ndarray:
        """Hook: the observation of the current state, an element of ``observation_space`` (a fresh array).

        Called after the current decision is set (``self._decision``); must not change the env.
        """

    def _extra_info(self) -> dict:
        """Hook: env-specific ``info`` entries beside the common keys, read after the current decision is set.

        Default: none.
        """
        return {}

    def _is_terminated(self) -> bool:
        """Hook: whether the episode has ended in a terminal state, after the step's decision. Default: never."""
        return False
