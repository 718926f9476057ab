"""Config dictionaries: defaults merged with user overrides, every key and value checked."""

from __future__ import annotations

import difflib
import numbers

import numpy as np


def merge_config(defaults: dict, overrides: dict, owner: str) -> dict:
    """Return ``defaults`` updated by ``overrides``.

    Raises:
        ValueError: for a key that ``defaults`` lacks (naming it and the closest
            valid key) or a value of the wrong type.
    """
    merged = dict(defaults)
    for key, value in overrides.items():
        if key not in defaults:
            close = difflib.get_close_matches(key, list(defaults), n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ValueError(f"unknown config key {key!r} for {owner}.{hint} Valid keys: {', '.join(sorted(defaults))}")
        merged[key] = _typed_like(defaults[key], value, f"config key {key!r} of {owner}")
    return merged


def _typed_like(default, value, where: str):
    if isinstance(default, bool):
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
    elif isinstance(default, int):
        if isinstance(value, numbers.Integral) and not isinstance(value, bool):
            return int(value)
    elif isinstance(default, float):
        if isinstance(value, numbers.Real) and not isinstance(value, bool):
            return float(value)
    elif isinstance(default, str):
        if isinstance(value, str):
            return value
    else:
        return value
    raise ValueError(f"{where} must be a {type(default).__name__} (like the default {default!r}), got {value!r}")


def check_choice(config: dict, key: str, choices, owner: str) -> None:
    """Raise ``ValueError`` unless ``config[key]`` is one of ``choices``."""
    if config[key] not in choices:
        raise ValueError(f"config key {key!r} of {owner} must be one of {sorted(choices)}, got {config[key]!r}")


def check_positive(config: dict, keys, owner: str, allow_zero: bool = False) -> None:
    """Raise ``ValueError`` unless every ``config[key]`` is positive (or non-negative)."""
    for key in keys:
        value = config[key]
        if not (value >= 0 if allow_zero else value > 0):
            bound = "non-negative" if allow_zero else "positive"
            raise ValueError(f"config key {key!r} of {owner} must be {bound}, got {value!r}")


def check_open_interval(config: dict, keys, low: float, high: float, owner: str, unit: str = "") -> None:
    """Raise ``ValueError`` unless every ``config[key]`` lies strictly between ``low`` and ``high``."""
    for key in keys:
        value = config[key]
        if not low < value < high:
            raise ValueError(f"config key {key!r} of {owner} must be in ({low:g}, {high:g}){unit}, got {value!r}")
