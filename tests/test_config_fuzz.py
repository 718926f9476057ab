"""Config fuzz: every default key of every env, set in turn to a bad value, is refused or harmless.

The bad values: 0, a negative, 1e12, 1e308, inf, NaN, a wrong type, and -1 and 10**12 for an
int key. Each trial either raises a ``ValueError`` naming the key at construction, or the env
runs reset and 10 steps with finite observations, rewards and infos. A trial that hangs (an
alarm after ``TRIAL_TIMEOUT_S``) or needs more than ``TRIAL_MEMORY_BYTES`` of new address space
fails.
"""

from __future__ import annotations

import math
import numbers
import resource
import signal
from contextlib import contextmanager

import gymnasium as gym
import numpy as np
import pytest

from infonav_gym.registry import PARALLEL, env_entry, make_env, registered_envs

TEAM_ENV = "cooperative_localization_v0"
ENV_IDS = [entry.id for entry in registered_envs()]  # every registered env, Gymnasium and PettingZoo alike
N_STEPS = 10
TRIAL_TIMEOUT_S = 30
TRIAL_MEMORY_BYTES = 4 * 2**30


def is_team(env_id: str) -> bool:
    return env_entry(env_id).api == PARALLEL


def default_config(env_id: str) -> dict:
    env = make_env(env_id)
    config = (env if is_team(env_id) else env.unwrapped).default_config()
    env.close()
    return config


CASES = [(env_id, key) for env_id in ENV_IDS for key in sorted(default_config(env_id))]


def bad_values(default) -> list:
    """0, a negative, 1e12, 1e308, inf, NaN, a wrong type and, for an int default, -1 and 10**12."""
    values = [0, -1.5, 1e12, 1e308, math.inf, math.nan, "wrong" if not isinstance(default, str) else 3]
    if isinstance(default, int) and not isinstance(default, bool):
        values += [-1, 10**12]
    return values


@contextmanager
def bounded(what: str):
    """Fail after ``TRIAL_TIMEOUT_S`` s; no allocation may grow the address space by ``TRIAL_MEMORY_BYTES``."""

    def alarm(signum, frame):
        raise TimeoutError(f"{what} did not finish within {TRIAL_TIMEOUT_S} s")

    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    with open("/proc/self/statm") as statm:
        in_use = int(statm.read().split()[0]) * resource.getpagesize()
    limit = in_use + TRIAL_MEMORY_BYTES
    resource.setrlimit(resource.RLIMIT_AS, (limit if hard == resource.RLIM_INFINITY else min(limit, hard), hard))
    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(TRIAL_TIMEOUT_S)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def non_finite_paths(value, path: str = "") -> list[str]:
    """Where ``value`` (numbers, arrays, dicts, lists and tuples of them, recursively) holds NaN or inf."""
    if isinstance(value, dict):
        return [bad for key, item in value.items() for bad in non_finite_paths(item, f"{path}[{key!r}]")]
    if isinstance(value, (list, tuple)):
        return [bad for index, item in enumerate(value) for bad in non_finite_paths(item, f"{path}[{index}]")]
    if isinstance(value, np.ndarray) and value.dtype.kind in "fc":
        return [] if np.all(np.isfinite(value)) else [path]
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return [] if math.isfinite(value) else [path]
    return []


def run_single(env, rng: np.random.Generator) -> list[str]:
    """Reset and ``N_STEPS`` steps of a Gymnasium env with valid actions; the non-finite outputs."""
    observation, info = env.reset(seed=0)
    bad = non_finite_paths({"observation": observation, "info": info})
    for step in range(N_STEPS):
        valid = np.flatnonzero(info["action_mask"])
        action = int(rng.choice(valid)) if valid.size else 0
        observation, reward, terminated, truncated, info = env.step(action)
        bad += non_finite_paths({"observation": observation, "reward": reward, "info": info}, f"step {step} ")
        if terminated or truncated:
            observation, info = env.reset()
    return bad


def run_team(env, rng: np.random.Generator) -> list[str]:
    """Reset and ``N_STEPS`` parallel steps of a team env with valid actions; the non-finite outputs."""
    observations, infos = env.reset(seed=0)
    bad = non_finite_paths({"observations": observations, "infos": infos})
    for step in range(N_STEPS):
        actions = {agent: int(rng.choice(np.flatnonzero(infos[agent]["action_mask"]))) for agent in env.agents}
        observations, rewards, _, _, infos = env.step(actions)
        bad += non_finite_paths({"observations": observations, "rewards": rewards, "infos": infos}, f"step {step} ")
        if not env.agents:
            observations, infos = env.reset()
    return bad


@pytest.mark.parametrize(("env_id", "key"), CASES)
def test_a_bad_config_value_is_refused_naming_the_key_or_runs_finite(env_id, key):
    default = default_config(env_id)[key]
    for value in bad_values(default):
        trial = f"{env_id} with {key}={value!r}"
        with bounded(trial):
            try:
                env = make_env(env_id, **{key: value})
            except ValueError as error:
                assert key in str(error), f"{trial}: the error does not name the key: {error}"
                continue
            rng = np.random.default_rng(0)
            bad = run_team(env, rng) if is_team(env_id) else run_single(env, rng)
            env.close()
        assert not bad, f"{trial}: non-finite outputs at {bad[:5]}"


@pytest.mark.parametrize(
    ("env_id", "key", "value", "allowed"),
    [
        ("infonav/LandmarkSelection-v0", "time_step_s", math.inf, "(0, 60] s"),  # was an OverflowError in World.step
        ("infonav/LandmarkSelection-v0", "n_obstacles", 10**6, "[0, 100]"),  # hung in the field's rejection sampling
        ("infonav/SensorSelection-v0", "scene_size_m", 1e12, "[0.5, 1000] m"),  # was a MemoryError in make_terrain
        ("infonav/ActiveLocalization-v0", "odometry_speed_std_mps", math.inf, "(0, 10] m/s"),  # inf observations
        (TEAM_ENV, "gps_outages", 0, "sequence of (robot, start_s, end_s) triples"),  # was a TypeError
        (TEAM_ENV, "gps_std_m", 1e-12, "[0.001, 100] m"),  # made P singular: NaN gains
        ("infonav/LandmarkSelection-v0", "range_std_m", -0.1, "[0.0001, 100] m"),  # named no key
    ],
)
def test_known_bad_values_are_refused_with_the_allowed_range(env_id, key, value, allowed):
    with pytest.raises(ValueError) as error:
        make_env(env_id, **{key: value})
    message = str(error.value)
    assert key in message and allowed in message and repr(value) in message


def test_a_sensor_parameter_error_names_the_env_key_and_the_sensor_field():
    with pytest.raises(ValueError) as error:
        gym.make("infonav/LandmarkSelection-v0", sensor_max_range_m=math.nan)
    assert str(error.value) == (
        "config key 'sensor_max_range_m' of LandmarkSelectionEnv must be in (0, 1000] m, got nan "
        "(the RangeBearingSensor's max_range_m)"
    )
