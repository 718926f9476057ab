"""``infonav/RangeRegistration-v0`` and ICP on simulated terrain frame pairs (the paper's Section V).

The env contract (checkers, determinism, pickle, subprocess) is in ``test_envs.py``, the vector env's in
``test_vector_envs.py``; here the sub-envs of the vector env against the single env in the configs that matter.
"""

import math

import gymnasium as gym
import numpy as np
import pytest
import vector_env_checks
from gymnasium.vector import AutoresetMode

import infonav_gym  # noqa: F401
from agents import GreedyEntropyAgent, RandomAgent
from infonav_gym.envs.vector_infos import reward_terms_of
from infonav_gym.registration import icp
from infonav_gym.registration.frame_pairs import (
    DEFAULT_ODOMETRY_STD,
    FRAME_PAIR_ICP,
    registration_error,
    terrain_frame_pair,
)
from infonav_gym.registration.gicp import gicp_covariances
from infonav_gym.sensors.ladar import sensor_points

REGISTRATION_ID = "infonav/RangeRegistration-v0"


def test_icp_from_odometry_lowers_the_error_on_at_least_90_percent_of_50_terrain_pairs():
    improved, tilted = 0, 0
    for seed in range(50):
        pair = terrain_frame_pair(np.random.default_rng(seed))
        tilted += max(abs(a) for a in pair.current.attitude_rad) > math.radians(2.0)
        result = icp(
            sensor_points(pair.current),
            sensor_points(pair.previous),
            pair.odometry_motion,
            max_correspondence_distance=1.0,
            method="point_to_plane",
        )
        before = registration_error(pair.odometry_motion, pair.true_motion)
        improved += registration_error(result.transform, pair.true_motion) < before
    assert tilted >= 25, "the pairs should come from a pitching, rolling vehicle"
    assert improved >= 45, f"ICP lowered the error on only {improved} of 50 pairs"


def episode_return(env, agent, seed: int) -> tuple[float, list[float]]:
    observation, info = env.reset(seed=seed)
    agent.reset(seed=seed)
    total, errors, done = 0.0, [], False
    while not done:
        observation, reward, terminated, truncated, info = env.step(agent.act(observation, info))
        total += reward
        if info["registered"]:
            errors.append(info["error_after_m"])
        done = terminated or truncated
    return total, errors


def test_greedy_information_beats_random_patches_over_20_seeds():
    env = gym.make(REGISTRATION_ID, horizon=16).unwrapped  # 4 frame pairs per episode
    greedy = [episode_return(env, GreedyEntropyAgent(), seed) for seed in range(20)]
    random = [episode_return(env, RandomAgent(env.action_space.n), seed) for seed in range(20)]
    greedy_return, random_return = np.mean([g[0] for g in greedy]), np.mean([r[0] for r in random])
    assert greedy_return > random_return
    greedy_error = np.mean([e for g in greedy for e in g[1]])
    random_error = np.mean([e for r in random for e in r[1]])
    assert greedy_error < random_error


def test_a_pair_registers_after_picks_per_pair_picks_with_the_reward_its_terms_say():
    env = gym.make(REGISTRATION_ID, picks_per_pair=3, point_cost=1e-3).unwrapped
    _, info = env.reset(seed=1)
    for pick in range(3):
        mask_before = info["action_mask"].copy()
        action = int(np.argmax(info["action_information_gain"]))
        _, reward, _, _, info = env.step(action)
        if pick < 2:
            assert reward == 0.0 and info["registered"] is False
            assert info["action_mask"][action] == 0 and info["action_mask"].sum() == mask_before.sum() - 1
    assert info["registered"] is True
    terms = reward_terms_of(info)
    assert terms["error_reduction_m"] == pytest.approx(info["error_before_m"] - info["error_after_m"])
    assert terms["point_cost"] == pytest.approx(-1e-3 * info["n_control_points"])
    assert reward == pytest.approx(sum(terms.values()))
    assert info["action_mask"].sum() > 3, "a new pair starts with every patch that has returns"


def test_gain_is_the_mutual_information_a_patch_adds_to_the_chosen_ones():
    env = gym.make(REGISTRATION_ID).unwrapped
    _, info = env.reset(seed=2)
    first = int(np.argmax(info["action_information_gain"]))
    alone = info["action_information_gain"].copy()
    _, _, _, _, info = env.step(first)
    second = int(np.argmax(info["action_information_gain"]))
    information = env.vector.state.patch_information[0]
    root = np.linalg.cholesky(env.vector.state.pairs[0].motion_covariance)

    def mi(matrix):
        return 0.5 * np.linalg.slogdet(np.eye(6) + root.T @ matrix @ root)[1]

    assert alone[first] == pytest.approx(mi(information[first]))
    expected = mi(information[first] + information[second]) - mi(information[first])
    assert info["action_information_gain"][second] == pytest.approx(expected)
    assert expected < alone[second] + 1e-12, "information is submodular: a gain shrinks as the set grows"


def test_gicp_registers_the_chosen_points_with_whole_frame_covariances_kept_for_the_next_pair():
    """Two pairs: each registration equals ``icp`` with ``FRAME_PAIR_ICP`` and both whole frames' covariances."""
    env = gym.make(REGISTRATION_ID).unwrapped
    vector = env.vector
    _, info = env.reset(seed=3)
    for _ in range(2):
        pair, source, target = vector.state.pairs[0], vector.state.source_points[0], vector.state.target_points[0]
        patches = vector.state.patch_of_return[0]
        chosen = []
        while len(chosen) < env.config["picks_per_pair"]:
            chosen.append(int(np.argmax(info["action_information_gain"])))
            _, _, _, _, info = env.step(chosen[-1])
        assert info["registered"]
        rows = np.isin(patches, chosen)
        expected = icp(
            source[rows],
            target,
            pair.odometry_motion,
            max_iterations=env.config["icp_max_iterations"],
            **FRAME_PAIR_ICP,
            source_covariances=gicp_covariances(source)[rows],
            target_covariances=gicp_covariances(target),
        )
        np.testing.assert_array_equal(vector.state.last_registration["transform"][0], expected.transform)


@pytest.mark.parametrize(
    "key, value",
    [
        ("picks_per_pair", 0),
        ("patch_rows", 0),
        ("patch_rows", 33),
        ("patch_columns", 181),
        ("point_cost", -1.0),
        ("odometry_xy_std_m", 0.0),
        ("icp_method", "magic"),
        ("icp_method", "point_to_point"),  # with the default robust kernel, which it cannot weigh
        ("icp_robust_kernel", None),
        ("icp_robust_kernel", "welsch"),
        ("icp_kernel_scale_m", 0.0),
        ("max_correspondence_distance_m", 0.0),
    ],
)
def test_bad_config_raises_value_error_naming_the_key(key, value):
    with pytest.raises(ValueError, match=f"'{key}'"):
        gym.make(REGISTRATION_ID, **{key: value})


def test_ladar_range_noise_and_odometry_defaults_come_from_one_source():
    """``ladar_range_std_m`` reaches the scans (so the control-point errors); odometry defaults are frame_pair's."""
    env = gym.make(REGISTRATION_ID, ladar_range_std_m=0.05).unwrapped
    env.reset(seed=0)
    pair = env.vector.state.pairs[0]
    assert pair.current.range_std_m == pair.previous.range_std_m == 0.05
    default = gym.make(REGISTRATION_ID).unwrapped
    np.testing.assert_array_equal(default.vector.odometry_std, DEFAULT_ODOMETRY_STD)
    default.reset(seed=0)
    np.testing.assert_array_equal(
        default.vector.state.pairs[0].motion_covariance, np.diag(np.square(DEFAULT_ODOMETRY_STD))
    )


def _greedy_or_any(rng, info):
    """Per sub-env: the patch of largest gain, or one time in four any action (a masked one is the no-op)."""
    greedy = np.argmax(info["action_information_gain"], axis=1)
    return np.where(rng.random(len(greedy)) < 0.75, greedy, rng.integers(0, info["action_mask"].shape[1], len(greedy)))


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_sub_envs_equal_the_single_env_through_autoresets(mode):
    config = {"horizon": 5, "picks_per_pair": 2, "patch_rows": 2, "patch_columns": 3}
    assert vector_env_checks.run_in_lockstep(REGISTRATION_ID, 3, 4, 12, _greedy_or_any, mode, **config) == (0, 6)


def test_sub_envs_equal_the_single_env_with_point_to_point_icp_and_one_pick_per_pair():
    config = {"horizon": 4, "picks_per_pair": 1, "icp_method": "point_to_point", "icp_robust_kernel": "none"}
    assert vector_env_checks.run_in_lockstep(REGISTRATION_ID, 2, 9, 4, _greedy_or_any, **config) == (0, 2)
