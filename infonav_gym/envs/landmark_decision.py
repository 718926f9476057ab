"""``LandmarkDecision``: which landmarks each copy's range-bearing sensor sees, their measurement model and gains
at the EKF's prior (``LandmarkSelection-v0``, ``ActiveLocalization-v0``); at most K landmarks a copy, (N, K, 2)
with an ``exists`` mask (N, K)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from infonav_gym.compiled import CopyThreads, contiguous, kernel
from infonav_gym.envs.noise_streams import NoiseStreams, taken
from infonav_gym.estimation import batched
from infonav_gym.estimation.kernels import (
    chosen_landmark_updates,
    landmark_gain,
    pose_block_log_dets,
    range_bearing_models,
)
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.information import gaussian_entropy_kernel, stacked_log_dets
from infonav_gym.sensors.range_bearing import noise_covariances, noisy_range_bearing
from infonav_gym.world.visibility import shape_arrays
from infonav_gym.world.visibility_kernels import blocked, covered


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
        cls, sensor, geometry, true_poses, x, P, landmarks, exists, mapping: bool, threads: CopyThreads
    ) -> LandmarkDecision:
        """The decisions of N copies at their priors ``x`` (N, n), ``P`` (N, n, n) (``landmark_decisions`` on
        ``threads``); raises as ``checked_fields``."""
        arguments = decision_arguments(sensor, geometry, true_poses, x, P, landmarks, exists, mapping)
        return cls(*checked_fields(threads.map_rows(landmark_decisions, len(x), arguments)))

    def observe(
        self, x, P, chosen, true_poses, landmarks, noise: NoiseStreams, noise_stds, threads: CopyThreads
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Update each copy's EKF prior ``(x, P)`` ((N, n), (N, n, n), this decision's) with a noisy range-bearing
        measurement of its ``chosen`` landmark (N,) (-1: none) from its true pose (N, 3) to the true ``landmarks``
        (N, K, 2), its two standard normals the next draw of its ``noise`` stream (``noise_stds``: the sensor's);
        ``(x, P, realized MI (N,) [nats])``, 0 for a copy without a measurement."""
        floats = [contiguous(array) for array in (x, P, true_poses, landmarks)]
        chosen, model = contiguous(np.asarray(chosen, dtype=np.int64)), (self.predicted, self.H, self.R)
        per_copy = (*floats, *noise.reserve(), chosen, *model, self.prior_log_det)
        *updated, not_positive_definite = threads.map_rows(measured_updates, len(chosen), per_copy, (noise_stds,))
        if not_positive_definite:
            raise ValueError("the posterior covariance is not positive definite (determinant <= 0)")
        return tuple(updated)


def checked_fields(decided: tuple) -> list:
    """The fields of the decision ``landmark_decisions`` returned; a ``ValueError`` if a landmark coincides with a
    copy's estimated position or a prior is not positive definite."""
    *decision, coincident, not_positive_definite = decided
    if coincident:
        raise ValueError(batched.COINCIDENT)
    if not_positive_definite:
        raise ValueError("P is not positive definite (determinant <= 0)")
    return decision


def decision_arguments(sensor, geometry, true_poses, x, P, landmarks, exists, mapping) -> tuple:
    """The arguments of ``landmark_decisions`` for ``LandmarkDecision.at_prior``'s (C-contiguous, typed)."""
    floats = [contiguous(np.asarray(array, dtype=float)) for array in (x, P, landmarks, true_poses)]
    coverage = float(sensor.max_range_m), float(sensor.fov_rad)
    exists = contiguous(np.asarray(exists, dtype=bool))
    return (*floats, exists, bool(mapping), sensor.noise_stds, coverage, *shape_arrays(geometry))


@kernel
def measured_updates(
    x, P, true_poses, landmarks, blocks, next_draw, chosen, predicted, H, R, prior_log_det, noise_stds
):
    """``LandmarkDecision.observe``: each chosen landmark's noisy ``[range, bearing]`` from its copy's true pose
    (``noisy_range_bearing`` given its copy's next draw of ``blocks``, ``NoiseStreams.reserve``'s),
    then ``chosen_landmark_updates``; and whether a posterior is not positive definite."""
    measurements = np.zeros((len(chosen), 2))
    for c in range(len(chosen)):
        k = chosen[c]
        if k >= 0:
            dx, dy = landmarks[c, k, 0] - true_poses[c, 0], landmarks[c, k, 1] - true_poses[c, 1]
            noise = taken(blocks, next_draw, c)
            noisy_range_bearing(dx, dy, true_poses[c, 2], noise_stds, noise, measurements[c])
    x, P, realized = chosen_landmark_updates(x, P, measurements, chosen, predicted, H, R, prior_log_det)
    not_positive_definite = False
    for c in range(len(chosen)):
        not_positive_definite |= math.isnan(realized[c])
    return x, P, realized, not_positive_definite


@kernel
def landmark_decisions(x, P, landmarks, true_poses, exists, mapped, noise_stds, coverage, walls, discs, culled):
    """``LandmarkDecision.at_prior`` of N copies: its fields, then whether a landmark coincides with its copy's
    estimate and whether a log det is NaN (a prior that is not positive definite).

    ``noise_stds``: the sensor's ``noise_stds``; ``coverage``: its ``(max_range_m, fov_rad)``; ``walls``, ``discs``,
    ``culled``: the static geometry's ``shape_arrays``. Without ``mapped`` a missing landmark is put 1 m off the
    estimate, where its (unused) model is defined; with it, the L <= K landmarks of the state are modelled.
    """
    n_copies, n = x.shape
    n_candidates = exists.shape[1]
    n_modelled = (n - POSE_DIM) // 2 if mapped else n_candidates
    positions = np.empty((n_copies, n_modelled, 2))
    for c in range(n_copies):
        for k in range(n_modelled):
            if mapped:
                positions[c, k, 0], positions[c, k, 1] = x[c, POSE_DIM + 2 * k], x[c, POSE_DIM + 2 * k + 1]
            elif exists[c, k]:
                positions[c, k, 0], positions[c, k, 1] = landmarks[c, k, 0], landmarks[c, k, 1]
            else:
                positions[c, k, 0], positions[c, k, 1] = x[c, 0] + 1.0, x[c, 1] + 1.0
    predicted, H, coincident = range_bearing_models(x, positions, mapped)
    if n_modelled < n_candidates:  # the candidates beyond the state's landmarks get zeros
        modelled, modelled_H = predicted, H
        predicted, H = np.zeros((n_copies, n_candidates, 2)), np.zeros((n_copies, n_candidates, 2, n))
        for c in range(n_copies):  # element by element: a slice assignment compiles numba's shape-error formatting
            for k in range(n_modelled):
                for i in range(2):
                    predicted[c, k, i] = modelled[c, k, i]
                    for j in range(n):
                        H[c, k, i, j] = modelled_H[c, k, i, j]
    ranges, n_queries = np.empty(n_copies * n_candidates), 0
    seen = covered(true_poses, landmarks, coverage[0], coverage[1])
    for c in range(n_copies):
        for k in range(n_candidates):
            ranges[c * n_candidates + k] = predicted[c, k, 0]
            seen[c, k] = seen[c, k] and exists[c, k]
            n_queries += seen[c, k]
    R = noise_covariances(ranges, noise_stds[0], noise_stds[1], noise_stds[2]).reshape(n_copies, n_candidates, 2, 2)
    copy, origins, targets = np.empty(n_queries, dtype=np.int64), np.empty((n_queries, 2)), np.empty((n_queries, 2))
    query = 0
    for c in range(n_copies):
        for k in range(n_candidates):
            if seen[c, k]:
                copy[query] = c
                origins[query, 0], origins[query, 1] = true_poses[c, 0], true_poses[c, 1]
                targets[query, 0], targets[query, 1] = landmarks[c, k, 0], landmarks[c, k, 1]
                query += 1
    hit = blocked(copy, origins, targets, walls, discs, culled)
    action_mask, gains = np.zeros((n_copies, n_candidates), dtype=np.int8), np.zeros((n_copies, n_candidates))
    HP, S, columns = np.empty((2, n)), np.empty((2, 2)), np.empty(n, dtype=np.int64)
    query = 0
    for c in range(n_copies):
        for k in range(n_candidates):
            if seen[c, k]:
                action_mask[c, k] = not hit[query]
                query += 1
            if action_mask[c, k]:  # a gain only where the landmark can be observed
                gains[c, k] = landmark_gain(P[c], H[c, k], R[c, k], HP, S, columns)
    prior_log_det = stacked_log_dets(P)
    pose_log_det = pose_block_log_dets(P, 1)[:, 0] if n > POSE_DIM else prior_log_det
    not_positive_definite, pose_entropy = False, np.empty(n_copies)
    for c in range(n_copies):
        not_positive_definite |= math.isnan(prior_log_det[c]) or math.isnan(pose_log_det[c])
        pose_entropy[c] = gaussian_entropy_kernel(pose_log_det[c], POSE_DIM)
    return action_mask, gains, predicted, H, R, prior_log_det, pose_entropy, coincident, not_positive_definite
