"""Argparse ``type=`` functions of the ``infonav`` command: a bad value is refused before any work starts."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

SEED_LIMIT = 2**32  # seeds below it suit gymnasium, numpy's legacy seeding and Stable-Baselines3 alike


def _checked(text: str, convert, requirement: str, accepts):
    """``convert(text)`` if it converts and ``accepts`` the value, else ``ArgumentTypeError``: it must be
    ``requirement``."""
    try:
        value = convert(text)
    except ValueError:
        value = None
    if value is None or not accepts(value):
        raise argparse.ArgumentTypeError(f"must be {requirement}, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An integer >= 1 (a count: episodes, steps, workers, ...)."""
    return _checked(text, int, "an integer >= 1", lambda value: value >= 1)


def non_negative_int(text: str) -> int:
    """An integer >= 0 (a count that may be none)."""
    return _checked(text, int, "an integer >= 0", lambda value: value >= 0)


def seed(text: str) -> int:
    """A seed: an integer in ``[0, SEED_LIMIT)``."""
    requirement = f"an integer from 0 to {SEED_LIMIT - 1} (2**32 - 1)"
    return _checked(text, int, requirement, lambda value: 0 <= value < SEED_LIMIT)


def positive_float(text: str) -> float:
    """A finite number > 0 (a duration)."""
    return _checked(text, float, "a finite number > 0", lambda value: 0 < value < math.inf)


def non_negative_float(text: str) -> float:
    """A finite number >= 0 (a start time)."""
    return _checked(text, float, "a finite number >= 0", lambda value: 0 <= value < math.inf)


def end_time(text: str) -> float:
    """A number > 0; ``inf`` for the end of the data."""
    return _checked(text, float, "a number > 0 (inf: the end)", lambda value: value > 0)


def episodes_or_file(text: str) -> int | Path:
    """A number of episodes (an integer >= 1), or an existing file (saved episodes, e.g. demonstrations.npz)."""
    if text.strip().isdigit():
        return positive_int(text)
    if not Path(text).is_file():
        raise argparse.ArgumentTypeError(f"must be a number of episodes >= 1 or an existing file, got {text!r}")
    return Path(text)


def names(text: str) -> list[str]:
    """Comma-separated names, none empty: ``"random, greedy"`` -> ``["random", "greedy"]``."""
    parts = [part.strip() for part in text.split(",")]
    if not all(parts):
        raise argparse.ArgumentTypeError(f"an empty name in {text!r}: give comma-separated names, e.g. random,greedy")
    return parts


def comma_separated(element):
    """A type function for comma-separated values, each checked by the type function ``element``."""

    def parse(text: str) -> list:
        return [element(part) for part in text.split(",")]

    return parse
