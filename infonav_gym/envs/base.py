"""``InfoNavEnv``: the fixed reset/step cycle every single-agent infonav env shares.

Subclasses fill small hooks and never override ``reset`` or ``step``:

- ``_reset_episode()``: build the world and the estimator from ``self.np_random``.
- ``_apply_action(action)``: act on a valid action (or ``None`` for a no-op);
  return the reward terms, a dict of floats summed into the reward.
- ``_advance()``: move time forward by one step (world, odometry, prediction).
- ``_next_decision()``: ``(action_mask, action_information_gain)`` for the next action.
- ``_observation()``, ``_extra_info()``, ``_is_terminated()``, ``_scene_frame()``.
"""

from __future__ import annotations

import operator

import gymnasium as gym
import numpy as np

from infonav_gym.config import Interval, check_choice, check_config, merge_config

INVALID_ACTION_MODES = ("noop", "raise")
MIN_RENDER_SIZE_PX = 64
RENDER_SIZE_PX = Interval(MIN_RENDER_SIZE_PX, 4096, integer=True)  # the allowed frame sizes [px]
MAX_EPISODE_STEPS = 10**7
EPISODE_STEPS = Interval(1, MAX_EPISODE_STEPS, integer=True)  # the allowed horizons (``horizon``, ``max_cycles``)


def discrete_action_index(action, space: gym.spaces.Discrete) -> int:
    """The action as an int, or ``ValueError`` if it is not an element of the ``Discrete(n)`` space."""
    value = action.reshape(()) if isinstance(action, np.ndarray) and action.size == 1 else action
    if not isinstance(value, (bool, np.bool_)):
        try:
            index = operator.index(value)
        except TypeError:
            index = None
        if index is not None and 0 <= index < space.n:
            return index
    raise ValueError(f"action {action!r} is not in the action space {space}: expected an integer in [0, {space.n - 1}]")


class SceneRendering:
    """Config and render mode checks, ``render``, ``close`` and pickling, shared by every infonav env.

    Used by the single-agent envs and the PettingZoo team env. The host has
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
        return {
            "horizon": 200,  # episode length [steps]; the episode is truncated after it
            "invalid_action": "noop",  # a masked action: "noop" (reward 0) or "raise" (ValueError)
            "render_size_px": 600,  # longer side of rendered frames [px]
        }

    def __init__(self, render_mode: str | None = None, **config):
        self._configure(render_mode, config)
        check_config(self.config, type(self).__name__, {"horizon": EPISODE_STEPS})
        self._action_mask = None
        self._action_information_gain = None
        self._chosen_action = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if options:
            raise ValueError(f"{type(self).__name__}.reset takes no options, got {sorted(options)}")
        self._elapsed_steps = 0
        self._chosen_action = None
        self._reset_episode()
        self._action_mask, self._action_information_gain = self._next_decision()
        observation, info = self._observation(), self._info({}, invalid=False)
        if self.render_mode == "human":
            self.render()
        return observation, info

    def step(self, action):
        if self._elapsed_steps is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before step()")
        action = discrete_action_index(action, self.action_space)
        valid = bool(self._action_mask[action])
        if not valid and self.config["invalid_action"] == "raise":
            raise ValueError(
                f"action {action} is not valid now (action_mask {self._action_mask.tolist()}); "
                'pick an action whose info["action_mask"] entry is 1, or set invalid_action="noop"'
            )
        self._chosen_action = action if valid else None
        reward_terms = self._apply_action(self._chosen_action)
        self._elapsed_steps += 1
        self._advance()
        self._action_mask, self._action_information_gain = self._next_decision()
        terminated = self._is_terminated()
        truncated = not terminated and self._elapsed_steps >= self.config["horizon"]
        info = self._info(reward_terms, invalid=not valid)
        if self.render_mode == "human":
            self.render()
        return self._observation(), float(sum(reward_terms.values())), terminated, truncated, info

    def _info(self, reward_terms: dict, invalid: bool) -> dict:
        return {
            "action_mask": self._action_mask.copy(),
            "action_information_gain": self._action_information_gain.copy(),
            "reward_terms": dict(reward_terms),
            "chosen_action": -1 if self._chosen_action is None else self._chosen_action,
            "invalid_action": invalid,
            **self._extra_info(),
        }

    def _extra_info(self) -> dict:
        return {}

    def _is_terminated(self) -> bool:
        return False
