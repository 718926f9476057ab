"""The batched decision, observation and info of ``LandmarkSelectionVectorEnv``: the single env's, on (N, ...) arrays.

Each copy has at most K = ``n_candidates`` landmarks, stacked as (N, K, 2) with an ``exists`` mask (N, K);
missing landmarks are masked out and their observation rows stay zero, as in ``LandmarkSelectionEnv``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from infonav_gym.envs.landmark_selection import CANDIDATE_FEATURES, POSE_FEATURES
from infonav_gym.estimation import batched
from infonav_gym.estimation.ekf import POSE_DIM
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import gaussian_entropy_from_log_det, log_det_spd
from infonav_gym.sensors.range_bearing import RangeBearingSensor
from infonav_gym.world.visibility import StaticGeometry, visible


class BatchedDecision(NamedTuple):
    """Every copy's decision at its EKF's prior (``LandmarkSight`` and ``Decision`` of the single env, stacked).

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
    ) -> BatchedDecision:
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


def batched_observation(
    decision: BatchedDecision, x, P, elapsed, exists, config: dict, space: spaces.Box
) -> np.ndarray:
    """``LandmarkSelectionEnv``'s observation of every copy (N, 10 + 5K), float32, clipped to ``space``."""
    n_copies, n_candidates = exists.shape
    observation = np.zeros((n_copies, *space.shape), dtype=np.float32)
    variances = np.diagonal(P[:, :POSE_DIM, :POSE_DIM], axis1=1, axis2=2)
    observation[:, :2] = x[:, :2]
    observation[:, 2], observation[:, 3] = np.cos(x[:, 2]), np.sin(x[:, 2])
    observation[:, 4:7] = np.sqrt(variances)
    observation[:, 7] = P[:, 0, 1] / np.sqrt(variances[:, 0] * variances[:, 1])
    observation[:, 8] = decision.pose_entropy
    observation[:, 9] = elapsed / config["horizon"]
    candidates = observation[:, POSE_FEATURES:].reshape(n_copies, n_candidates, CANDIDATE_FEATURES)
    candidates[..., 0] = decision.action_mask
    ranges, bearings = decision.predicted[..., 0], decision.predicted[..., 1]
    candidates[..., 1] = np.where(exists, ranges, 0.0)
    candidates[..., 2] = np.where(exists, np.cos(bearings), 0.0)
    candidates[..., 3] = np.where(exists, np.sin(bearings), 0.0)
    if config["mapping"]:
        landmark_variances = np.diagonal(P, axis1=1, axis2=2)[:, POSE_DIM:].reshape(n_copies, -1, 2)
        candidates[:, : landmark_variances.shape[1], 4] = np.sqrt(landmark_variances.mean(axis=2))
    return np.clip(observation, space.low, space.high, out=observation)


def batched_info(decision: BatchedDecision, x, true_poses, elapsed, stepped, chosen, rewards, config: dict) -> dict:
    """``LandmarkSelectionEnv``'s info of every copy as arrays (N, ...), each with its ``_key`` mask.

    Args:
        decision: the new decisions.
        x: the EKF states (N, n).
        true_poses: the true poses (N, 3).
        elapsed: steps since each copy's reset (N,).
        stepped: which copies acted in this step (N,) bool; the others were reset and give the reset info.
        chosen: the landmark each copy observed (N,), -1 for none.
        rewards: each copy's realized MI (N,) [nats].
        config: the env config.
    """
    errors = true_poses - x[:, :POSE_DIM]
    everyone = np.ones(len(x), dtype=bool)
    info = {
        "action_mask": decision.action_mask.copy(),
        "action_information_gain": decision.action_information_gain.copy(),
        "reward_terms": {"mutual_information": np.where(stepped, rewards, 0.0), "_mutual_information": stepped.copy()},
        "chosen_action": np.where(stepped, chosen, -1),
        "invalid_action": stepped & (chosen < 0),
        "pose_entropy": decision.pose_entropy.copy(),
        "state_entropy": gaussian_entropy_from_log_det(decision.prior_log_det, x.shape[1]),
        "position_error_m": np.hypot(errors[:, 0], errors[:, 1]),
        "heading_error_rad": np.abs(wrap_angle(errors[:, 2])),
        "true_pose": true_poses.copy(),
        "estimated_pose": x[:, :POSE_DIM].copy(),
        "time_s": elapsed * config["time_step_s"],
    }
    return {**info, **{f"_{key}": everyone for key in info}}
