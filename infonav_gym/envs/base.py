"""What every infonav env shares below the driver (``envs.driver``): the shared config keys, their limits, and
action checks."""

from __future__ import annotations

import operator

import gymnasium as gym
import numpy as np

from infonav_gym.config import Interval

INVALID_ACTION_MODES = ("noop", "raise")
RENDER_SIZE_PX = Interval(64, 4096, integer=True)  # the allowed frame sizes [px]
MAX_EPISODE_STEPS = 10**7
EPISODE_STEPS = Interval(1, MAX_EPISODE_STEPS, integer=True)  # the allowed horizons (``horizon``, ``max_cycles``)
REWARD_WEIGHT = Interval(0.0, 1e6)  # a cost, reward or bonus weight [nats, or nats per unit]


def shared_config() -> dict:
    """A fresh dict of the config keys every single-agent env has, with their defaults."""
    return {
        "horizon": 200,  # episode length [steps]; the episode is truncated after it
        "invalid_action": "noop",  # a masked action: "noop" (reward 0) or "raise" (ValueError)
        "render_size_px": 600,  # longer side of rendered frames [px]
    }


def discrete_action_index(action, space: gym.spaces.Discrete, agent: str | None = None) -> int:
    """The action as an int, or ``ValueError`` if it is not one integer of the ``Discrete(n)`` space.

    A Python or numpy integer and an integer array or list of one element (``[0]``, ``np.array([[0]])``)
    are accepted alike; floats, bools, strings, several elements and values outside ``[0, n)`` are not.
    ``agent`` (team envs) is named in the error.
    """
    if type(action) is int and 0 <= action < space.n:  # the common case, first
        return action
    try:  # a ragged list raises ValueError, anything that is not an integer (None included) TypeError
        value = np.asarray(action) if isinstance(action, (list, tuple)) else action
        if isinstance(value, np.ndarray):
            value = value.reshape(()) if value.size == 1 and value.dtype.kind in "iu" else None
        index = None if isinstance(value, (bool, np.bool_)) else operator.index(value)
        if index is not None and 0 <= index < space.n:
            return index
    except (TypeError, ValueError):
        pass
    owner = "" if agent is None else f" of {agent}"
    raise ValueError(
        f"action {action!r}{owner} is not in the action space {space}: expected one integer in [0, {space.n - 1}] "
        "(a Python or numpy integer, or an integer array of one element)"
    )


def accepts_action(action: int, mask: np.ndarray, invalid_action: str, mask_key: str, agent: str | None = None) -> bool:
    """Whether ``action`` is valid per ``mask``; ``False`` means it becomes the env's no-op.

    When no action is valid, every action is the same no-op and is accepted even with
    ``invalid_action="raise"`` (there is nothing valid to choose instead). The error names ``mask_key``, where the
    agent reads ``mask`` (int8, 1 = valid), and ``agent`` (team envs).

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
