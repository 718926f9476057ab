"""What every native vector env shares: its arguments (num_envs, autoreset mode, seeds), and infos as dicts of arrays.

Infos follow Gymnasium's vector layout: each key holds an array with a leading sub-env dimension and a
``_key`` bool mask of the sub-envs that have it; nested dicts (``reward_terms``) the same, recursively.
"""

from __future__ import annotations

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode


def checked_num_envs(num_envs, owner: str) -> int:
    """``num_envs`` if it is an int >= 1 (not a bool), else a ``ValueError`` naming ``owner``."""
    if type(num_envs) is not int or num_envs < 1:
        raise ValueError(f"num_envs of {owner} must be an int >= 1, got {num_envs!r}")
    return num_envs


def reseeded(generators: list, seed, owner: str) -> list[np.random.Generator]:
    """The sub-envs' generators after ``reset(seed=seed)``, as each single env's ``reset`` leaves its ``np_random``.

    An int ``s`` seeds sub-env ``i`` with ``s + i``; a list gives one seed (or None) per sub-env; None (or a
    None entry) keeps a sub-env's generator going, or makes a fresh one where it has none yet.

    Raises:
        ValueError: naming ``owner``, for a seed that is not None, an int >= 0 (not a bool) or a list of one
            such seed per sub-env.
    """
    if _is_seed(seed):
        seeds = [None if seed is None else int(seed) + copy for copy in range(len(generators))]
    else:
        seeds = list(seed) if isinstance(seed, (list, tuple)) else []
        if len(seeds) != len(generators) or not all(_is_seed(item) for item in seeds):
            raise ValueError(
                f"seed of {owner}.reset must be None, an int >= 0 or a list of {len(generators)} such seeds "
                f"(one per sub-env), got {seed!r}"
            )
        seeds = [None if item is None else int(item) for item in seeds]
    return [
        generator if copy_seed is None and generator is not None else seeding.np_random(copy_seed)[0]
        for generator, copy_seed in zip(generators, seeds)
    ]


def _is_seed(value) -> bool:
    """Whether ``value`` is a seed of one sub-env: None, or an int >= 0 (not a bool)."""
    return value is None or (isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 0)


def autoreset_mode_of(value, allowed: tuple[AutoresetMode, ...], owner: str) -> AutoresetMode:
    """``value`` as an ``AutoresetMode``: the enum, its value (``"SameStep"``) or its name (``"same_step"``).

    Raises:
        ValueError: naming ``owner`` and the modes it allows, for anything else.
    """
    for mode in allowed:
        if value is mode or (isinstance(value, str) and value.lower() in (mode.value.lower(), mode.name.lower())):
            return mode
    names = ", ".join(f"{mode.name.lower()!r}" for mode in allowed)
    raise ValueError(f"autoreset_mode of {owner} must be one of {names} (or the AutoresetMode), got {value!r}")


def set_rows(full, rows: np.ndarray, part):
    """Write ``part``'s rows into ``full`` at ``rows`` (arrays, or dicts of them, recursively); returns ``full``."""
    if isinstance(full, dict):
        for key, value in full.items():
            set_rows(value, rows, part[key])
        return full
    full[rows] = part
    return full


def final_step_infos(observation: np.ndarray, info: dict, ended: np.ndarray) -> dict:
    """Gymnasium's ``SAME_STEP`` keys for the sub-envs ``ended`` (N,) bool: their last observation and info.

    ``final_obs`` is an object array of the ended sub-envs' observations (``None`` elsewhere); ``final_info`` a
    copy of ``info`` whose masks hold only for them; ``_final_obs`` and ``_final_info`` are ``ended``.
    """
    final_obs = np.full(len(ended), None, dtype=object)
    for row in np.flatnonzero(ended).tolist():
        final_obs[row] = observation[row].copy()
    return {
        "final_obs": final_obs,
        "_final_obs": ended.copy(),
        "final_info": _masked_copy(info, ended),
        "_final_info": ended.copy(),
    }


def _masked_copy(info: dict, rows: np.ndarray) -> dict:
    copied = {}
    for key, value in info.items():
        if isinstance(value, dict):
            copied[key] = _masked_copy(value, rows)
        elif key.startswith("_"):
            copied[key] = value & rows
        else:
            copied[key] = value.copy()
    return copied
