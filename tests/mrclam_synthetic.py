"""Synthetic MRCLAM-format logs drawn from a known noise model (``RobotNoise``), for calibration tests.

Robots drive weaving circles among 16 landmarks, in a direction the model's travel offset away from the
heading their ground truth (and camera) gives. Odometry and measurement times are written on their
own clocks (true time minus the model's offsets); odometry carries its scale and white noise of the
model's densities; each measurement carries the model's systematic error (polynomial in the true
bearing), a per-landmark and a shared Gauss-Markov bias in distance driven, white noise growing with the
squared range, and,
with the model's outlier fractions, gross errors of 5 to 30 model std.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from infonav_gym.datasets.noise_model import RobotNoise

EPOCH = 1.25e9  # [s] the logs' clock, as in the published sets
RING = [(5.0 * math.cos(a), 4.0 * math.sin(a)) for a in np.linspace(0, 2 * math.pi, 12, endpoint=False)]
LANDMARKS = {6 + i: position for i, position in enumerate(RING + [(1.5, 0.0), (-1.5, 0.0), (0.0, 2.5), (0.0, -2.5)])}
ODOMETRY_DT, MEASUREMENT_DT, GROUNDTRUTH_DT = 0.02, 0.2, 0.01  # [s]
FIELD_OF_VIEW_RAD, MAX_RANGE_M = 0.55, 6.0
MODEL = RobotNoise(
    odometry_time_offset_s=0.2,
    measurement_time_offset_s=-0.1,
    speed_scale=1.04,
    turn_rate_scale=1.03,
    travel_heading_offset_rad=0.012,
    speed_std=0.02,
    turn_rate_std=0.03,
    speed_bias_std=0.0,
    speed_correlation_time_s=10.0,
    turn_rate_bias_std=0.0,
    turn_rate_correlation_time_s=10.0,
    range_bias_m=0.15,
    range_bias_per_rad=0.0,
    range_bias_per_rad2=-1.5,
    range_bias_per_m=-0.01,
    range_bias_per_m_rad=0.0,
    range_bias_per_m_rad2=-0.3,
    range_white_std_m=0.005,
    range_white_std_per_m2=0.0033,
    range_bias_std_m=0.04,
    range_correlation_distance_m=0.5,
    range_shared_std_m=0.01,
    range_shared_correlation_distance_m=2.0,
    range_outlier_fraction=0.02,
    bearing_bias_rad=0.005,
    bearing_bias_per_rad=0.0,
    bearing_bias_per_rad2=-0.05,
    bearing_bias_per_rad3=0.0,
    bearing_white_std_rad=0.005,
    bearing_bias_std_rad=0.004,
    bearing_correlation_distance_m=1.0,
    bearing_shared_std_rad=0.003,
    bearing_shared_correlation_distance_m=2.0,
    bearing_outlier_fraction=0.02,
)


def _write(path: Path, rows) -> None:
    path.write_text(
        "# synthetic MRCLAM-format file\n" + "".join(" \t".join(f"{v:.6f}" for v in row) + "\n" for row in rows)
    )


def _controls(t, phase: float):
    speed = 0.15 + 0.05 * np.sin(2 * math.pi * t / 37.0 + phase)
    return speed, speed / 2.5 + 0.35 * np.sin(2 * math.pi * t / 6.0 + phase)


def true_motion(t, phase: float):
    """Pose (T, 3), speed and turn rate (T,) at times ``t``: a 2.5 m circle driven at 0.1-0.2 m/s, weaving
    (turn rate +-0.35 rad/s, period 6 s) as the real robots do; integrated from t = 0 on a 1 ms grid."""
    t = np.asarray(t, dtype=float)
    step = 1e-3
    fine = np.arange(0.0, t.max() + 2 * step, step)
    speed, turn_rate = _controls(fine + 0.5 * step, phase)  # midpoint rule
    heading = phase + np.concatenate([[0.0], np.cumsum(turn_rate[:-1] * step)])
    middle = heading[:-1] + 0.5 * turn_rate[:-1] * step
    x = 2.5 * math.sin(phase) + np.concatenate([[0.0], np.cumsum(speed[:-1] * np.cos(middle) * step)])
    y = -2.5 * math.cos(phase) + np.concatenate([[0.0], np.cumsum(speed[:-1] * np.sin(middle) * step)])
    heading_at = np.interp(t, fine, heading)
    pose = np.stack(
        [np.interp(t, fine, x), np.interp(t, fine, y), np.remainder(heading_at + math.pi, 2 * math.pi) - math.pi], -1
    )
    return (pose, *_controls(t, phase))


def _gauss_markov(rng, distances, std, length, n_targets) -> np.ndarray:
    """A bias per target along cumulative ``distances`` (T,): (T, n_targets), stationary std ``std``."""
    decay = np.exp(-np.diff(distances, prepend=distances[0]) / length)
    bias = np.empty((len(distances), n_targets))
    bias[0] = rng.normal(0.0, std, n_targets)
    for i in range(1, len(distances)):
        bias[i] = decay[i] * bias[i - 1] + rng.normal(0.0, std * math.sqrt(1 - decay[i] ** 2), n_targets)
    return bias


def _with_outliers(rng, error, std, fraction):
    gross = rng.random(len(error)) < fraction
    error[gross] += rng.choice([-1.0, 1.0], gross.sum()) * rng.uniform(5.0, 30.0, gross.sum()) * std[gross]
    return error


def write_synthetic_dataset(directory: Path, rng: np.random.Generator, duration_s: float = 1200.0, model=MODEL):
    """Write a two-robot dataset drawn from ``model`` into ``directory`` (created); return ``directory``."""
    directory.mkdir(parents=True, exist_ok=True)
    subjects = {1: 1, 2: 2, **{s: s for s in LANDMARKS}}
    _write(directory / "Barcodes.dat", [(subject, 100 + barcode) for subject, barcode in subjects.items()])
    _write(directory / "Landmark_Groundtruth.dat", [(s, x, y, 1e-4, 1e-4) for s, (x, y) in LANDMARKS.items()])
    positions = np.array(list(LANDMARKS.values()))
    for robot, phase in ((1, 0.0), (2, math.pi)):
        times = np.arange(0.0, duration_s, GROUNDTRUTH_DT)
        pose, *_ = true_motion(times, phase)
        pose[:, 2] = _marker_heading(pose[:, 2], model)
        _write(directory / f"Robot{robot}_Groundtruth.dat", np.column_stack([EPOCH + times, pose]))
        times = np.arange(0.0, duration_s, ODOMETRY_DT)
        _, speed, turn_rate = true_motion(times, phase)
        noise_speed = rng.normal(0.0, model.speed_std / math.sqrt(ODOMETRY_DT), len(times))
        noise_turn = rng.normal(0.0, model.turn_rate_std / math.sqrt(ODOMETRY_DT), len(times))
        odometry = [
            EPOCH + times - model.odometry_time_offset_s,
            model.speed_scale * (speed + noise_speed),
            model.turn_rate_scale * (turn_rate + noise_turn),
        ]
        _write(directory / f"Robot{robot}_Odometry.dat", np.column_stack(odometry))
        _write(directory / f"Robot{robot}_Measurement.dat", _measurements(rng, model, positions, phase, duration_s))
    return directory


def _marker_heading(heading, model):
    """The motion-capture (and camera) heading of a robot driving along ``heading``."""
    return np.remainder(heading - model.travel_heading_offset_rad + math.pi, 2 * math.pi) - math.pi


def _measurements(rng, model, positions, phase, duration_s) -> np.ndarray:
    times = np.arange(0.5, duration_s, MEASUREMENT_DT)
    pose, speed, _ = true_motion(times, phase)
    pose[:, 2] = _marker_heading(pose[:, 2], model)
    driven = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * MEASUREMENT_DT)])
    range_bias = _gauss_markov(rng, driven, model.range_bias_std_m, model.range_correlation_distance_m, len(positions))
    bearing_bias = _gauss_markov(
        rng, driven, model.bearing_bias_std_rad, model.bearing_correlation_distance_m, len(positions)
    )
    range_bias += _gauss_markov(rng, driven, model.range_shared_std_m, model.range_shared_correlation_distance_m, 1)
    bearing_bias += _gauss_markov(
        rng, driven, model.bearing_shared_std_rad, model.bearing_shared_correlation_distance_m, 1
    )
    offsets = positions[None] - pose[:, None, :2]
    true_range = np.hypot(offsets[..., 0], offsets[..., 1])
    true_bearing = np.remainder(np.arctan2(offsets[..., 1], offsets[..., 0]) - pose[:, 2:3] + math.pi, 2 * math.pi)
    true_bearing -= math.pi
    seen = (true_range < MAX_RANGE_M) & (np.abs(true_bearing) < FIELD_OF_VIEW_RAD)
    epoch, target = np.nonzero(seen)
    r, b = true_range[seen], true_bearing[seen]
    white_range = model.range_white_std(r)
    range_error = model.range_bias(r, b) + range_bias[epoch, target] + rng.normal(0.0, 1.0, len(r)) * white_range
    range_error = _with_outliers(
        rng, range_error, np.hypot(white_range, model.range_bias_std_m), model.range_outlier_fraction
    )
    bearing_std = np.full(len(b), math.hypot(model.bearing_white_std_rad, model.bearing_bias_std_rad))
    bearing_error = (
        model.bearing_bias(b) + bearing_bias[epoch, target] + rng.normal(0, model.bearing_white_std_rad, len(b))
    )
    bearing_error = _with_outliers(rng, bearing_error, bearing_std, model.bearing_outlier_fraction)
    subjects = np.array(list(LANDMARKS))[target]
    return np.column_stack(
        [EPOCH + times[epoch] - model.measurement_time_offset_s, 100 + subjects, r + range_error, b + bearing_error]
    )
