"""Argparse ``type=`` functions of the ``infonav`` command: a bad value is refused before any work starts."""

from __future__ import annotations

import argparse
from pathlib import Path

SEED_LIMIT = 2**32  # seeds below it suit gymnasium, numpy's legacy seeding and Stable-Baselines3 alike
MAX_PLANNER_EPISODES = 100_000  # train --init-from-planner EPISODES


def _checked(text: str, convert, requirement: str, accepts):
    """``convert(text)`` if it converts and ``accepts`` the value, else ``ArgumentTypeError``: ``requirement``."""
    try:
        value = convert(text)
    except ValueError:
        value = None
    if value is None or not accepts(value):
        raise argparse.ArgumentTypeError(f"must be {requirement}, got {text!r}")
    return value


def integer(low: int, high: int):
    """A type function for an integer from ``low`` to ``high`` (a count: episodes, steps, workers, ...)."""
    return lambda text: _checked(text, int, f"an integer from {low} to {high}", lambda value: low <= value <= high)


def seed(text: str) -> int:
    """A seed: an integer in ``[0, SEED_LIMIT)``."""
    requirement = f"an integer from 0 to {SEED_LIMIT - 1} (2**32 - 1)"
    return _checked(text, int, requirement, lambda value: 0 <= value < SEED_LIMIT)


def number(low: float, high: float, *, low_open: bool = True):
    """A type function for a finite number in ``(low, high]`` (``[low, high]`` unless ``low_open``)."""
    requirement = f"a number in {'(' if low_open else '['}{low:g}, {high:g}]"
    return lambda text: _checked(text, float, requirement, lambda x: (low < x if low_open else low <= x) and x <= high)


def end_time(text: str) -> float:
    """A number > 0; ``inf`` for the end of the data."""
    return _checked(text, float, "a number > 0 (inf: the end)", lambda value: value > 0)


def episodes_or_file(text: str) -> int | Path:
    """A number of episodes (an integer >= 1), or an existing file (saved episodes, e.g. demonstrations.npz)."""
    if text.strip().isdigit():
        return integer(1, MAX_PLANNER_EPISODES)(text)
    if not Path(text).is_file():
        raise argparse.ArgumentTypeError(f"must be a number of episodes >= 1 or an existing file, got {text!r}")
    return Path(text)


def names(text: str) -> list[str]:
    """Comma-separated names, none empty or repeated: ``"random, greedy"`` -> ``["random", "greedy"]``."""
    parts = [part.strip() for part in text.split(",")]
    if not all(parts):
        raise argparse.ArgumentTypeError(f"an empty name in {text!r}: give comma-separated names, e.g. random,greedy")
    repeated = next((part for index, part in enumerate(parts) if part in parts[:index]), None)
    if repeated:
        raise argparse.ArgumentTypeError(f"{repeated!r} is given twice in {text!r}: give each name once")
    return parts
