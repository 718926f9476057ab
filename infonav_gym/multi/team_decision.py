"""A team's relative-pose decision on (N, R, ...) arrays: every copy has the same P pairs (``SensingPairs``), so the
candidates of all copies stack as (N, P, ...); a pair that is not observable now is masked out."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from infonav_gym.compiled import contiguous, kernel
from infonav_gym.estimation.kernels import pose_block_log_dets, relative_pose_gains, relative_pose_models
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.multi.team_sensing import NO_OBSERVATION, SensingPairs
from infonav_gym.world.visibility import StaticGeometry, shape_arrays
from infonav_gym.world.visibility_kernels import blocked


class TeamDecision(NamedTuple):
    """Every copy's decision at its joint EKF's prior: ``action_mask`` int8 (N, R, R + 1) (action 0 always,
    ``1 + j`` where robot ``j`` is observable) and ``action_information_gain`` (expected reward [nats], 0 where
    masked); of every pair (N, P, ...): its true range, bearing and relative heading (``geometry``), whether it is
    observable (``valid``), the prior's prediction of its measurement (``predicted``), its Jacobians and its noise
    covariance ``R`` at the predicted range; each robot's pose ``ln det`` (N, R) and x, y, heading std (N, R, 3)."""

    action_mask: np.ndarray
    action_information_gain: np.ndarray
    geometry: np.ndarray
    valid: np.ndarray
    predicted: np.ndarray
    H_observer: np.ndarray
    H_target: np.ndarray
    R: np.ndarray
    pose_log_det: np.ndarray
    pose_std: np.ndarray

    @classmethod
    def at_prior(cls, pairs: SensingPairs, geometry, valid, x, P, team_reward: float) -> TeamDecision:
        """The decisions of N copies at their priors ``x`` (N, 3R), ``P`` (N, 3R, 3R), of the ``pairs``' true
        ``geometry`` and ``valid`` (``observable_pairs``); ``team_reward``: the team MI's weight in [0, 1]."""
        mask, gains, *models, undefined = pair_decisions(x, P, *pairs[:3], valid, float(team_reward))
        if undefined:
            raise ValueError("a pose covariance, or a posterior or innovation covariance, is not positive definite")
        return cls(mask, gains, geometry, valid, *models)


def observable_pairs(pairs: SensingPairs, geometry: StaticGeometry, true_poses) -> tuple[np.ndarray, np.ndarray]:
    """Every pair's true range, bearing and relative heading (N, P, 3) and which are observable now (N, P) bool: in
    the observer's range and field of view, the line of sight clear of ``geometry`` (tested once, where needed)."""
    lines = pairs.observers, pairs.targets, pairs.max_range_m, pairs.half_fov_rad, pairs.sight_line, pairs.sight_lines
    return pair_sight(contiguous(true_poses), *lines, *shape_arrays(geometry))


@kernel
def pair_sight(true_poses, observers, targets, max_range_m, half_fov_rad, sight_line, lines, walls, discs, culled):
    """``observable_pairs`` of the pairs' arrays (``SensingPairs``) and the shapes' (``shape_arrays``)."""
    n_copies, n_pairs = true_poses.shape[0], len(observers)
    geometry, valid = np.empty((n_copies, n_pairs, POSE_DIM)), np.zeros((n_copies, n_pairs), dtype=np.bool_)
    needed = np.zeros((n_copies, len(lines)), dtype=np.bool_)
    for c in range(n_copies):
        for k in range(n_pairs):
            observer, target = true_poses[c, observers[k]], true_poses[c, targets[k]]
            dx, dy = target[0] - observer[0], target[1] - observer[1]
            range_m, bearing = math.hypot(dx, dy), wrap(math.atan2(dy, dx) - observer[2])
            geometry[c, k, 0], geometry[c, k, 1], geometry[c, k, 2] = range_m, bearing, wrap(target[2] - observer[2])
            valid[c, k] = range_m <= max_range_m[k] and abs(bearing) <= half_fov_rad[k]
            needed[c, sight_line[k]] |= valid[c, k]
    copies, needed_lines = np.nonzero(needed)
    starts, ends = np.empty((len(copies), 2)), np.empty((len(copies), 2))
    for m in range(len(copies)):
        for i in range(2):
            starts[m, i] = true_poses[copies[m], lines[needed_lines[m], 0], i]
            ends[m, i] = true_poses[copies[m], lines[needed_lines[m], 1], i]
    clear = np.ones(needed.shape, dtype=np.bool_)
    hit = blocked(copies, starts, ends, walls, discs, culled)
    for m in range(len(copies)):
        clear[copies[m], needed_lines[m]] = not hit[m]
    for c in range(n_copies):
        for k in range(n_pairs):
            valid[c, k] &= clear[c, sight_line[k]]
    return geometry, valid


@kernel
def pair_decisions(x, P, observers, targets, noise, valid, team_reward):
    """``TeamDecision.at_prior``'s arrays of the pairs (``SensingPairs``) and which are ``valid`` (N, P), then
    whether a determinant was not > 0 (``relative_pose_gains``, of the valid pairs: no action observes another)
    or a target lies on its observer."""
    n_copies, n_robots, n_pairs = x.shape[0], x.shape[1] // POSE_DIM, len(observers)
    copy_observers, copy_targets = np.empty((n_copies, n_pairs), np.int64), np.empty((n_copies, n_pairs), np.int64)
    for c in range(n_copies):  # every copy has the same pairs (element by element: see ``infonav_gym.compiled``)
        for k in range(n_pairs):
            copy_observers[c, k], copy_targets[c, k] = observers[k], targets[k]
    predicted, H_observer, H_target, coincident = relative_pose_models(x, copy_observers, copy_targets)
    R = np.zeros((n_copies, n_pairs, POSE_DIM, POSE_DIM))
    for c in range(n_copies):
        for k in range(n_pairs):  # the diagonal noise covariance at the predicted range (``noise_covariances``)
            range_m = predicted[c, k, 0]
            R[c, k, 0, 0] = (noise[k, 0] + noise[k, 1] * range_m) ** 2
            R[c, k, 1, 1] = noise[k, 2] ** 2
            R[c, k, 2, 2] = (noise[k, 3] + noise[k, 4] * range_m) ** 2
    own, joint = relative_pose_gains(P, copy_observers, copy_targets, H_observer, H_target, R, valid)
    mask, gains = np.zeros((n_copies, n_robots, n_robots + 1), np.int8), np.zeros((n_copies, n_robots, n_robots + 1))
    mask[..., NO_OBSERVATION] = 1
    undefined = coincident
    for c in range(n_copies):
        for k in range(n_pairs):
            undefined |= math.isnan(own[c, k]) or math.isnan(joint[c, k])
            if valid[c, k]:
                mask[c, observers[k], targets[k] + 1] = 1
                gains[c, observers[k], targets[k] + 1] = (1.0 - team_reward) * own[c, k] + team_reward * joint[c, k]
    pose_std, pose_log_det = np.empty((n_copies, n_robots * POSE_DIM)), pose_block_log_dets(P, n_robots)
    for c in range(n_copies):
        for i in range(POSE_DIM * n_robots):
            pose_std[c, i] = math.sqrt(P[c, i, i])
            undefined |= math.isnan(pose_log_det[c, i // POSE_DIM])
    pose_std = pose_std.reshape((n_copies, n_robots, POSE_DIM))
    return mask, gains, predicted, H_observer, H_target, R, pose_log_det, pose_std, undefined
