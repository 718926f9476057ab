"""What every estimator shares, without any filter library: the pose dimension, the ranges of a pose prior,
the input checks of the filters' public methods, and block-diagonal assembly (numpy only, cheap to import)."""

from __future__ import annotations

import math
import numbers
from typing import NamedTuple

import numpy as np

from infonav_gym.config import Interval
from infonav_gym.information import log_det_spd

POSE_DIM = 3
INITIAL_POSE_STD = {  # the allowed prior standard deviations of a pose estimate, as env config keys
    "initial_position_std_m": Interval(1e-4, 100.0, unit="m"),
    "initial_heading_std_rad": Interval(1e-5, math.pi, unit="rad"),
}


def _finite(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape``, or ``ValueError`` naming it for another shape or a NaN / inf entry."""
    array = np.asarray(value, dtype=float)
    if array.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite, got {array.tolist()}")
    return array


def _noise_covariance(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """``_finite``, and symmetric positive definite (each matrix of a stack), or ``ValueError`` naming it."""
    covariance = _finite(name, value, shape)
    if covariance.size:
        log_det_spd(covariance, name)
    return covariance


def _time_step(dt) -> float:
    """``dt`` as a float, or ``ValueError`` unless it is finite and >= 0 [s]."""
    if not (isinstance(dt, numbers.Real) and math.isfinite(dt) and dt >= 0):
        raise ValueError(f"dt must be a finite time step >= 0 [s], got {dt!r}")
    return float(dt)


def block_diagonal(blocks) -> np.ndarray:
    """The block-diagonal matrix of (k, m, m) ``blocks``."""
    k, m, _ = np.shape(blocks)
    matrix = np.zeros((k, m, k, m))
    matrix[np.arange(k), :, np.arange(k), :] = blocks
    return matrix.reshape(k * m, k * m)


class Prior(NamedTuple):
    """The estimator's prior at an episode's start, ``PoseEKF(*prior)``: the pose estimate (3,) and its diagonal
    covariance (3, 3); with mapping, the landmarks' estimates (L, 2) and the variance of each coordinate [m^2]."""

    pose: np.ndarray
    pose_covariance: np.ndarray
    landmarks: np.ndarray | None = None
    landmark_variance: float | None = None

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x, P)`` of ``PoseEKF(*prior)``: the pose then the landmarks, block-diagonal covariance."""
        if self.landmarks is None:
            return self.pose.copy(), self.pose_covariance.copy()
        variances = np.full(self.landmarks.size, self.landmark_variance)
        x = np.concatenate([self.pose, self.landmarks.ravel()])
        return x, np.diag(np.concatenate([np.diagonal(self.pose_covariance), variances]))


class BeliefBatch:
    """The batch behaviour of a planning model's belief: a frozen dataclass of arrays, each of leading size B."""

    def __len__(self) -> int:
        return len(getattr(self, next(iter(self.__dataclass_fields__))))

    def take(self, indices):
        """The beliefs at ``indices`` (a new batch, e.g. repeated once per action to try)."""
        return type(self)(*(np.take(getattr(self, name), indices, axis=0) for name in self.__dataclass_fields__))
