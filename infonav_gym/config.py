"""Config dictionaries: defaults merged with user overrides, every key and value checked."""

from __future__ import annotations

import difflib
import numbers
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np


def merge_config(defaults: dict, overrides: dict, owner: str) -> dict:
    """``defaults`` updated by ``overrides``; ``ValueError`` for a key it lacks (naming the closest) or a wrong type."""
    merged = dict(defaults)
    for key, value in overrides.items():
        if key not in defaults:
            close = difflib.get_close_matches(key, list(defaults), n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ValueError(f"unknown config key {key!r} for {owner}.{hint} Valid keys: {', '.join(sorted(defaults))}")
        merged[key] = _typed_like(defaults[key], value, f"config key {key!r} of {owner}")
    return merged


KINDS = {bool: "a bool (true or false)", int: "a finite integer", float: "a number", str: "a string"}
_ACCEPTED = {bool: (bool, np.bool_), int: numbers.Integral, float: numbers.Real, str: str}  # what each kind takes


def _typed_like(default, value, where: str):
    """``value`` as the type of ``default``; ``ValueError`` naming ``where`` unless it is one (an int for a float
    is one, a bool for neither; NaN and infinities are left to the key's range check)."""
    kind = next((kind for kind in KINDS if isinstance(default, kind)), None)  # bool before int: a bool is an int
    if kind is None:
        return value
    if isinstance(value, _ACCEPTED[kind]) and (kind is bool or not isinstance(value, bool)):
        return value if kind is str else kind(value)
    raise ValueError(f"{where} must be {KINDS[kind]} (like the default {default!r}), got {value!r}")


_requirement_logs: list[dict[str, list[str]]] = []  # the logs of the open ``stated_requirements`` contexts
_open_key_maps: list[dict[str, str]] = []  # key_of_parameter of the open ``config_keys`` while a log is open


@contextmanager
def stated_requirements():
    """Yields a dict, config key -> the requirements the checks run inside state (``["in (0, 1000] m"]``), in their
    errors' words: making an env inside documents its keys' allowed values from the checks themselves."""
    log: dict[str, list[str]] = {}
    _requirement_logs.append(log)
    try:
        yield log
    finally:
        _requirement_logs.remove(log)


def _note_requirement(parameter: str, requirement: str, *, is_key: bool = False) -> None:
    """Add ``requirement`` to the open logs, under ``parameter``'s config key (``parameter`` itself if ``is_key``)."""
    key = parameter if is_key else next((keys[parameter] for keys in _open_key_maps[::-1] if parameter in keys), None)
    if key is None:  # a parameter no config key sets
        return
    for log in _requirement_logs:
        if requirement not in log.setdefault(key, []):
            log[key].append(requirement)


def check_choice(config: dict, key: str, choices, owner: str) -> None:
    """Raise ``ValueError`` unless ``config[key]`` is one of ``choices``."""
    requirement = f"one of {sorted(choices)}"
    if _requirement_logs:
        _note_requirement(key, requirement, is_key=True)
    if config[key] not in choices:
        raise ValueError(f"config key {key!r} of {owner} must be {requirement}, got {config[key]!r}")


class ParameterError(ValueError):
    """A parameter value outside its allowed range (``owner``, ``parameter``, ``requirement`` such as ``"in (0,
    1000] m"``, ``value``); a config layer turns it into an error naming its key."""

    def __init__(self, owner: str, parameter: str, requirement: str, value):
        self.owner, self.parameter, self.requirement, self.value = owner, parameter, requirement, value
        super().__init__(f"{owner} {parameter} must be {requirement}, got {value!r}")


def check_number(
    owner: str,
    parameter: str,
    value,
    low: float,
    high: float,
    *,
    open_low: bool = False,
    open_high: bool = False,
    unit: str = "",
) -> None:
    """``ParameterError`` unless ``value`` is a real number from ``low`` to ``high`` (finite; ``open_*`` excludes a
    bound); ``unit`` follows the interval in the message."""
    real = isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
    inside = real and (low < value if open_low else low <= value) and (value < high if open_high else value <= high)
    if inside and not _requirement_logs:
        return
    interval = f"{'(' if open_low else '['}{low:g}, {high:g}{')' if open_high else ']'}"
    requirement = f"in {interval}{' ' + unit if unit else ''}"
    _note_requirement(parameter, requirement)
    if not inside:
        raise ParameterError(owner, parameter, requirement, value)


def check_integer(owner: str, parameter: str, value, low: int, high: int) -> None:
    """Raise ``ParameterError`` unless ``value`` is an integer (not a bool) in ``[low, high]``."""
    requirement = f"an integer in [{low}, {high}]"
    if _requirement_logs:
        _note_requirement(parameter, requirement)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or not low <= value <= high:
        raise ParameterError(owner, parameter, requirement, value)


@dataclass(frozen=True)
class Interval:
    """The allowed values of a number parameter, from ``low`` to ``high`` (finite): only integers (not bools) if
    ``integer``; ``open_*`` excludes a bound (reals only); ``unit`` follows the interval in messages."""

    low: float
    high: float
    integer: bool = False
    open_low: bool = False
    open_high: bool = False
    unit: str = ""

    def check(self, owner: str, parameter: str, value) -> None:
        """``ParameterError`` (naming ``owner`` and ``parameter``) unless ``value`` lies in the interval."""
        if self.integer:
            check_integer(owner, parameter, value, self.low, self.high)
        else:
            bounds = {"open_low": self.open_low, "open_high": self.open_high, "unit": self.unit}
            check_number(owner, parameter, value, self.low, self.high, **bounds)


def check_arguments(owner: str, intervals: dict[str, Interval], **arguments) -> None:
    """``ParameterError`` for the first keyword argument outside its ``intervals`` entry (each must have one)."""
    for name, value in arguments.items():
        intervals[name].check(owner, name, value)


@contextmanager
def config_keys(owner: str, key_of_parameter: dict[str, str]):
    """Turn a ``ParameterError`` raised inside into a ``ValueError`` of ``owner`` naming the config key of its
    parameter (``key_of_parameter``, e.g. ``{"max_range_m": "sensor_max_range_m"}``; others pass unchanged)."""
    logging = bool(_requirement_logs)
    if logging:
        _open_key_maps.append(key_of_parameter)
    try:
        yield
    except ParameterError as error:
        key = key_of_parameter.get(error.parameter)
        if key is None:
            raise
        source = "" if error.owner == owner else f" (the {error.owner}'s {error.parameter})"
        raise ValueError(
            f"config key {key!r} of {owner} must be {error.requirement}, got {error.value!r}{source}"
        ) from None
    finally:
        if logging:
            _open_key_maps.pop()


def from_config(factory, config: dict, key_of_parameter: dict[str, str], owner: str):
    """``factory(parameter=config[key], ...)`` over ``key_of_parameter``; a bad value's error names its config key."""
    with config_keys(owner, key_of_parameter):
        return factory(**{parameter: config[key] for parameter, key in key_of_parameter.items()})


def check_config_arguments(
    config: dict, owner: str, source: str, intervals: dict[str, Interval], key_of_argument: dict[str, str]
) -> None:
    """``check_arguments(source, intervals, argument=config[key], ...)`` over ``key_of_argument``; errors name the key.

    For the arguments an env hands a builder (a scenario), checked at the env's construction.
    """
    with config_keys(owner, key_of_argument):
        check_arguments(source, intervals, **{argument: config[key] for argument, key in key_of_argument.items()})


def check_config(config: dict, owner: str, intervals: dict[str, Interval]) -> None:
    """Each ``config[key]`` in its ``intervals[key]``, or ``ValueError`` naming the key and the interval."""
    check_config_arguments(config, owner, owner, intervals, {key: key for key in intervals})
