"""Models, PoseEKF and consistency: finite differences, filterpy as the peer, Monte Carlo NEES."""

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import numerical_jacobian
from scipy import stats

import infonav_gym  # noqa: F401  (registers the envs)
from agents import RandomAgent
from infonav_gym.estimation import PoseEKF, chi2_bounds, nees, nis, pose_error
from infonav_gym.estimation.models import (
    angular_residual,
    range_bearing,
    range_bearing_linearized,
    unicycle_jacobians,
    unicycle_motion,
)
from infonav_gym.geometry import wrap_angle
from infonav_gym.world.motion_kernels import executed_controls

POSES = [np.array([0.3, -1.2, 0.4]), np.array([5.0, 2.0, 3.1]), np.array([-2.0, 7.0, -2.9])]


@pytest.mark.parametrize("pose", POSES)
def test_unicycle_jacobians_match_finite_differences(pose):
    control, dt = np.array([1.3, -0.4]), 0.5
    F, V = unicycle_jacobians(pose, control, dt)
    np.testing.assert_allclose(F, numerical_jacobian(lambda p: unicycle_motion(p, control, dt), pose), atol=1e-6)
    np.testing.assert_allclose(V, numerical_jacobian(lambda u: unicycle_motion(pose, u, dt), control), atol=1e-6)


@pytest.mark.parametrize("pose", POSES)
def test_range_bearing_jacobians_match_finite_differences(pose):
    landmarks = np.array([[4.0, 1.0], [-3.0, -2.5], [0.5, 9.0]])
    predicted, H_pose, H_landmark = range_bearing_linearized(pose, landmarks)
    np.testing.assert_allclose(predicted, range_bearing(pose, landmarks), rtol=1e-15)
    for i, landmark in enumerate(landmarks):
        numeric_pose = numerical_jacobian(lambda p, lm=landmark: range_bearing(p, lm)[0], pose)
        numeric_landmark = numerical_jacobian(lambda lm, p=pose: range_bearing(p, lm)[0], landmark)
        np.testing.assert_allclose(H_pose[i], numeric_pose, atol=1e-6)
        np.testing.assert_allclose(H_landmark[i], numeric_landmark, atol=1e-6)


def test_range_bearing_at_the_sensor_is_an_error():
    with pytest.raises(ValueError, match="coincides"):
        range_bearing_linearized(np.zeros(3), np.zeros((1, 2)))


def test_executed_controls_invert_the_motion_model():
    pose, control = np.array([1.0, -2.0, 3.0]), np.array([1.3, 0.4])  # the turn wraps the heading past pi
    after = unicycle_motion(pose, control, 0.5)
    np.testing.assert_allclose(executed_controls(pose[None, None], after[None, None], 0.5)[0, 0], control, rtol=1e-12)


def test_wrap_angle_and_residual_cross_the_branch_cut():
    np.testing.assert_allclose(
        wrap_angle(np.array([math.pi, -math.pi, 3 * math.pi, 0.1])), [-math.pi, -math.pi, -math.pi, 0.1]
    )
    residual = angular_residual([2.0, math.pi - 0.01], [1.5, -math.pi + 0.01], 1)
    np.testing.assert_allclose(residual, [0.5, -0.02], atol=1e-12)


def mapping_filter() -> PoseEKF:
    """A PoseEKF mapping two landmarks."""
    return PoseEKF(np.array([1.0, 2.0, 3.0]), np.diag([0.3, 0.2, 0.05]), np.array([[5.0, 4.0], [0.0, -3.0]]), 0.5)


def test_mapped_measurement_jacobian_matches_finite_differences_on_the_whole_state():
    ekf = mapping_filter()
    _, H = ekf.landmark_measurement_model()

    def measure(state, index):
        return range_bearing(state[:3], state[3 + 2 * index : 5 + 2 * index])[0]

    for index in range(2):
        np.testing.assert_allclose(H[index], numerical_jacobian(lambda s, i=index: measure(s, i), ekf.x), atol=1e-6)


def test_predict_is_the_linearized_unicycle_propagation():
    ekf = mapping_filter()
    prior_x, prior_P = ekf.x.copy(), ekf.P.copy()
    control, dt, M = np.array([1.0, 0.2]), 0.5, np.diag([0.01, 0.004])
    ekf.predict(control, dt, M)
    F_pose, V = unicycle_jacobians(prior_x[:3], control, dt)
    F = np.eye(7)
    F[:3, :3] = F_pose
    Q = np.zeros((7, 7))
    Q[:3, :3] = V @ M @ V.T
    np.testing.assert_allclose(ekf.x[:3], unicycle_motion(prior_x[:3], control, dt), rtol=1e-15)
    np.testing.assert_array_equal(ekf.x[3:], prior_x[3:])
    np.testing.assert_allclose(ekf.P, F @ prior_P @ F.T + Q, rtol=1e-14)
    assert -math.pi <= ekf.x[2] < math.pi


def test_heading_stays_wrapped_through_updates():
    ekf = PoseEKF(np.array([0.0, 0.0, math.pi - 0.001]), np.diag([0.1, 0.1, 0.1]))
    landmark = np.array([[-5.0, 0.0]])
    predicted, H = ekf.landmark_measurement_model(landmark)
    ekf.update_range_bearing([5.0, -0.05], predicted[0], H[0], np.diag([0.01, 0.0001]))
    assert -math.pi <= ekf.x[2] < math.pi
    assert abs(wrap_angle(ekf.x[2] - (math.pi + 0.05))) < 0.01


@pytest.mark.parametrize(
    "pose, covariance, problem",
    [
        (np.zeros(3), np.diag([1.0, -1.0, 1.0]), "positive definite"),
        (np.zeros(3), np.ones((2, 2)), "square|shape"),
        (np.array([0.0, np.nan, 0.0]), np.eye(3), "pose"),
        (np.zeros(2), np.eye(3), "pose"),
    ],
)
def test_bad_initial_state_raises(pose, covariance, problem):
    with pytest.raises(ValueError, match=problem):
        PoseEKF(pose, covariance)


def test_mapping_needs_a_landmark_covariance():
    with pytest.raises(ValueError, match="landmark_covariance"):
        PoseEKF(np.zeros(3), np.eye(3), landmarks=np.ones((2, 2)))


def test_chi2_bounds_and_statistics():
    low, high = chi2_bounds(3, 50)
    assert math.isclose(low, stats.chi2.ppf(0.025, 150) / 50) and math.isclose(high, stats.chi2.ppf(0.975, 150) / 50)
    assert low < 3 < high
    assert math.isclose(nis([1.0, 2.0], np.diag([1.0, 4.0])), 2.0)
    assert math.isclose(nees([1.0, 1.0, math.pi - 0.1], [0.0, 1.0, -math.pi + 0.1], np.diag([1.0, 1.0, 0.04])), 2.0)
    np.testing.assert_allclose(pose_error([0, 0, 3.1], [0, 0, -3.1]), [0, 0, 6.2 - 2 * math.pi])
    with pytest.raises(ValueError):
        chi2_bounds(0)
    with pytest.raises(ValueError, match="covariance must be"):
        nis([1.0, 2.0], np.eye(3))


def test_pose_ekf_is_consistent_over_50_monte_carlo_runs_of_the_field():
    """Average NEES over 50 runs stays inside the two-sided 95% chi-square bounds."""
    env = gym.make("infonav/LandmarkSelection-v0").unwrapped
    n_runs = 50
    runs = []
    for seed in range(n_runs):
        observation, info = env.reset(seed=seed)
        agent, errors = RandomAgent(env.action_space.n, seed=seed), []
        truncated = False
        while not truncated:
            errors.append(nees(info["true_pose"], info["estimated_pose"], env.vector.estimate(0)[1][:3, :3]))
            observation, _, _, truncated, info = env.step(agent.act(observation, info))
        runs.append(errors)
    average_nees = np.mean(runs, axis=0)
    low, high = chi2_bounds(3, n_runs)
    inside = (average_nees >= low) & (average_nees <= high)
    assert low <= average_nees.mean() <= high
    assert inside.mean() >= 0.9, f"only {inside.mean():.0%} of time steps inside [{low:.2f}, {high:.2f}]"
