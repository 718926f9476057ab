"""The Huber-weighted update (standard EKF inside the threshold) and the target-bias EKF."""

import math

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

from infonav_gym.estimation.bias_ekf import TargetBiasPoseEKF
from infonav_gym.estimation.ekf import PoseEKF
from infonav_gym.estimation.models import range_bearing_residual
from infonav_gym.estimation.robust import huber_noise

P = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.002], [0.0, 0.002, 0.01]])
R = np.diag([0.1**2, 0.02**2])
LANDMARK = np.array([3.0, 1.0])
POSE = np.array([0.5, 0.2, 0.3])


def _filterpy_update(residual):
    """filterpy's generic EKF update with the pose filter's model: the peer library's answer."""
    reference = PoseEKF(POSE, P)
    predicted, H = reference.landmark_measurement_model(LANDMARK[None])
    ekf = ExtendedKalmanFilter(dim_x=3, dim_z=2)
    ekf.x, ekf.P = POSE.copy(), P.copy()
    ekf.update(predicted[0] + residual, lambda _: H[0], lambda _: predicted[0], R=R, residual=range_bearing_residual)
    return ekf, H[0]


def test_the_robust_update_is_the_standard_update_without_outliers():
    residual = np.array([0.05, -0.01])
    reference, H = _filterpy_update(residual)
    R_used, weight, nis = huber_noise(residual, H, P, R, threshold_nis=5.99)
    assert weight == 1.0 and np.array_equal(R_used, R)
    assert nis == pytest.approx(float(residual @ np.linalg.solve(H @ P @ H.T + R, residual)), rel=1e-12)
    ekf = PoseEKF(POSE, P)
    ekf.update_range_bearing(reference.z, reference.z - residual, H, R_used)
    np.testing.assert_allclose(ekf.x, reference.x, atol=1e-12)
    np.testing.assert_allclose(ekf.P, reference.P, atol=1e-12)


def test_an_outlier_gets_the_huber_weight_at_its_fixed_point():
    residual = np.array([1.5, 0.2])
    _, H = _filterpy_update(residual)
    R_used, weight, nis = huber_noise(residual, H, P, R, threshold_nis=5.99)
    assert nis > 5.99 and 0 < weight < 1
    inflated_nis = float(residual @ np.linalg.solve(H @ P @ H.T + R_used, residual))
    assert weight == pytest.approx(math.sqrt(5.99 / inflated_nis), rel=1e-9)  # Huber: w = c / d at the fit
    np.testing.assert_allclose(R_used, R / weight)


def test_a_threshold_that_is_not_positive_is_refused():
    with pytest.raises(ValueError, match="threshold_nis"):
        huber_noise(np.zeros(2), np.eye(2, 3), P, R, threshold_nis=0.0)


def test_without_biases_the_target_bias_filter_is_the_pose_filter():
    control, control_covariance = np.array([0.2, 0.1]), np.diag([0.01**2, 0.03**2]) / 0.02
    augmented = TargetBiasPoseEKF(POSE, P, np.zeros((2, 2)), [60.0, 60.0])
    plain = PoseEKF(POSE, P)
    for step in range(5):
        augmented.predict(control, 0.02, control_covariance)
        plain.predict(control, 0.02, control_covariance)
        z = np.array([2.4 + 0.01 * step, 0.05])
        predicted, H = augmented.measurement_model(1, LANDMARK)
        augmented.update_range_bearing(z, range_bearing_residual(z, predicted), H, R)
        predicted_plain, H_plain = plain.landmark_measurement_model(LANDMARK[None])
        plain.update_range_bearing(z, predicted_plain[0], H_plain[0], R)
    np.testing.assert_allclose(augmented.x[:3], plain.x, atol=1e-12)
    np.testing.assert_allclose(augmented.P[:3, :3], plain.P, atol=1e-12)


def test_unobserved_biases_keep_their_stationary_variance_and_decay():
    bias_std = np.array([[0.1, 0.01], [0.2, 0.02]])
    ekf = TargetBiasPoseEKF(
        POSE, P, bias_std, [1.0, 0.5], shared_std=[0.05, 0.005], shared_correlation_distance_m=[2, 4]
    )
    start = np.array([0.03, 0.003, 0.1, 0.01, -0.2, 0.02])
    ekf.x[3:] = start
    decayed = start * np.exp(-0.1 / np.array([2, 4, 1, 0.5, 1, 0.5]))
    for _ in range(50):  # 50 steps of 0.02 s at -0.1 m/s: 0.1 m driven
        ekf.predict(np.array([-0.1, 0.3]), 0.02, np.eye(2) * 1e-6)
    np.testing.assert_allclose(np.diag(ekf.P)[3:], np.r_[0.05**2, 0.005**2, bias_std.ravel() ** 2], rtol=1e-12)
    np.testing.assert_allclose(ekf.x[3:], decayed)
    ekf.predict(np.array([0.0, 0.3]), 0.02, np.eye(2) * 1e-6)  # turning in place: no decay
    np.testing.assert_allclose(ekf.x[3:], decayed)


def test_a_measurement_moves_only_its_targets_biases():
    ekf = TargetBiasPoseEKF(POSE, P, np.array([[0.1, 0.01], [0.1, 0.01]]), [60.0, 60.0], shared_std=[0.05, 0.0])
    predicted, H = ekf.measurement_model(0, LANDMARK)
    z = predicted + [0.2, 0.0]
    ekf.update_range_bearing(z, range_bearing_residual(z, predicted), H, R)
    assert ekf.x[3] > 0 and ekf.x[5] > ekf.x[3] and ekf.x[7:].tolist() == [0.0, 0.0]  # shared, target 0, not 1
    assert ekf.n_targets == 2


def test_the_shared_bias_adds_to_every_targets_prediction():
    ekf = TargetBiasPoseEKF(POSE, P, np.full((2, 2), 0.01), [1.0, 1.0], shared_std=[0.05, 0.005])
    ekf.x[3:] = [0.03, 0.002, 0.1, 0.01, -0.2, 0.02]
    plain = TargetBiasPoseEKF(POSE, P, np.zeros((2, 2)), [1.0, 1.0])
    for target, own in ((0, [0.1, 0.01]), (1, [-0.2, 0.02])):
        predicted, H = ekf.measurement_model(target, LANDMARK)
        np.testing.assert_allclose(predicted - plain.measurement_model(target, LANDMARK)[0], np.add(own, [0.03, 0.002]))
        np.testing.assert_array_equal(H[:, 3:5], np.eye(2))


def test_the_robot_drives_along_its_heading_plus_the_travel_offset():
    offset, pose = 0.05, np.array([1.0, 2.0, 0.3])
    ekf = TargetBiasPoseEKF(pose, P, np.zeros((1, 2)), [1.0, 1.0], travel_heading_offset_rad=offset)
    plain = PoseEKF(pose + [0.0, 0.0, offset], P)
    control, covariance = np.array([0.5, 0.2]), np.diag([0.01, 0.02])
    ekf.predict(control, 0.1, covariance)
    plain.predict(control, 0.1, covariance)
    np.testing.assert_allclose(ekf.x[:3], plain.x - [0.0, 0.0, offset], atol=1e-15)
    np.testing.assert_allclose(ekf.P[:3, :3], plain.P, atol=1e-15)  # the same step, in a frame turned by the offset


def test_target_bias_filter_rejects_bad_parameters():
    with pytest.raises(ValueError, match="bias_std"):
        TargetBiasPoseEKF(POSE, P, [[-0.1, 0.0]], [1.0, 1.0])
    with pytest.raises(ValueError, match="correlation_distance_m"):
        TargetBiasPoseEKF(POSE, P, [[0.1, 0.0]], [0.0, 1.0])
