"""Filter consistency: NEES, NIS and their chi-square bounds (Bar-Shalom, Ch. 5.4)."""

from __future__ import annotations

import numpy as np

from infonav_gym.geometry import wrap_angle


def pose_error(true_pose, estimated_pose) -> np.ndarray:
    """``true - estimated`` for ``[x, y, heading]`` poses, heading wrapped; works on (..., 3) stacks."""
    error = np.asarray(true_pose, dtype=float) - np.asarray(estimated_pose, dtype=float)
    error[..., 2] = wrap_angle(error[..., 2])
    return error


def normalized_squared_error(error, covariance) -> float:
    """``e^T C^-1 e``: the NEES of an estimation error or the NIS of an innovation."""
    error, covariance = np.asarray(error, dtype=float), np.asarray(covariance, dtype=float)
    if covariance.shape != (error.size, error.size):
        raise ValueError(f"covariance must be ({error.size}, {error.size}) for an error of size {error.size}")
    return float(error @ np.linalg.solve(covariance, error))


def nees(true_state, estimate, covariance) -> float:
    """Normalized estimation error squared of a pose estimate; chi-square with 3 dof if consistent."""
    return normalized_squared_error(pose_error(true_state, estimate), covariance)


def nis(innovation, innovation_covariance) -> float:
    """Normalized innovation squared; chi-square with ``len(innovation)`` dof if consistent."""
    return normalized_squared_error(innovation, innovation_covariance)


def chi2_bounds(dof: int, n_runs: int = 1, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided bounds for the average of ``n_runs`` independent chi-square(dof) statistics (``n_runs * average`` is
    chi-square with ``n_runs * dof`` degrees of freedom)."""
    if dof < 1 or n_runs < 1 or not 0 < confidence < 1:
        raise ValueError(f"need dof >= 1, n_runs >= 1 and 0 < confidence < 1, got {dof}, {n_runs}, {confidence}")
    from scipy import stats  # about 1 s to import: only when bounds are asked for, not with every env

    tail = (1.0 - confidence) / 2.0
    low, high = stats.chi2.ppf([tail, 1.0 - tail], dof * n_runs)
    return float(low) / n_runs, float(high) / n_runs
