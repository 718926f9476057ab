"""PettingZoo's own test suite over every registered team env, from the registry: a new team env is covered here
without editing a test (the parallel and AEC API tests, seeding, max_cycles, rendering, pickling)."""

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import pickle  # noqa: E402
from types import SimpleNamespace  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from conftest import assert_identical, random_valid_actions  # noqa: E402
from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, render_test  # noqa: E402

from infonav_gym.envs.parallel_view import pettingzoo_entry_points  # noqa: E402
from infonav_gym.registry import PARALLEL, registered_envs  # noqa: E402

API_CYCLES = 300
team_envs = pytest.mark.parametrize("entry", registered_envs(PARALLEL), ids=lambda entry: entry.id)


def entry_points(entry) -> SimpleNamespace:
    """The versioned-module functions of a registered team env (``parallel_env``, ``raw_env``, ``env``)."""
    parallel_env, raw_env, env = pettingzoo_entry_points(entry.load())
    return SimpleNamespace(parallel_env=parallel_env, raw_env=raw_env, env=env)


@team_envs
def test_pettingzoo_parallel_and_aec_api_tests_pass(entry):
    module = entry_points(entry)
    env = module.parallel_env()
    parallel_api_test(env, num_cycles=API_CYCLES)
    assert env.observation_space("robot_0") is env.observation_space("robot_0")
    assert env.action_space("robot_1") is env.action_space("robot_1")
    api_test(module.env(), num_cycles=API_CYCLES // 3)


@team_envs
def test_pettingzoo_seed_max_cycles_and_render_tests_pass(entry):
    module = entry_points(entry)
    parallel_seed_test(module.parallel_env, num_cycles=API_CYCLES // 3)
    max_cycles_test(module)
    render_test(module.env)


@team_envs
def test_a_pickled_env_continues_its_episode_exactly(entry):
    env = entry_points(entry).parallel_env()
    _, infos = env.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(3):
        _, _, _, _, infos = env.step(random_valid_actions(env, infos, rng))
    clone = pickle.loads(pickle.dumps(env))
    actions = random_valid_actions(env, infos, rng)
    assert_identical(env.step(actions), clone.step(actions))
