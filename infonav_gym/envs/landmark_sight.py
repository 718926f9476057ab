"""What a range-bearing sensor offers at a decision: which landmarks it sees, and their measurement model.

Shared by ``LandmarkSelection-v0`` and ``ActiveLocalization-v0``, whose decisions both pick a landmark to
observe with a ``PoseEKF`` at the step's prior.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from infonav_gym.estimation.ekf import POSE_DIM, PoseEKF
from infonav_gym.estimation.models import range_bearing
from infonav_gym.information import expected_information_gain, gaussian_entropy_from_log_det, log_det_spd
from infonav_gym.sensors.range_bearing import RangeBearingSensor
from infonav_gym.world.world import World


class LandmarkSight(NamedTuple):
    """The landmarks visible at a decision and their range-bearing measurement model at the EKF's prior.

    Immutable (a named tuple: cheap to build every step).

    Attributes:
        visible: which landmarks are within range and field of view with a clear line of sight
            from the true pose (K,) bool.
        visible_indices: the indices of those landmarks, ascending (V,).
        predicted: range [m] and bearing [rad] to each landmark as the prior predicts them (K, 2).
        jacobians: ``H`` of each prediction w.r.t. the EKF's state (K, 2, n).
        noise: measurement noise covariance ``R`` of each (K, 2, 2).
        prior_log_det: ``ln det P`` of the prior over the whole state.
        pose_entropy: entropy of the prior's pose part [nats].
    """

    visible: np.ndarray
    visible_indices: np.ndarray
    predicted: np.ndarray
    jacobians: np.ndarray
    noise: np.ndarray
    prior_log_det: float
    pose_entropy: float

    @classmethod
    def at_prior(
        cls, sensor: RangeBearingSensor, world: World, true_pose: np.ndarray, P: np.ndarray, predicted, jacobians
    ) -> LandmarkSight:
        """The sight of ``world``'s landmarks from ``true_pose``, with the EKF's prior covariance ``P``.

        Args:
            sensor: the range-bearing sensor (coverage and noise).
            world: the world (landmarks, line of sight).
            true_pose: the robot's true pose ``[x, y, heading]``.
            P: the prior covariance (n, n), the pose first.
            predicted: the predicted measurements (K, 2) of the EKF's measurement model.
            jacobians: their Jacobians (K, 2, n).
        """
        landmarks = world.landmarks
        visible = np.zeros(len(landmarks), dtype=bool)
        indices = np.flatnonzero(sensor.in_coverage(range_bearing(true_pose, landmarks)))
        if indices.size:
            indices = indices[world.line_of_sight(true_pose, landmarks[indices])]
            visible[indices] = True
        prior_log_det = log_det_spd(P, check_input=False)
        pose_log_det = prior_log_det
        if len(P) > POSE_DIM:
            pose_log_det = log_det_spd(P[:POSE_DIM, :POSE_DIM], check_input=False)
        return cls(
            visible=visible,
            visible_indices=indices,
            predicted=predicted,
            jacobians=jacobians,
            noise=sensor.noise_covariance(predicted[:, 0]),
            prior_log_det=prior_log_det,
            pose_entropy=gaussian_entropy_from_log_det(pose_log_det, POSE_DIM),
        )

    def information_gains(self, P: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
        """Expected mutual information [nats] of observing each of ``landmarks`` (indices) at the prior ``P``."""
        return expected_information_gain(P, self.jacobians[landmarks], self.noise[landmarks], check_input=False)

    def observe(self, ekf: PoseEKF, landmark: int, measurement: np.ndarray) -> float:
        """Update ``ekf`` (at this prior) with ``measurement`` of ``landmark``; the realized MI [nats] (Eq. 3)."""
        ekf.update_range_bearing(
            measurement, self.predicted[landmark], self.jacobians[landmark], self.noise[landmark], check_input=False
        )
        return 0.5 * (self.prior_log_det - log_det_spd(ekf.P, check_input=False))
