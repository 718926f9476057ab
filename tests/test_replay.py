"""Replay building blocks: the replay clock, selection policies, the cooperative landmark model."""

from types import SimpleNamespace

import numpy as np
import pytest

from infonav_gym.datasets.timeline import LANDMARK, ROBOT, Timeline, _tick_means, dead_reckoning
from infonav_gym.estimation.ekf import PoseEKF
from infonav_gym.experiments.replay.filters import ReplayConfig, _CooperativeFilter
from infonav_gym.experiments.replay.policies import select_greedy, select_nearest, select_random
from infonav_gym.information import expected_information_gain


def test_tick_means_integrate_held_odometry_exactly():
    odometry = np.array([[10.0, 1.0, 0.5], [10.03, 2.0, -0.5], [10.05, 0.0, 0.0]])
    means = _tick_means(odometry, np.array([9.98, 10.0, 10.02, 10.04, 10.06]))
    np.testing.assert_allclose(means[:, 0], [0.0, 1.0, 1.5, 1.0], atol=1e-12)  # 0 before the first reading
    np.testing.assert_allclose(means[:, 1], [0.0, 0.5, 0.0, -0.25], atol=1e-12)


def test_dead_reckoning_matches_the_filter_prediction():
    rng = np.random.default_rng(0)
    controls = rng.uniform([0.0, -0.5], [0.3, 0.5], size=(50, 1, 2))
    timeline = Timeline(start_time=0.0, dt=0.02, controls=controls, events=[np.zeros((0, 6))])
    ekf = PoseEKF([1.0, 2.0, 3.0], np.eye(3) * 0.01)
    for control in controls[:, 0]:
        ekf.predict(control, 0.02, np.eye(2) * 1e-4)
    np.testing.assert_allclose(dead_reckoning(np.array([[1.0, 2.0, 3.0]]), timeline)[-1, 0], ekf.x, atol=1e-12)


def test_greedy_takes_the_largest_expected_gain_then_conditions_on_it():
    P = np.diag([1.0, 1.0, 0.1])
    R = np.diag([0.01, 0.01])
    along_x = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    along_y = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    weak = np.array([[0.1, 0.0, 0.0], [0.0, 0.0, 0.1]])
    H = np.array([weak, along_x, along_x, along_y])
    first = select_greedy(P, H, R, 1)
    assert first == [int(np.argmax(expected_information_gain(P, H, R)))] == [1]
    assert select_greedy(P, H, R, 2) == [1, 3], "a repeat of the same information is worth less than y"


def test_nearest_and_random():
    assert select_nearest(np.array([3.0, 1.0, 2.0, 1.0]), 2) == [1, 3]
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    chosen = select_random(10, 3, rng_a)
    assert chosen == select_random(10, 3, rng_b) and len(set(chosen)) == 3
    assert sorted(select_random(2, 3, rng_a)) == [0, 1]


def test_config_rejects_unknown_policy_and_empty_outage():
    with pytest.raises(ValueError, match="unknown policy 'oracle'"):
        ReplayConfig(policy="oracle")
    with pytest.raises(ValueError, match="outage must end after it starts"):
        ReplayConfig(outage_start_s=5.0, outage_end_s=5.0)


def test_cooperative_models_match_central_differences():
    landmarks = np.array([[3.0, 1.0], [-1.0, 2.0]])
    poses = np.array([[0.5, -0.2, 0.3], [1.5, 1.0, -2.0]])
    dataset = SimpleNamespace(landmarks=landmarks, robots=(1, 2))
    backend = _CooperativeFilter(poses, np.repeat(np.eye(3)[None] * 0.1, 2, axis=0), dataset, ReplayConfig())
    for kind, target in ((LANDMARK, 0), (LANDMARK, 1), (ROBOT, 1)):
        predicted, H = backend.model(0, kind, target)
        numeric = np.zeros_like(H)
        for column in range(6):
            step = np.zeros(6)
            step[column] = 1e-6
            backend.x = (poses.ravel() + step)[None]
            plus = backend.model(0, kind, target)[0]
            backend.x = (poses.ravel() - step)[None]
            minus = backend.model(0, kind, target)[0]
            numeric[:, column] = (plus - minus) / 2e-6
        backend.x = poses.reshape(1, -1).copy()
        np.testing.assert_allclose(H, numeric, atol=1e-6)
        assert predicted[0] == pytest.approx(
            np.hypot(*((landmarks[target] if kind == LANDMARK else poses[1, :2]) - poses[0, :2]))
        )


def test_greedy_on_the_pose_marginal_ignores_nuisance_information():
    """With a nuisance state (a bias) beside the pose, the marginal gain counts only the pose's information."""
    P = np.diag([0.04, 0.04, 0.01, 1.0])  # pose and a very uncertain bias of candidate 0
    about_bias = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0]])  # informs only the bias
    about_x = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
    H = np.array([about_bias, about_x])
    R = np.diag([0.01, 0.01])
    assert select_greedy(P, H, R, 1) == [0], "the whole-state gain prefers the bias"
    assert select_greedy(P, H, R, 1, of=np.arange(3)) == [1]
    pose_prior = P[:3, :3]
    K = P @ about_x.T @ np.linalg.inv(about_x @ P @ about_x.T + R)
    posterior = (P - K @ about_x @ P)[:3, :3]
    expected = 0.5 * np.log(np.linalg.det(pose_prior) / np.linalg.det(posterior))
    from infonav_gym.experiments.replay.policies import _marginal_gains

    np.testing.assert_allclose(_marginal_gains(P, H, np.broadcast_to(R, (2, 2, 2)), np.arange(3)), [0.0, expected])
