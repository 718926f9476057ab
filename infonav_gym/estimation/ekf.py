"""Extended Kalman filters built on filterpy's ``ExtendedKalmanFilter``."""

from __future__ import annotations

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from scipy.linalg import block_diag

from infonav_gym.estimation.models import (
    range_bearing_linearized,
    range_bearing_residual,
    unicycle_jacobians,
    unicycle_motion,
    wrap_angle,
)
from infonav_gym.information import log_det_spd

POSE_DIM = 3


class PoseEKF(ExtendedKalmanFilter):
    """EKF over a planar pose ``[x, y, heading]``, optionally with mapped landmarks (EKF-SLAM).

    The state is ``[x, y, heading, l1x, l1y, l2x, ...]``: with ``landmarks`` given,
    their positions are estimated alongside the pose. Prediction runs through
    filterpy's ``predict`` (with the unicycle model in ``predict_x``); range-bearing
    updates are closed-form and equal filterpy's generic ``update``, which stays
    available for other measurement models. Headings and bearing innovations are
    wrapped, and the covariance is symmetrized after every update.

    Args:
        pose: initial pose estimate (3,).
        pose_covariance: its covariance (3, 3).
        landmarks: initial estimates of the mapped landmarks (L, 2), or None.
        landmark_covariance: their covariance, (2L, 2L) or a scalar variance [m^2].
    """

    def __init__(self, pose, pose_covariance, landmarks=None, landmark_covariance=None):
        landmarks = np.zeros((0, 2)) if landmarks is None else np.asarray(landmarks, dtype=float).reshape(-1, 2)
        super().__init__(dim_x=POSE_DIM + 2 * len(landmarks), dim_z=2)
        pose = np.asarray(pose, dtype=float)
        if pose.shape != (POSE_DIM,) or not np.all(np.isfinite(pose)):
            raise ValueError(f"pose must be 3 finite numbers [x, y, heading], got {pose!r}")
        covariance = np.asarray(pose_covariance, dtype=float)
        if covariance.shape != (POSE_DIM, POSE_DIM):
            raise ValueError(f"pose_covariance must have shape (3, 3), got {covariance.shape}")
        if len(landmarks):
            if landmark_covariance is None:
                raise ValueError("landmark_covariance is required when landmarks are mapped")
            if np.ndim(landmark_covariance) == 0:
                landmark_covariance = float(landmark_covariance) * np.eye(2 * len(landmarks))
            covariance = block_diag(covariance, landmark_covariance)
        log_det_spd(covariance, "initial covariance")
        self.x = np.concatenate([pose, landmarks.ravel()])
        self.P = covariance.copy()
        self.Q = np.zeros_like(self.P)
        self._motion = None

    @property
    def n_landmarks(self) -> int:
        """Number of landmarks in the state."""
        return (self.dim_x - POSE_DIM) // 2

    @property
    def pose(self) -> np.ndarray:
        return self.x[:POSE_DIM].copy()

    @property
    def pose_covariance(self) -> np.ndarray:
        return self.P[:POSE_DIM, :POSE_DIM].copy()

    @property
    def landmark_positions(self) -> np.ndarray:
        """Current estimates of the mapped landmarks (L, 2)."""
        return self.x[POSE_DIM:].reshape(-1, 2).copy()

    def predict(self, control, dt: float, control_covariance) -> None:
        """Propagate through the unicycle model with a noisy odometry ``control`` (speed, turn rate).

        ``F P F^T + Q`` keeps the covariance symmetric; the update symmetrizes it.
        """
        F_pose, V = unicycle_jacobians(self.x, control, dt)
        self.F[:POSE_DIM, :POSE_DIM] = F_pose
        self.Q[:POSE_DIM, :POSE_DIM] = V @ control_covariance @ V.T
        self._motion = (control, dt)
        super().predict()

    def predict_x(self, u=0) -> None:
        """filterpy hook: the nonlinear state prediction (landmarks are static)."""
        control, dt = self._motion
        self.x[:POSE_DIM] = unicycle_motion(self.x[:POSE_DIM], control, dt)

    def landmark_measurement_model(self, landmarks=None) -> tuple[np.ndarray, np.ndarray]:
        """Predicted range-bearing to each landmark and its Jacobian w.r.t. the whole state.

        Args:
            landmarks: known positions (N, 2); None to use the mapped landmarks in the state.

        Returns:
            ``(predicted (N, 2), H (N, 2, dim_x))``.
        """
        mapped = landmarks is None
        positions = self.x[POSE_DIM:].reshape(-1, 2) if mapped else np.asarray(landmarks, dtype=float).reshape(-1, 2)
        predicted, H_pose, H_landmark = range_bearing_linearized(self.x, positions)
        if self.dim_x == POSE_DIM:
            return predicted, H_pose
        H = np.zeros((len(positions), 2, self.dim_x))
        H[:, :, :POSE_DIM] = H_pose
        if mapped:
            rows = np.arange(len(positions))
            columns = POSE_DIM + 2 * rows[:, None] + np.arange(2)
            H[rows[:, None, None], np.arange(2)[None, :, None], columns[:, None, :]] = H_landmark
        return predicted, H

    def update_range_bearing(self, measurement, predicted, H, R) -> None:
        """Update with one range-bearing measurement, linearized at the prior; covariance symmetrized.

        Gives what filterpy's generic ``update`` gives with a wrapped-bearing
        residual (tested against it) and fills the same attributes (``y``, ``S``,
        ``SI``, ``K``, ``z``, ``x_post``, ``P_post``), without its per-call
        overhead (a general matrix inverse and deep copies) in the env's hot loop.

        Args:
            measurement: ``[range, bearing]``.
            predicted: the measurement predicted at the prior, ``[range, bearing]``.
            H: its Jacobian w.r.t. the state (2, dim_x).
            R: measurement noise covariance (2, 2).
        """
        PHT = self.P @ H.T
        S = H @ PHT + R
        (a, b), (_, d) = S.tolist()
        SI = np.array([[d, -b], [-b, a]]) / (a * d - b * b)
        K = PHT @ SI
        self.z = np.array(measurement, dtype=float)
        self.y = range_bearing_residual(self.z, predicted)
        self.x = self.x + K @ self.y
        self.x[2] = wrap_angle(self.x[2])
        P = self.P - K @ PHT.T
        self.P = 0.5 * (P + P.T)
        self.S, self.SI, self.K = S, SI, K
        self.x_post, self.P_post = self.x.copy(), self.P.copy()
        self._log_likelihood = self._likelihood = self._mahalanobis = None
