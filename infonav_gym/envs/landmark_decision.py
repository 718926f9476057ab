"""``LandmarkDecision``: which landmarks each copy's range-bearing sensor sees, their measurement model and gains.

Shared by ``LandmarkSelection-v0`` and ``ActiveLocalization-v0``, whose decisions both pick a landmark to observe
at the EKF's prior. Each copy has at most K landmarks, stacked as (N, K, 2) with an ``exists`` mask (N, K).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from infonav_gym.estimation import batched
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.information import gaussian_entropy_from_log_det, log_det_spd
from infonav_gym.sensors.range_bearing import RangeBearingSensor
from infonav_gym.world.visibility import StaticGeometry, visible


class LandmarkDecision(NamedTuple):
    """Every copy's decision at its EKF's prior.

    Attributes:
        action_mask: int8 (N, K), 1 = the landmark exists and is visible from the true pose.
        action_information_gain: expected MI of observing each landmark (N, K) [nats], 0 where masked.
        predicted: range [m] and bearing [rad] of each landmark as the prior predicts them (N, K, 2).
        H: their Jacobians w.r.t. the state (N, K, 2, n).
        R: their noise covariances (N, K, 2, 2).
        prior_log_det: ``ln det P`` of each prior over the whole state (N,).
        pose_entropy: entropy of each prior's pose part (N,) [nats].
    """

    action_mask: np.ndarray
    action_information_gain: np.ndarray
    predicted: np.ndarray
    H: np.ndarray
    R: np.ndarray
    prior_log_det: np.ndarray
    pose_entropy: np.ndarray

    @classmethod
    def at_prior(
        cls,
        sensor: RangeBearingSensor,
        geometry: StaticGeometry,
        true_poses: np.ndarray,
        x: np.ndarray,
        P: np.ndarray,
        landmarks: np.ndarray,
        exists: np.ndarray,
        mapping: bool,
    ) -> LandmarkDecision:
        """The decisions of N copies: true poses (N, 3), priors ``x`` (N, n), ``P`` (N, n, n), landmarks (N, K, 2)."""
        n_copies, n_candidates = exists.shape
        if mapping:  # every copy maps its L <= K landmarks in its state
            mapped_predicted, mapped_H = batched.landmark_measurement_model(x, check_input=False)
            n_mapped = mapped_predicted.shape[1]
            predicted = np.zeros((n_copies, n_candidates, 2))
            H = np.zeros((n_copies, n_candidates, 2, x.shape[1]))
            predicted[:, :n_mapped], H[:, :n_mapped] = mapped_predicted, mapped_H
        else:  # a missing landmark is put 1 m off the estimate, where its (unused) model is defined
            known = np.where(exists[..., None], landmarks, x[:, None, :2] + 1.0)
            predicted, H = batched.landmark_measurement_model(x, known, check_input=False)
        R = sensor.noise_covariance(predicted[..., 0].ravel()).reshape(n_copies, n_candidates, 2, 2)
        seen = exists & visible(geometry, sensor, true_poses, landmarks, check_input=False)
        gains = np.where(seen, batched.landmark_information_gains(P, H, R, check_input=False), 0.0)
        prior_log_det = log_det_spd(P, check_input=False)
        pose_log_det = prior_log_det
        if x.shape[1] > POSE_DIM:
            pose_log_det = log_det_spd(P[:, :POSE_DIM, :POSE_DIM], check_input=False)
        pose_entropy = gaussian_entropy_from_log_det(pose_log_det, POSE_DIM)
        return cls(seen.astype(np.int8), gains, predicted, H, R, prior_log_det, pose_entropy)
