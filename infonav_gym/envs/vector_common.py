"""What the native vector envs share: per-sub-env seeds, action checks, ``invalid_action`` and ``action_masks``."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from infonav_gym.envs.base import accepts_action


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


def checked_discrete_actions(actions, num_envs: int, space: spaces.Discrete, owner: str) -> np.ndarray:
    """The actions as an int array (N,), one index of the ``Discrete`` ``space`` per sub-env.

    Raises:
        ValueError: for another shape, a non-integer dtype, or an action outside ``space`` (naming its sub-env).
    """
    array = np.asarray(actions)
    top = space.n - 1
    if array.shape != (num_envs,) or array.dtype.kind not in "iu":
        raise ValueError(
            f"actions of {owner} must be an integer array of shape ({num_envs},), one per sub-env, in [0, {top}]; "
            f"got {array.dtype} of shape {array.shape}"
        )
    outside = np.flatnonzero((array < 0) | (array > top))
    if outside.size:
        copy = int(outside[0])
        raise ValueError(
            f"action {array[copy]} of sub-env {copy} is not in the action space {space}: expected an integer in "
            f"[0, {top}]"
        )
    return array.astype(int)


def accepted_actions(actions: np.ndarray, acting: np.ndarray, mask: np.ndarray, invalid_action: str) -> np.ndarray:
    """Each acting sub-env's action where its ``mask`` (N, A) allows it, else -1 (the no-op), per ``invalid_action``.

    Raises:
        ValueError: with ``invalid_action="raise"``, for a masked action of a sub-env that has a valid one.
    """
    valid = acting & mask[np.arange(len(actions)), actions].astype(bool)
    for copy in np.flatnonzero(acting & ~valid).tolist():
        accepts_action(int(actions[copy]), mask[copy], invalid_action, 'info["action_mask"]', f"sub-env {copy}")
    return np.where(valid, actions, -1)


def masks_for_maskable_ppo(mask: np.ndarray) -> np.ndarray:
    """The valid actions of each sub-env as bool (N, A); all ``True`` where none is valid (each is the no-op)."""
    masks = mask.astype(bool)
    masks[~masks.any(axis=1)] = True
    return masks
