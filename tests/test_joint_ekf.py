"""Relative-pose model and JointEKF: finite differences, filterpy as the peer, closed forms."""

import math

import numpy as np
import pytest
from conftest import numerical_jacobian
from filterpy.kalman import ExtendedKalmanFilter

from infonav_gym.estimation import JointEKF, relative_pose, relative_pose_linearized
from infonav_gym.estimation.models import GPS_POSE_JACOBIAN, angular_residual
from infonav_gym.geometry import wrap_angle

OBSERVERS = np.array([[0.3, -1.2, 0.4], [5.0, 2.0, 3.1], [-2.0, 7.0, -2.9], [1.0, 1.0, -math.pi]])
TARGETS = np.array([[4.0, 1.0, -0.3], [-3.0, -2.5, 2.0], [0.5, 9.0, 3.0], [0.0, 0.99, math.pi - 0.01]])


def make_joint(cross_covariances=True) -> JointEKF:
    """Three robots with different, uncorrelated uncertainties."""
    poses = np.array([[0.0, 0.0, 0.1], [6.0, 1.0, -0.4], [2.0, -5.0, 2.5]])
    covariances = np.array([np.diag([0.01, 0.02, 0.001]), np.diag([1.0, 0.5, 0.05]), np.diag([0.3, 0.3, 0.02])])
    return JointEKF(poses, covariances, cross_covariances)


def filterpy_twin(ekf: JointEKF) -> ExtendedKalmanFilter:
    reference = ExtendedKalmanFilter(dim_x=ekf.dim_x, dim_z=3)
    reference.x, reference.P = ekf.x.copy(), ekf.P.copy()
    return reference


R_LASER = np.diag([0.05**2, math.radians(1) ** 2, math.radians(3) ** 2])


def relative_update_args(ekf: JointEKF, observer: int, target: int, noise=(0.05, 0.02, -0.03)):
    """``relative_pose_update`` arguments for one observation, linearized at the current prior."""
    predicted, H_observer, H_target = ekf.relative_pose_model([observer], [target])
    return [observer], [target], predicted + np.array(noise), predicted, H_observer, H_target, R_LASER[None]


@pytest.mark.parametrize("index", range(len(OBSERVERS)))
def test_relative_pose_jacobians_match_finite_differences(index):
    observer, target = OBSERVERS[index], TARGETS[index]
    predicted, H_observer, H_target = relative_pose_linearized(observer, target)
    np.testing.assert_allclose(predicted[0], relative_pose(observer, target)[0], rtol=1e-15)
    numeric_observer = numerical_jacobian(lambda p: relative_pose(p, target)[0], observer)
    numeric_target = numerical_jacobian(lambda p: relative_pose(observer, p)[0], target)
    np.testing.assert_allclose(H_observer[0], numeric_observer, atol=1e-6)
    np.testing.assert_allclose(H_target[0], numeric_target, atol=1e-6)


def test_relative_pose_is_the_target_in_the_observers_frame():
    observer, target = np.array([1.0, 2.0, math.pi / 2]), np.array([1.0, 5.0, math.pi])
    np.testing.assert_allclose(relative_pose(observer, target)[0], [3.0, 0.0, math.pi / 2], atol=1e-12)
    with pytest.raises(ValueError, match="coincides"):
        relative_pose_linearized(observer, observer)


def test_angular_residual_wraps_only_the_angle_rows():
    residual = angular_residual([7.0, math.pi - 0.01, -math.pi + 0.01], [0.0, -math.pi + 0.01, math.pi - 0.01], [1, 2])
    np.testing.assert_allclose(residual, [7.0, -0.02, 0.02], atol=1e-12)


@pytest.mark.parametrize("cross_covariances", [True, False])
def test_stacked_relative_pose_update_equals_filterpys_update_on_the_joint_state(cross_covariances):
    ekf = make_joint()
    ekf.relative_pose_update(*relative_update_args(ekf, 0, 1))  # correlate robots 0 and 1 first
    ekf.cross_covariances = cross_covariances
    reference = filterpy_twin(ekf)
    observers, targets = np.array([2, 0]), np.array([1, 2])
    predicted, H_observer, H_target = ekf.relative_pose_model(observers, targets)
    measurements = predicted + np.array([[0.05, 0.02, -0.03], [-0.1, 0.3, 0.01]])
    R = np.array([R_LASER, 2 * R_LASER])
    H = np.zeros((6, ekf.dim_x))
    H[0:3, 6:9], H[0:3, 3:6], H[3:6, 0:3], H[3:6, 6:9] = H_observer[0], H_target[0], H_observer[1], H_target[1]
    ekf.relative_pose_update(observers, targets, measurements, predicted, H_observer, H_target, R)
    reference.update(
        measurements.ravel(),
        lambda x: H,
        lambda x: predicted.ravel(),
        R=np.kron(np.diag([1.0, 2.0]), R_LASER),
        residual=lambda a, b: angular_residual(a, b, [1, 2, 4, 5]),
    )
    reference.x[2::3] = wrap_angle(reference.x[2::3])
    np.testing.assert_allclose(ekf.x, reference.x, rtol=1e-12, atol=1e-14)
    if cross_covariances:
        np.testing.assert_allclose(ekf.P, reference.P, rtol=1e-10, atol=1e-14)
    else:
        own = np.kron(np.eye(3), np.ones((3, 3))).astype(bool)
        np.testing.assert_allclose(ekf.P[own], reference.P[own], rtol=1e-10, atol=1e-14)
        assert np.all(ekf.P[~own] == 0.0) and np.any(reference.P[~own] != 0.0)


def test_relative_pose_update_correlates_the_two_robots_and_leaves_a_third_alone():
    ekf = make_joint()
    before = ekf.P.copy()
    ekf.relative_pose_update(*relative_update_args(ekf, 0, 1))
    assert np.abs(ekf.P[0:3, 3:6]).max() > 1e-4
    np.testing.assert_array_equal(ekf.P[6:9, 6:9], before[6:9, 6:9])
    np.testing.assert_array_equal(ekf.P[0:6, 6:9], 0.0)
    assert np.linalg.det(ekf.pose_covariance(1)) < np.linalg.det(before[3:6, 3:6])


def test_gps_update_equals_filterpys_linear_update():
    ekf = make_joint()
    ekf.relative_pose_update(*relative_update_args(ekf, 0, 1))
    reference = filterpy_twin(ekf)
    fixes, R = np.array([[0.1, -0.2], [5.5, 1.3]]), np.array([np.eye(2) * 0.01, np.eye(2) * 0.04])
    H = np.zeros((4, 9))
    H[0:2, 0:3], H[2:4, 6:9] = GPS_POSE_JACOBIAN, GPS_POSE_JACOBIAN
    ekf.gps_update([0, 2], fixes, R)
    reference.update(fixes.ravel(), lambda x: H, lambda x: H @ x, R=np.diag([0.01, 0.01, 0.04, 0.04]))
    np.testing.assert_allclose(ekf.x, reference.x, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(ekf.P, reference.P, rtol=1e-10, atol=1e-14)


def test_bad_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        JointEKF(np.zeros((2, 2)), np.array([np.eye(3)] * 2))
    with pytest.raises(ValueError, match=r"pose_covariances must have shape \(2, 3, 3\)"):
        JointEKF(np.zeros((2, 3)), np.eye(3))
    with pytest.raises(ValueError, match="robot 1 is not positive definite"):
        JointEKF(np.zeros((2, 3)), np.array([np.eye(3), -np.eye(3)]))
    ekf = make_joint()
    with pytest.raises(ValueError, match="its own relative pose"):
        ekf.relative_pose_update([1], [1], *relative_update_args(ekf, 0, 1)[2:])
