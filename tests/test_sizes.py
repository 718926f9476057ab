"""Sizes are bounded before memory is spent: ``num_envs`` against the available memory (each env's declared
``kb_per_copy``, held to a measurement here), every integer config key against its range."""

import tracemalloc

import gymnasium as gym
import numpy as np
import pytest

from infonav_gym import memory
from infonav_gym.config import stated_requirements
from infonav_gym.experiments.vector_timing import random_valid_actions, vector_env_ids
from infonav_gym.registry import env_entry, make_vector_env

VECTOR_ENVS = vector_env_ids()
GROWING_MAP, PATCHES = "cooperative_exploration_v0", "infonav/RangeRegistration-v0"  # copies grow with a config key
DECLARATION_FACTOR = 4.0  # the declared memory a copy is within this factor of the one measured here


def test_every_env_declares_its_memory_a_copy():
    assert len(VECTOR_ENVS) == 9
    for env_id in VECTOR_ENVS:
        assert env_entry(env_id).load_vector().traits.kb_per_copy > 0, env_id


@pytest.mark.parametrize("env_id", VECTOR_ENVS)
def test_more_copies_than_memory_holds_are_refused_before_any_is_made(env_id, monkeypatch):
    monkeypatch.setattr(memory, "available_bytes", lambda: 10**9)
    kb = env_entry(env_id).load_vector().traits.kb_per_copy
    message = rf"num_envs=10000000 of \w+ \(about {kb:.4g} kB a copy\) needs about [\d.]+ GB of memory; 1.0 GB are"
    with pytest.raises(ValueError, match=message):
        make_vector_env(env_id, 10**7)
    if env_id.startswith("infonav/"):
        with pytest.raises(ValueError, match=message):
            gym.make_vec(env_id, num_envs=10**7)


@pytest.mark.parametrize("num_envs", [0, -1, 2.5, True, "3", None])
def test_num_envs_must_be_an_int_of_at_least_one(num_envs):
    with pytest.raises(ValueError, match=r"num_envs of LandmarkSelectionVectorEnv must be an int >= 1, got"):
        make_vector_env("infonav/LandmarkSelection-v0", num_envs)


def _traced_peak_bytes(env_id: str, num_envs: int, config: dict) -> int:
    """Peak traced allocation [bytes] while building ``num_envs`` copies, resetting them and taking one step."""
    tracemalloc.start()
    try:
        env = make_vector_env(env_id, num_envs, **config)
        env.reset(seed=0)
        env.step(random_valid_actions(env.action_masks(), np.random.default_rng(0)))
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize(
    ("env_id", "config"),
    [(env_id, {}) for env_id in VECTOR_ENVS]
    + [(GROWING_MAP, {"map_cells_per_side": 60}), (PATCHES, {"patch_rows": 16})],
)
def test_the_declared_memory_a_copy_matches_a_measurement(env_id, config):
    """The marginal traced memory a copy (17 copies against 1, numpy's arrays included) against ``copy_kb()`` (the
    traits' ``kb_per_copy`` at the defaults, which the benchmark measures as peak RSS growth, ``*_kb_per_env``):
    within ``DECLARATION_FACTOR``, at the defaults and where a config key makes copies larger."""
    peaks = [_traced_peak_bytes(env_id, n, config) for n in (1, 17, 1, 17)]  # the first two: imports, compiles
    measured_kb = (peaks[3] - peaks[2]) / 16 / 1024
    declared_kb = make_vector_env(env_id, 1, **config).copy_kb()
    assert 1 / DECLARATION_FACTOR <= measured_kb / declared_kb <= DECLARATION_FACTOR, (measured_kb, declared_kb)


def _integer_keys(env_id: str) -> dict[str, str]:
    """Each integer config key of ``env_id`` with the range its check states."""
    env_class = env_entry(env_id).load_vector()
    with stated_requirements() as log:
        env_class(num_envs=1)
    defaults = env_class.default_config()
    return {key: log[key][0] for key, value in defaults.items() if type(value) is int}


@pytest.mark.parametrize("env_id", VECTOR_ENVS)
def test_every_integer_config_key_has_an_upper_end_named_in_one_line(env_id):
    keys = _integer_keys(env_id)
    assert keys
    for key, requirement in keys.items():
        assert requirement.startswith("an integer in ["), (key, requirement)
        with pytest.raises(ValueError, match=rf"config key '{key}' of \w+ must be an integer in \[\d+, \d+\]"):
            make_vector_env(env_id, 1, **{key: 10**12})
