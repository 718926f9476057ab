"""The checks every native vector env passes (``vector_env_checks``), on each id registered with a vector entry point.

A new native vector env gets them by being registered; its own test file adds the same-numbers runs against
its single env in the configs that matter to it.
"""

from __future__ import annotations

import gc
import os
import sys

import gymnasium as gym
import numpy as np
import pytest
import vector_env_checks
from gymnasium.vector import AutoresetMode

from infonav_gym.compiled import MIN_COPIES_PER_THREAD
from infonav_gym.experiments.vector_timing import random_valid_actions
from infonav_gym.registry import GYMNASIUM, make_vector_env, registered_envs

VECTOR_ENV_IDS = [entry.id for entry in registered_envs(GYMNASIUM) if entry.vector_entry_point is not None]
NATIVE_ENTRIES = [entry for entry in registered_envs() if entry.vector_entry_point is not None]  # team envs too
CHECKS = [
    vector_env_checks.check_seeding,
    vector_env_checks.check_vector_api,
    vector_env_checks.check_other_vectorizations,
    vector_env_checks.check_step_before_reset_raises,
    vector_env_checks.check_bad_actions_raise_naming_the_sub_env,
    vector_env_checks.check_masked_actions_follow_invalid_action,
    vector_env_checks.check_bad_reset_arguments_raise,
    vector_env_checks.check_bad_vector_arguments_raise,
]


def test_the_native_vector_envs_are_found():
    assert {
        "infonav/LandmarkSelection-v0",
        "infonav/ActiveLocalization-v0",
        "infonav/SensorSelection-v0",
        "infonav/RangeRegistration-v0",
    } <= set(VECTOR_ENV_IDS)


@pytest.mark.parametrize("env_id", VECTOR_ENV_IDS)
@pytest.mark.parametrize("check", CHECKS, ids=lambda check: check.__name__.removeprefix("check_"))
def test_vector_env_check(env_id, check):
    check(env_id)


@pytest.mark.parametrize("env_id", VECTOR_ENV_IDS)
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_equal_to_gymnasiums_sync_vectorization(env_id, mode):
    assert vector_env_checks.check_matches_sync_vectorization(env_id, mode, n_steps=40, horizon=12) >= 6


@pytest.mark.parametrize("env_id", VECTOR_ENV_IDS)
def test_gymnasium_vector_wrappers_read_the_infos(env_id):
    vector_env_checks.check_episode_statistics(env_id, horizon=10)


@pytest.mark.parametrize("env_id", VECTOR_ENV_IDS)
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_render_draws_sub_env_0(env_id, mode):
    pytest.importorskip("pygame")
    vector_env_checks.check_render_draws_sub_env_0(env_id, mode, n_steps=12, horizon=4)


@pytest.mark.parametrize("entry", NATIVE_ENTRIES, ids=lambda entry: entry.id)
@pytest.mark.parametrize("num_envs", [0, -1])
def test_no_copies_is_a_value_error_that_leaves_nothing_to_report_when_collected(entry, num_envs, monkeypatch):
    unraisable = []  # what VectorEnv.__del__ would print on stderr
    monkeypatch.setattr(sys, "unraisablehook", unraisable.append)
    makers = [make_vector_env] + ([gym.make_vec] if entry.api == GYMNASIUM else [])
    for make in makers:
        with pytest.raises(ValueError, match=rf"num_envs of \w+ must be an int >= 1, got {num_envs}"):
            make(entry.id, num_envs=num_envs)
        gc.collect()
    assert [hook.exc_value for hook in unraisable] == []


@pytest.mark.parametrize("num_threads", [0, 2.0, os.cpu_count() + 1])
def test_num_threads_outside_one_to_the_cpus_is_a_value_error(num_threads):
    with pytest.raises(ValueError, match=rf"num_threads of \w+ must be an int from 1 to {os.cpu_count()}"):
        make_vector_env("infonav/LandmarkSelection-v0", num_envs=2, num_threads=num_threads)


@pytest.mark.parametrize("env_id", ["infonav/LandmarkSelection-v0", "infonav/ActiveLocalization-v0"])
@pytest.mark.parametrize("autoreset_mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_copies_on_two_threads_give_the_numbers_of_one(env_id, autoreset_mode):
    """Enough copies for two chunks (``MIN_COPIES_PER_THREAD`` each), through autoresets: every output the same."""
    num_envs, outputs = 2 * MIN_COPIES_PER_THREAD + 3, {}
    for num_threads in (1, 2):
        env = make_vector_env(env_id, num_envs, num_threads=num_threads, autoreset_mode=autoreset_mode, horizon=6)
        rng, steps = np.random.default_rng(0), [env.reset(seed=3)]
        for _ in range(14):
            steps.append(env.step(random_valid_actions(env.action_masks(), rng)))
        outputs[num_threads] = steps
    np.testing.assert_equal(*map(comparable, outputs.values()))  # observations, rewards, flags, infos, final ones too


def comparable(value):
    """``value`` with object arrays (``final_obs``) as lists, nested alike, for ``np.testing.assert_equal``."""
    if isinstance(value, dict):
        return {key: comparable(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.dtype == object):
        return [comparable(item) for item in value]
    return value
