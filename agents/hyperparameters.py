"""Every PPO hyperparameter ``infonav train`` takes, with its type and range, in one table: ``HYPERPARAMETERS``.
Numbers YAML 1.1 reads as strings (``3e-4``) are numbers; NaN and infinities are refused; ``batch_size`` is 2 or
more (MaskablePPO normalizes every minibatch's advantages)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from typing import NamedTuple

LINEAR = "lin_"  # rl-zoo's lin_<start>: annealed linearly from start to 0 over training
ACTIVATIONS = {"tanh": "Tanh", "relu": "ReLU"}  # policy_kwargs.activation_fn: its torch.nn class
MAX_N_ENVS = 4096  # env copies in one process
MAX_N_STEPS = 65536  # steps per copy in one rollout
MAX_LAYER_WIDTH = 4096


class Rule(NamedTuple):
    """What a hyperparameter may be (``allowed``, said in the error) and ``check(value, name) -> value as used``."""

    allowed: str
    check: Callable[[object, str], object]


def _refuse(name: str, allowed: str, value) -> None:
    raise ValueError(f"hyperparameter {name} must be {allowed}, got {value!r}")


def _leaf(allowed: str, accepts: Callable[[object], bool], used=lambda value: value) -> Rule:
    def check(value, name):
        if not accepts(value):
            _refuse(name, allowed, value)
        return used(value)

    return Rule(allowed, check)


def _as_float(value) -> float:
    """A number, or a string YAML 1.1 did not read as one (``"3e-4"``), as a float; NaN for anything else."""
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        return math.nan
    try:
        return float(value)
    except ValueError:
        return math.nan


def number(low: float, high: float = math.inf, *, above: bool = False, schedule: bool = False, null: bool = False):
    """A finite number from ``low`` (excluded with ``above``) to ``high``; with ``schedule`` also ``lin_<start>``, with
    ``null`` also null (SB3's "off")."""

    def in_range(value) -> bool:
        x = _as_float(value)
        return math.isfinite(x) and (x > low if above else x >= low) and x <= high

    def accepts(value) -> bool:
        linear = schedule and isinstance(value, str) and value.startswith(LINEAR)
        return (null and value is None) or (in_range(value.removeprefix(LINEAR)) if linear else in_range(value))

    if high == math.inf:
        allowed = f"a finite number {'>' if above else '>='} {low:g}"
    else:
        allowed = f"a number in {'(' if above else '['}{low:g}, {high:g}]"
    allowed += f" or {LINEAR}<start> with such a start" * schedule + " or null" * null
    as_number = lambda value: _as_float(value) if isinstance(value, str) and in_range(value) else value  # noqa: E731
    return _leaf(allowed, accepts, as_number)


def integer(low: int, high: int | None = None) -> Rule:
    allowed = f"an integer >= {low}" if high is None else f"an integer from {low} to {high}"
    return _leaf(allowed, lambda value: type(value) is int and low <= value <= (math.inf if high is None else high))


def choice(*options: str) -> Rule:
    return _leaf(f"one of {', '.join(options)}", lambda value: isinstance(value, str) and value in options)


def mapping(rules: dict[str, Rule], allowed_too: Rule | None = None) -> Rule:
    """A mapping whose keys are among ``rules``, each checked by its rule; or a value ``allowed_too`` takes."""
    allowed = f"a mapping with keys from {', '.join(rules)}"
    if allowed_too is not None:
        allowed = f"{allowed_too.allowed}, or {allowed}"

    def check(value, name):
        if not isinstance(value, dict):
            with contextlib.suppress(ValueError, AttributeError):  # AttributeError: no allowed_too
                return allowed_too.check(value, name)
            _refuse(name, allowed, value)
        for key in value:
            if key not in rules:
                where = f" of {name}" if name else ""
                raise ValueError(f"unknown hyperparameter {key!r}{where}: the keys are {', '.join(rules)}")
        return {key: rules[key].check(item, f"{name}.{key}" if name else key) for key, item in value.items()}

    return Rule(allowed, check)


FLAG = _leaf("true or false", lambda value: isinstance(value, bool))
LAYERS = _leaf(
    f"a list of layer widths from 1 to {MAX_LAYER_WIDTH}",
    lambda value: isinstance(value, list) and all(type(w) is int and 1 <= w <= MAX_LAYER_WIDTH for w in value),
)
POSITIVE = number(0, above=True)
HYPERPARAMETERS = mapping(
    {
        "n_envs": integer(1, MAX_N_ENVS),
        "policy": choice("MlpPolicy"),
        "n_timesteps": integer(1),  # rl-zoo's; infonav train's --timesteps decides
        "normalize": mapping(
            {"norm_obs": FLAG, "norm_reward": FLAG} | dict.fromkeys(("clip_obs", "clip_reward", "epsilon"), POSITIVE),
            allowed_too=FLAG,
        ),
        "learning_rate": number(0, above=True, schedule=True),
        "n_steps": integer(1, MAX_N_STEPS),
        "batch_size": integer(2),
        "n_epochs": integer(1),
        "gamma": number(0, 1),
        "gae_lambda": number(0, 1),
        "clip_range": number(0, 1, above=True, schedule=True),
        "clip_range_vf": number(0, above=True, null=True),
        "normalize_advantage": FLAG,
        "ent_coef": number(0),
        "vf_coef": number(0),
        "max_grad_norm": POSITIVE,
        "target_kl": number(0, above=True, null=True),
        "stats_window_size": integer(1),
        "policy_kwargs": mapping(
            {
                "net_arch": mapping({"pi": LAYERS, "vf": LAYERS}, allowed_too=LAYERS),
                "activation_fn": choice(*ACTIVATIONS),
                "ortho_init": FLAG,
                "share_features_extractor": FLAG,
            }
        ),
    }
)


def checked_block(block: dict, where: str) -> dict:
    """``block`` with its values as used (``"3e-4"`` a float), once every key and value is seen to be allowed
    (``ValueError`` naming the key, its allowed range and ``where``)."""
    try:
        return HYPERPARAMETERS.check(block, "")
    except ValueError as error:
        raise ValueError(f"{error} ({where})") from None
