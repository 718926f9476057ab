"""The batched decision, observation and info of ``ActiveLocalizationVectorEnv``: the single env's, on (N, ...) arrays.

Every copy has K = ``n_candidates`` landmarks and O = ``n_obstacles`` obstacles (a goal field has exactly those
counts), stacked as (N, K, 2) and (N, O, 2). An action is observation slot ``a // 5`` (0: none, ``j + 1``:
landmark ``j``) and primitive ``a % 5``, so masks and gains are (N, 1 + K, 5) flattened to (N, 5 (1 + K)).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from infonav_gym.envs.active_localization import (
    GOAL_FEATURES,
    LANDMARK_FEATURES,
    OBSTACLE_FEATURES,
    POSE_FEATURES,
)
from infonav_gym.envs.active_planning import N_PRIMITIVES
from infonav_gym.envs.landmark_decision import LandmarkDecision
from infonav_gym.estimation.ekf import POSE_DIM
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import largest_position_std


class ActiveDecision(NamedTuple):
    """Every copy's decision at its EKF's prior (the single env's ``Decision``, stacked).

    Attributes:
        sight: the landmarks' visibility and measurement model at each prior (its mask: visible, budget aside).
        action_mask: int8 (N, A), 1 = valid: every primitive without an observation, and with each visible
            landmark while budget is left.
        action_information_gain: expected MI of each action (N, A) [nats], 0 where masked.
    """

    sight: LandmarkDecision
    action_mask: np.ndarray
    action_information_gain: np.ndarray

    @classmethod
    def from_sight(cls, sight: LandmarkDecision, observations_left: np.ndarray) -> ActiveDecision:
        """The decisions of copies whose landmarks are ``sight`` and sensing budgets ``observations_left`` (N,)."""
        n_copies, n_landmarks = sight.action_mask.shape
        observable = sight.action_mask.astype(bool) & (observations_left > 0)[:, None]
        mask = np.ones((n_copies, 1 + n_landmarks, N_PRIMITIVES), dtype=np.int8)
        mask[:, 1:] = observable[:, :, None]
        gains = np.zeros((n_copies, 1 + n_landmarks, N_PRIMITIVES))
        gains[:, 1:] = np.where(observable, sight.action_information_gain, 0.0)[:, :, None]
        return cls(sight, mask.reshape(n_copies, -1), gains.reshape(n_copies, -1))


def ranges_and_bearings(x: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Range [m] and bearing [rad] of targets (N, T, 2) from each pose (N, 3): (N, T, 2), as ``range_bearing``."""
    dx, dy = targets[..., 0] - x[:, None, 0], targets[..., 1] - x[:, None, 1]
    return np.stack([np.hypot(dx, dy), wrap_angle(np.arctan2(dy, dx) - x[:, None, 2])], axis=-1)


def batched_observation(
    decision: ActiveDecision, x, P, elapsed, observations_left, goals, obstacles, config: dict, space: spaces.Box
) -> np.ndarray:
    """``ActiveLocalizationEnv``'s observation of every copy (N, 14 + 4K + 4O), float32, clipped to ``space``.

    Args:
        decision: the copies' decisions.
        x: the EKF states (N, 3); ``P`` their covariances (N, 3, 3).
        elapsed: steps since each copy's reset (N,).
        observations_left: each copy's sensing budget left (N,).
        goals: the goal positions (N, 2) [m].
        obstacles: ``(centers (N, O, 2), radii (N, O))`` [m].
        config: the env config; ``space`` the single observation space.
    """
    n_copies, n_landmarks = decision.sight.action_mask.shape
    sight, (centers, radii) = decision.sight, obstacles
    observation = np.zeros((n_copies, *space.shape), dtype=np.float32)
    pose_end, landmarks_end = (
        POSE_FEATURES + GOAL_FEATURES,
        POSE_FEATURES + GOAL_FEATURES + LANDMARK_FEATURES * n_landmarks,
    )
    variances = np.diagonal(P, axis1=1, axis2=2)
    observation[:, :2] = x[:, :2]
    observation[:, 2], observation[:, 3] = np.cos(x[:, 2]), np.sin(x[:, 2])
    observation[:, 4:7] = np.sqrt(variances)
    observation[:, 7] = P[:, 0, 1] / np.sqrt(variances[:, 0] * variances[:, 1])
    observation[:, 8], observation[:, 9] = sight.pose_entropy, elapsed / config["horizon"]
    goal = ranges_and_bearings(x, goals[:, None])[:, 0]
    observation[:, 10], observation[:, 11], observation[:, 12] = goal[:, 0], np.cos(goal[:, 1]), np.sin(goal[:, 1])
    budget = config["max_observations"]
    observation[:, 13] = observations_left / budget if budget else 0.0
    landmarks = observation[:, pose_end:landmarks_end].reshape(n_copies, n_landmarks, LANDMARK_FEATURES)
    landmarks[..., 0], landmarks[..., 1] = sight.action_mask, sight.predicted[..., 0]
    landmarks[..., 2], landmarks[..., 3] = np.cos(sight.predicted[..., 1]), np.sin(sight.predicted[..., 1])
    seen = ranges_and_bearings(x, centers)
    obstacle_rows = observation[:, landmarks_end:].reshape(n_copies, -1, OBSTACLE_FEATURES)
    obstacle_rows[..., 0], obstacle_rows[..., 1] = seen[..., 0], np.cos(seen[..., 1])
    obstacle_rows[..., 2], obstacle_rows[..., 3] = np.sin(seen[..., 1]), radii
    return np.clip(observation, space.low, space.high, out=observation)


def batched_info(decision: ActiveDecision, state: dict, stepped, chosen, reward_terms: dict, config: dict) -> dict:
    """``ActiveLocalizationEnv``'s info of every copy as arrays (N, ...), each with its ``_key`` mask.

    Args:
        decision: the new decisions.
        state: the copies' arrays ``x`` (N, 3), ``P`` (N, 3, 3), ``true_poses`` (N, 3), ``goals`` (N, 2),
            ``elapsed``, ``observations_left``, ``goal_reached`` and ``failed`` (N,).
        stepped: which copies acted in this step (N,) bool; the others were reset and give the reset info.
        chosen: the action each copy took (N,), -1 for a no-op.
        reward_terms: each term of each copy (N,) [nats].
        config: the env config.
    """
    x, true_poses, goals = state["x"], state["true_poses"], state["goals"]
    errors = true_poses - x
    pose_entropy = decision.sight.pose_entropy
    everyone = np.ones(len(x), dtype=bool)
    terms = {key: np.where(stepped, value, 0.0) for key, value in reward_terms.items()}
    info = {
        "action_mask": decision.action_mask.copy(),
        "action_information_gain": decision.action_information_gain.copy(),
        "reward_terms": {**terms, **{f"_{key}": stepped.copy() for key in terms}},
        "chosen_action": np.where(stepped, chosen, -1),
        "invalid_action": stepped & (chosen < 0),
        "pose_entropy": pose_entropy.copy(),
        "state_entropy": pose_entropy.copy(),
        "position_error_m": np.hypot(errors[:, 0], errors[:, 1]),
        "heading_error_rad": np.abs(wrap_angle(errors[:, 2])),
        "position_std_m": largest_position_std(state["P"]),
        "true_pose": true_poses.copy(),
        "estimated_pose": x[:, :POSE_DIM].copy(),
        "goal": goals.copy(),
        "distance_to_goal_m": np.hypot(*(true_poses[:, :2] - goals).T),
        "observations_left": state["observations_left"].copy(),
        "goal_reached": state["goal_reached"].copy(),
        "success": state["goal_reached"].copy(),
        "failed": state["failed"].copy(),
        "time_s": state["elapsed"] * config["time_step_s"],
    }
    return {**info, **{f"_{key}": everyone for key in info}}
