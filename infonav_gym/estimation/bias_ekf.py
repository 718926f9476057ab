"""A pose EKF whose range-bearing errors to each known target are partly slow (colored) noise.

Real range-bearing sensors err alike on consecutive looks at the same target (on MRCLAM Dataset 6,
consecutive range errors to a landmark correlate above 0.9). A filter that takes them as independent
counts one error many times and grows overconfident. The standard remedy for colored measurement
noise is to augment the state with it (Gelb 1974, "Applied Optimal Estimation", Sec. 4.5;
Bar-Shalom, Li and Kirubarajan 2001, "Estimation with Applications to Tracking and Navigation",
Sec. 8.3): each target ``j`` gets a range bias and a bearing bias, each a first-order Gauss-Markov
process, stationary variance ``sigma_b^2``; a measurement is ``h(pose, target) + b_j + white noise``.
The errors change with the viewing geometry, not with time (a parked robot keeps its error), so the
process runs in the distance the robot travels: ``b(s + ds) = a b(s) + w``, ``a = exp(-ds / l)``.
Part of the slow error is the sensor's own, shared by every target (on Dataset 6 bearing errors to
different landmarks seen within 0.3 s correlate by 0.2-0.5: the camera's yaw against the robot's
frame drifts): a second pair of bias states, shared by all targets, carries it; a measurement of target
``j`` sees ``b_shared + b_j``. The pose's heading is the frame the sensor and the ground truth share; the
wheels may drive a small fixed angle off it (``travel_heading_offset_rad``: on Dataset 6, -0.017 to
+0.008 rad, the same in both halves of the log), which the motion model applies.
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from infonav_gym.estimation.ekf import POSE_DIM, _kalman_update, set_pose_motion
from infonav_gym.estimation.models import range_bearing_linearized, unicycle_motion
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import log_det_spd

SHARED = slice(POSE_DIM, POSE_DIM + 2)  # the range and bearing biases every target shares
FIRST_TARGET = POSE_DIM + 2


def _checked(name: str, values, shape) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    if values.shape != shape or np.any(values < 0) or not np.all(np.isfinite(values)):
        raise ValueError(f"{name} must be finite and >= 0 with shape {shape}, got {values.tolist()}")
    return values


def _lengths(name: str, values) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    if values.shape != (2,) or not np.all(values > 0):
        raise ValueError(f"{name} must be 2 positive lengths, got {values.tolist()}")
    return values


class TargetBiasPoseEKF(ExtendedKalmanFilter):
    """EKF over ``[x, y, heading, b_range, b_bearing, b_range_1, b_bearing_1, ..., b_range_T, b_bearing_T]``.

    Prediction runs through filterpy's ``predict`` (the unicycle model in ``predict_x``; each bias decays
    by its ``a`` and gains ``(1 - a^2) sigma_b^2``); updates are the closed-form EKF update of ``ekf.py``.
    With every ``sigma_b`` -> 0 it is ``PoseEKF`` with known targets (tested).

    Args:
        pose: initial pose estimate (3,).
        pose_covariance: its covariance (3, 3).
        bias_std: stationary standard deviations ``[range [m], bearing [rad]]`` of each target's biases (T, 2).
        correlation_distance_m: the biases' correlation lengths ``[range, bearing]`` in travelled distance [m].
        shared_std: stationary standard deviations ``[range, bearing]`` of the biases all targets share (2,).
        shared_correlation_distance_m: their correlation lengths [m] (2,).
        travel_heading_offset_rad: the robot drives along ``heading + this``.
    """

    def __init__(
        self,
        pose,
        pose_covariance,
        bias_std,
        correlation_distance_m,
        shared_std=(0.0, 0.0),
        shared_correlation_distance_m=(1.0, 1.0),
        travel_heading_offset_rad: float = 0.0,
    ):
        bias_std = np.asarray(bias_std, dtype=float).reshape(-1, 2)
        stds = np.concatenate(
            [_checked("shared_std", shared_std, (2,)), _checked("bias_std", bias_std, bias_std.shape).ravel()]
        )
        super().__init__(dim_x=POSE_DIM + stds.size, dim_z=2)
        log_det_spd(np.asarray(pose_covariance, dtype=float), "pose_covariance")
        self.x = np.concatenate([np.asarray(pose, dtype=float), np.zeros(stds.size)])
        self._bias_variance = stds**2
        self.P = np.diag(np.concatenate([np.zeros(POSE_DIM), self._bias_variance]))
        self.P[:POSE_DIM, :POSE_DIM] = pose_covariance
        self.Q = np.zeros_like(self.P)
        self._correlation_distance_m = np.concatenate(
            [
                _lengths("shared_correlation_distance_m", shared_correlation_distance_m),
                np.tile(_lengths("correlation_distance_m", correlation_distance_m), len(bias_std)),
            ]
        )
        self._motion = None
        self._travel_offset = float(travel_heading_offset_rad)

    @property
    def n_targets(self) -> int:
        return (self.dim_x - FIRST_TARGET) // 2

    def predict(self, control, dt: float, control_covariance) -> None:
        """Unicycle step with odometry ``control`` ``[speed, turn_rate]`` and its covariance (2, 2); biases decay
        over the distance driven."""
        decay = np.exp(-abs(control[0]) * dt / self._correlation_distance_m)
        biases = np.arange(POSE_DIM, self.dim_x)
        self.F[biases, biases] = decay
        self.Q[biases, biases] = (1.0 - decay**2) * self._bias_variance
        self.x[2] += self._travel_offset  # the step and its Jacobians along the direction of travel
        set_pose_motion(self, control, dt, control_covariance)
        super().predict()
        self.x[2] = wrap_angle(self.x[2] - self._travel_offset)

    def predict_x(self, u=0) -> None:
        """filterpy hook: the unicycle step of the pose and the biases' decay."""
        control, dt = self._motion
        self.x[:POSE_DIM] = unicycle_motion(self.x[:POSE_DIM], control, dt)
        self.x[POSE_DIM:] = self.F.diagonal()[POSE_DIM:] * self.x[POSE_DIM:]

    def measurement_model(self, target: int, position) -> tuple[np.ndarray, np.ndarray]:
        """Predicted ``[range, bearing]`` of target ``target`` at ``position`` (2,), biases included, and H (2, n)."""
        predicted, H_pose, _ = range_bearing_linearized(self.x, np.asarray(position, dtype=float)[None])
        biases = slice(FIRST_TARGET + 2 * target, FIRST_TARGET + 2 * target + 2)
        H = np.zeros((2, self.dim_x))
        H[:, :POSE_DIM] = H_pose[0]
        H[:, biases] = np.eye(2)
        H[:, SHARED] = np.eye(2)
        predicted = predicted[0] + self.x[biases] + self.x[SHARED]
        predicted[1] = wrap_angle(predicted[1])
        return predicted, H

    def update_range_bearing(self, measurement, residual, H, R) -> None:
        """The EKF update with ``residual = measurement - predicted`` (bearing wrapped), Jacobian H and noise R."""
        _kalman_update(self, measurement, residual, H, R, 2)
