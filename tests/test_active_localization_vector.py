"""``ActiveLocalizationVectorEnv``: sub-env ``i`` is the N = 1 env seeded ``s + i`` through terminations and
truncations (the seeding and autoreset contract), and its filter is raw filterpy's EKF update for update.

The checks every native vector env passes (seeding, API, bad input, SyncVectorEnv) run in ``test_vector_envs.py``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import vector_env_checks
from gymnasium.vector import AutoresetMode

from agents import GreedyEntropyAgent
from infonav_gym.envs.active_localization import N_PRIMITIVES, REWARD_TERMS, ActiveLocalizationVectorEnv

ENV_ID = "infonav/ActiveLocalization-v0"
TOLERANCE = 1e-9
GREEDY = GreedyEntropyAgent()


def _greedy(rng: np.random.Generator, info: dict) -> np.ndarray:
    keys = ("action_mask", "action_information_gain")
    return np.array([GREEDY.act(None, {key: info[key][copy] for key in keys}) for copy in range(len(info[keys[0]]))])


def _greedy_or_blind(rng: np.random.Generator, info: dict) -> np.ndarray:
    """Per sub-env: the greedy agent's action, a random valid one, or any action (masked ones are no-ops)."""
    mask = info["action_mask"]
    greedy = _greedy(rng, info)
    valid = np.array([rng.choice(np.flatnonzero(row)) for row in mask])
    blind = rng.integers(0, mask.shape[1], len(mask))
    return np.select([rng.random(len(mask)) < 0.4, rng.random(len(mask)) < 0.7], [greedy, valid], blind)


def _run_in_lockstep(n_envs: int, seed: int, n_steps: int, mode=AutoresetMode.NEXT_STEP, **config):
    return vector_env_checks.run_in_lockstep(ENV_ID, n_envs, seed, n_steps, _greedy_or_blind, mode, **config)


@pytest.mark.parametrize("n_envs", [1, 4])
@pytest.mark.parametrize("seed", [0, 21])
def test_sub_envs_equal_the_single_env_through_autoresets(n_envs, seed):
    terminated, truncated = _run_in_lockstep(n_envs, seed, n_steps=60, horizon=25)
    assert truncated >= n_envs  # every sub-env ended at least once, and was reset


@pytest.mark.parametrize(
    ("config", "ends"),
    [
        ({"goal_radius_m": 30.0}, "terminated"),  # the goal is reached within a few steps
        ({"max_position_std_m": 0.25}, "terminated"),  # the uncertainty bound is crossed
        ({"max_observations": 0, "n_obstacles": 0, "horizon": 20}, "truncated"),  # no budget: observe nothing
        ({"n_candidates": 5, "sensor_fov_rad": 1.0, "horizon": 12}, "truncated"),
    ],
    ids=["goal", "failure", "no-budget", "narrow-fov"],
)
def test_sub_envs_equal_the_single_env_in_other_configs(config, ends):
    terminated, truncated = _run_in_lockstep(3, 5, n_steps=45, **config)
    assert {"terminated": terminated, "truncated": truncated}[ends] >= 3


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_whole_greedy_episodes_equal_the_single_env(mode):
    """The greedy agent to the end of the default (100-step) episodes, and on into the next ones."""
    terminated, truncated = vector_env_checks.run_in_lockstep(ENV_ID, 3, 40, 120, _greedy, mode)
    assert terminated + truncated >= 3


def test_same_step_autoreset_gives_the_single_envs_last_and_reset_outputs():
    config = {"horizon": 9, "goal_radius_m": 29.0}  # episodes end both ways
    terminated, truncated = _run_in_lockstep(3, 6, 30, AutoresetMode.SAME_STEP, **config)
    assert terminated >= 1 and truncated >= 3


def test_next_step_autoreset_after_termination_and_truncation():
    env = gym.make_vec(
        ENV_ID, num_envs=2, horizon=3, goal_radius_m=33.0, failure_penalty=4.0, autoreset_mode="next_step"
    )
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    _, info = env.reset(seed=0)
    distance = info["distance_to_goal_m"]
    assert distance[0] > 33.0 and distance[1] > 33.0  # neither reached yet
    ended = np.zeros(2, dtype=bool)
    for step in range(1, 4):
        _, rewards, terminated, truncated, info = env.step(np.zeros(2, dtype=int))  # to the goal, observing nothing
        assert not (terminated & truncated).any()
        np.testing.assert_array_equal(terminated, info["goal_reached"] & ~ended)
        np.testing.assert_array_equal(info["reward_goal_bonus"], np.where(terminated, 10.0, 0.0))
        assert (truncated == (~ended & ~terminated & (step == 3))).all()
        ended |= terminated | truncated
        if ended.all():
            break
    assert ended.all()
    observations, rewards, terminated, truncated, info = env.step(np.full(2, 7))  # actions ignored
    assert not (terminated.any() or truncated.any()) and not rewards.any()
    np.testing.assert_array_equal(observations[:, 9], 0.0)  # elapsed fraction of the new episode
    np.testing.assert_array_equal(info["chosen_action"], -1)
    np.testing.assert_array_equal(info["observations_left"], env.unwrapped.config["max_observations"])
    assert all(info[f"_reward_{term}"].all() for term in REWARD_TERMS)  # each term, 0 after a reset
    assert not any(info[f"reward_{term}"].any() for term in REWARD_TERMS)
    assert not env.step(np.zeros(2, dtype=int))[3].any()


def test_a_no_op_keeps_the_budget_and_an_observation_spends_it():
    env = ActiveLocalizationVectorEnv(num_envs=3, max_observations=5)
    _, info = env.reset(seed=1)
    observing = N_PRIMITIVES + info["action_mask"][:, N_PRIMITIVES:].argmax(axis=1)  # the first visible landmark
    assert info["action_mask"][np.arange(3), observing].all()  # each sub-env sees one at the start
    hidden = int(np.flatnonzero(info["action_mask"][0] == 0)[0])
    actions = np.array([hidden, observing[1], 1])  # masked, observe a landmark, veer left
    _, rewards, _, _, info = env.step(actions)
    np.testing.assert_array_equal(info["observations_left"], [5, 4, 5])
    np.testing.assert_array_equal(info["reward_sensing_cost"], [0.0, -0.1, 0.0])
    np.testing.assert_array_equal(info["reward_motion_cost"], [0.0, -0.1, -0.1])  # a no-op stands still
    assert info["reward_mutual_information"][1] > 0 and rewards[0] == 0.0


@pytest.mark.parametrize(
    ("arguments", "match"),
    [
        ({"n_candidate": 8}, "n_candidate"),
        ({"n_candidates": 2}, "n_candidates"),
        ({"max_position_std_m": 0.05}, "must exceed initial_position_std_m"),
    ],
)
def test_bad_config_raises_as_in_the_single_env(arguments, match):
    with pytest.raises(ValueError, match=match):
        ActiveLocalizationVectorEnv(**{"num_envs": 2, **arguments})


def test_gymnasium_vector_wrappers_read_its_infos_at_terminations():
    vector_env_checks.check_episode_statistics(ENV_ID, horizon=10, goal_radius_m=31.0)  # terminated at the goal


def test_with_autoreset_disabled_sub_envs_step_on_past_their_end_until_reset():
    vector_env_checks.check_autoreset_disabled(ENV_ID)


@pytest.mark.parametrize("seed", [2, 7])
def test_the_filter_equals_filterpys_ekf_update_for_update(seed, monkeypatch):
    """Along a whole episode the env's EKF equals raw filterpy fed the same readings (x 1e-12, P 1e-10);
    each observation's ``mutual_information`` term is the MI of filterpy's update."""
    n_observed = vector_env_checks.check_filter_equals_filterpy(
        ENV_ID,
        lambda chosen: chosen // N_PRIMITIVES - 1 if chosen >= 0 else -1,
        monkeypatch,
        seed=seed,
        n_steps=100,
        max_observations=60,
        max_position_std_m=50.0,
    )
    assert n_observed >= 10
