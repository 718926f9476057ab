"""Accuracy and consistency of a replay: RMSE against ground truth, NEES, NIS, posterior entropy."""

from __future__ import annotations

import numpy as np
from scipy import stats

from infonav_gym.estimation.consistency import chi2_bounds, pose_error
from infonav_gym.geometry import wrap_angle

MAX_GROUNDTRUTH_GAP_S = 0.5  # [s] no comparison across a longer motion-capture dropout


def groundtruth_at(groundtruth: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ground-truth poses (T, 3) interpolated at absolute ``times`` (headings unwrapped), and where that is valid (T,):
    inside the ground truth's time span and between two samples at most ``MAX_GROUNDTRUTH_GAP_S`` apart."""
    gt_times = groundtruth[:, 0]
    after = np.clip(np.searchsorted(gt_times, times), 1, len(gt_times) - 1)
    gap = gt_times[after] - gt_times[after - 1]
    valid = (times >= gt_times[0]) & (times <= gt_times[-1]) & (gap <= MAX_GROUNDTRUTH_GAP_S)
    x, y = (np.interp(times, gt_times, groundtruth[:, column]) for column in (1, 2))
    heading = wrap_angle(np.interp(times, gt_times, np.unwrap(groundtruth[:, 3])))
    return np.stack([x, y, heading], axis=-1), valid


def pose_rmse(true_poses: np.ndarray, estimates: np.ndarray) -> tuple[float, float]:
    """Position RMSE [m] and heading RMSE [rad] over matching (T, 3) pose stacks."""
    error = pose_error(true_poses, estimates)
    return (
        float(np.sqrt(np.mean(np.sum(error[:, :2] ** 2, axis=1)))),
        float(np.sqrt(np.mean(error[:, 2] ** 2))),
    )


def fraction_inside_95(values, dof: int) -> float:
    """Share of ``values`` inside the two-sided 95 % chi-square(``dof``) interval."""
    low, high = chi2_bounds(dof)
    values = np.asarray(values, dtype=float)
    return float(np.mean((values >= low) & (values <= high)))


def mean_and_ci95(values) -> dict:
    """Mean and the half-width of its Student-t 95 % confidence interval."""
    values = np.asarray(values, dtype=float)
    half_width = 0.0
    if len(values) > 1:
        half_width = float(stats.t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / np.sqrt(len(values)))
    return {"mean": float(values.mean()), "ci95": half_width, "n": len(values)}
