"""The Huber-weighted update (standard EKF inside the threshold) and the replay's filter with target biases."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter
from scipy.linalg import block_diag

from infonav_gym.estimation.ekf import PoseEKF
from infonav_gym.estimation.models import (
    range_bearing_linearized,
    range_bearing_residual,
    unicycle_jacobians,
    unicycle_motion,
)
from infonav_gym.estimation.robust import huber_noise
from infonav_gym.experiments.replay.filters import _CalibratedFilters

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


def calibrated(offset: float = 0.0) -> _CalibratedFilters:
    """The replay's calibrated filter of one robot with two landmarks, each its own biases beside the shared ones."""
    model = SimpleNamespace(
        range_bias_std_m=0.1,
        bearing_bias_std_rad=0.01,
        range_correlation_distance_m=1.0,
        bearing_correlation_distance_m=0.5,
        range_shared_std_m=0.05,
        bearing_shared_std_rad=0.005,
        range_shared_correlation_distance_m=2.0,
        bearing_shared_correlation_distance_m=4.0,
        travel_heading_offset_rad=offset,
    )
    dataset = SimpleNamespace(landmarks=np.array([LANDMARK, [-1.0, 2.0]]), robots=(1,))
    return _CalibratedFilters(
        POSE[None], P[None], dataset, SimpleNamespace(noise=SimpleNamespace(for_robot=lambda _: model))
    )


CORRELATION_DISTANCES_M = np.array([2.0, 4.0, 1.0, 0.5, 1.0, 0.5])  # shared range, bearing, then each landmark's
BIAS_VARIANCES = np.square([0.05, 0.005, 0.1, 0.01, 0.1, 0.01])


def test_the_calibrated_filter_is_filterpys_ekf_on_the_augmented_state():
    """Colored noise by state augmentation, the wheels driving off the heading: update for update filterpy's EKF
    with the biases' decay in F and Q and their columns in H (x 1e-12, P 1e-10)."""
    offset, dt, control, covariance = 0.05, 0.1, np.array([0.4, 0.3]), np.diag([1e-4, 4e-4])
    backend = calibrated(offset)
    reference = ExtendedKalmanFilter(dim_x=9, dim_z=2)
    reference.x, reference.P = backend.x[0].copy(), backend.P[0].copy()
    for step in range(6):
        backend.predict(control[None], dt, covariance[None])
        travel = reference.x[:3] + [0.0, 0.0, offset]
        decay = np.exp(-control[0] * dt / CORRELATION_DISTANCES_M)
        F_pose, V = unicycle_jacobians(travel, control, dt)
        reference.F = block_diag(F_pose, np.diag(decay))
        reference.Q = block_diag(V @ covariance @ V.T, np.diag((1.0 - decay**2) * BIAS_VARIANCES))
        pose = unicycle_motion(travel, control, dt) - [0.0, 0.0, offset]
        reference.predict_x = lambda u, pose=pose, decay=decay: setattr(
            reference, "x", np.r_[pose, decay * reference.x[3:]]
        )
        reference.predict()
        target = step % 2
        biases = [3 + 2 + 2 * target, 3 + 3 + 2 * target]
        predicted, H_pose, _ = range_bearing_linearized(reference.x, backend.landmarks[target])
        H = np.zeros((2, 9))
        H[:, :3], H[:, biases], H[:, 3:5] = H_pose[0], np.eye(2), np.eye(2)
        predicted = predicted[0] + reference.x[biases] + reference.x[3:5]
        z = predicted + [0.05 * (-1) ** step, 0.01]
        reference.update(z, lambda _, H=H: H, lambda _, p=predicted: p, R=R, residual=range_bearing_residual)
        backend.update(0, 0, target, z, *backend.model(0, 0, target), R)
        np.testing.assert_allclose(backend.x[0], reference.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(backend.P[0], reference.P, rtol=0, atol=1e-10)


def test_unobserved_biases_keep_their_stationary_variance_and_decay():
    backend = calibrated()
    start = np.array([0.03, 0.003, 0.1, 0.01, -0.2, 0.02])
    backend.x[0, 3:] = start
    decayed = start * np.exp(-0.1 / CORRELATION_DISTANCES_M)
    for _ in range(50):  # 50 steps of 0.02 s at -0.1 m/s: 0.1 m driven
        backend.predict(np.array([[-0.1, 0.3]]), 0.02, np.eye(2)[None] * 1e-6)
    np.testing.assert_allclose(np.diag(backend.P[0])[3:], BIAS_VARIANCES, rtol=1e-12)
    np.testing.assert_allclose(backend.x[0, 3:], decayed)
    backend.predict(np.array([[0.0, 0.3]]), 0.02, np.eye(2)[None] * 1e-6)  # turning in place: no decay
    np.testing.assert_allclose(backend.x[0, 3:], decayed)


def test_the_shared_bias_and_the_targets_own_add_to_its_prediction():
    backend = calibrated()
    unbiased = [backend.model(0, 0, target)[0] for target in (0, 1)]
    backend.x[0, 3:] = [0.03, 0.002, 0.1, 0.01, -0.2, 0.02]
    for target, own in ((0, [0.1, 0.01]), (1, [-0.2, 0.02])):
        predicted, H = backend.model(0, 0, target)
        np.testing.assert_allclose(predicted - unbiased[target], np.add(own, [0.03, 0.002]))
        np.testing.assert_array_equal(H[:, 3:5], np.eye(2))
