"""Noise identification from motion-capture ground truth (never the filter's RMSE): the errors actually seen.

Per robot and pooled: the odometry and measurement clock offsets and the direction of travel against the ground-truth
heading; the odometry's scales, white noise densities and slow Gauss-Markov biases (``fit_odometry``, from the growth
of the integrated error's variance with the window; the plain variance, not a robust one: odometry cannot be gated, so
its noise must carry its heavy tails, wheel slip); for range and bearing to landmarks (``fit_channel``) a systematic
part, a polynomial in the measured bearing, the target's place in the camera image (on Dataset 6 the range term cuts
the robust spread of the range residuals from 4-5.5 cm to 1.5-2 cm), white noise from looks at a target under 0.5 s
apart (the bias cancels), a slow per-target and a shared bias from the covariance of look pairs against the distance
driven between them (the errors follow the viewing geometry, not the clock), the outlier fraction, and a Student-t fit
of the standardized errors as a diagnostic.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize, stats

from infonav_gym.datasets.mrclam import MRCLAMDataset
from infonav_gym.datasets.noise_model import (
    ODOMETRY_HORIZON_S,
    SYSTEMATIC_FIELDS,
    NoiseModel,
    RobotNoise,
    integrated_variance,
)
from infonav_gym.datasets.timeline import held_integral, running_sums
from infonav_gym.experiments.replay.metrics import groundtruth_at
from infonav_gym.geometry import wrap_angle

OFFSET_GRID_S = np.round(np.arange(-0.5, 0.5001, 0.01), 2)  # [s] candidate clock offsets
ODOMETRY_GRID_S = 0.1  # [s] resolution of the integrated odometry errors
TRAVEL_STEP_S = 0.2  # [s] ground-truth steps whose sideways motion gives the direction of travel
# [s] windows whose error growth gives the odometry noise, up to the horizon the filter's density matches
NOISE_WINDOWS_S = (1.0, 2.0, 4.0, 8.0, 16.0, 32.0, ODOMETRY_HORIZON_S)
WINDOW_STEP_S = 0.5  # [s] windows start this far apart (longer ones overlap: more samples of their variance)
SHORT_LAG_S = 0.5  # [s] consecutive looks closer than this share their bias
# A parked robot repeats one error (on Dataset 6 robot 1's 136 parked look pairs hold 32 distinct looks, with a
# covariance 40 times the moving ones'): the bias process is fitted from pairs at least 1 cm of driving apart.
TRAVEL_EDGES_M = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)  # [m] bins of the bias covariance fit
NO_DECAY_LENGTH_M = 1000.0  # [m] correlation length when the covariance does not decay: a constant bias
OUTLIER_Z = 4.0  # errors beyond this many model std count as outliers
RANGE_BINS = 5  # range quantile bins of the white range std
MIN_BIN = 20  # fewest samples a bin needs to enter a fit
PAIR_STEPS = (1, 2, 4, 8, 16, 32, 64, 128, 256)  # looks apart of the pairs whose covariance gives the bias
INDEPENDENT_CELL_M = 0.05  # [m] looks at a target within this much travel count as one sample of its bias


def robust_std(values) -> float:
    """``1.4826 * MAD``: the std of a normal sample, insensitive to outliers."""
    values = np.asarray(values, dtype=float)
    return float(1.4826 * np.median(np.abs(values - np.median(values))))


def odometry_errors(odometry, groundtruth, offset_s: float, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Integrated odometry errors ``[forward distance, heading]`` (W, 2) over windows starting every ``WINDOW_STEP_S``
    and the true forward progress and heading change (W, 2), as ``(errors, truth)``; odometry times shifted by
    ``offset_s``."""
    times = odometry[:, 0] + offset_s
    start, end = max(times[0], groundtruth[0, 0]), min(times[-1], groundtruth[-1, 0])
    grid = np.arange(start, end, ODOMETRY_GRID_S)
    poses, valid = groundtruth_at(groundtruth, grid)
    heading = np.unwrap(poses[:, 2])
    middle = heading[:-1] + 0.5 * np.diff(heading)
    forward = np.einsum("ti,ti->t", np.diff(poses[:, :2], axis=0), np.stack([np.cos(middle), np.sin(middle)], -1))
    true_cumulative = np.column_stack([running_sums(forward), heading - heading[0]])
    odometry_cumulative = np.column_stack([held_integral(times, odometry[:, column], grid) for column in (1, 2)])
    stride = int(round(window_s / ODOMETRY_GRID_S))
    invalid_before = running_sums(~valid)
    starts = np.arange(0, len(grid) - stride, int(round(WINDOW_STEP_S / ODOMETRY_GRID_S)))
    ok = invalid_before[starts + stride + 1] == invalid_before[starts]
    truth = (true_cumulative[starts + stride] - true_cumulative[starts])[ok]
    measured = (odometry_cumulative[starts + stride] - odometry_cumulative[starts])[ok]
    return measured - truth, truth


def trimmed_std(values) -> float:
    """The standard deviation of ``values`` within ``OUTLIER_Z`` robust std of their median."""
    values = np.asarray(values, dtype=float)
    return float(np.std(values[np.abs(values - np.median(values)) < OUTLIER_Z * robust_std(values)]))


def fit_travel_heading_offset(groundtruth, step_s: float = TRAVEL_STEP_S) -> float:
    """The angle [rad] between the ground truth's heading and the direction the robot moves in: the slope
    of the sideways displacement on the forward one over steps of ``step_s``, least squares beside a term in
    the heading change (a marker off the wheel axis moves sideways as the robot turns)."""
    times = np.arange(groundtruth[0, 0], groundtruth[-1, 0], step_s)
    poses, valid = groundtruth_at(groundtruth, times)
    heading = np.unwrap(poses[:, 2])
    turned = np.diff(heading)
    middle = heading[:-1] + 0.5 * turned
    step = np.diff(poses[:, :2], axis=0)
    forward = step[:, 0] * np.cos(middle) + step[:, 1] * np.sin(middle)
    sideways = step[:, 1] * np.cos(middle) - step[:, 0] * np.sin(middle)
    usable = valid[1:] & valid[:-1]
    design = np.column_stack([forward, turned])[usable]
    return float(np.linalg.lstsq(design, sideways[usable], rcond=None)[0][0])


def fit_odometry_offset(odometry, groundtruth) -> float:
    """The odometry clock offset [s] with the least trimmed spread of the 1 s heading-change error."""
    spreads = [trimmed_std(odometry_errors(odometry, groundtruth, offset, 1.0)[0][:, 1]) for offset in OFFSET_GRID_S]
    return float(OFFSET_GRID_S[int(np.argmin(spreads))])


def fit_odometry(samples: list[tuple[np.ndarray, np.ndarray]], windows_s=NOISE_WINDOWS_S) -> tuple[dict, dict]:
    """The ``RobotNoise`` scales and noise densities of speed and turn rate, and the error variance by window, from
    per-window samples: per window length in ``windows_s`` [s], ``(measured, truth)`` increments (W, 2) of forward
    distance and heading change."""
    measured, truth = samples[0]
    windows = np.asarray(windows_s, dtype=float)
    independent = np.array([len(m) for m, _ in samples]) * WINDOW_STEP_S / windows  # non-overlapping windows
    fields, variances = {}, []
    for column, rate in enumerate(("speed", "turn_rate")):
        error = measured[:, column] - truth[:, column]
        inlier = np.abs(error - np.median(error)) < 5 * robust_std(error)
        scale = float(measured[inlier, column] @ truth[inlier, column] / (truth[inlier, column] ** 2).sum())
        variances.append([np.var(m[:, column] / scale - t[:, column]) for m, t in samples])
        q, sigma, tau = fit_integrated_variance(windows, variances[-1], independent)
        fields |= {f"{rate}_scale": scale, f"{rate}_std": q, f"{rate}_bias_std": sigma}
        fields[f"{rate}_correlation_time_s"] = tau
    return fields, {f"{w:g}": list(map(float, pair)) for w, pair in zip(windows_s, zip(*variances))}


def fit_integrated_variance(windows_s, variances, independent) -> tuple[float, float, float]:
    """``(q, sigma, tau)`` of ``integrated_variance`` fitted to the variances over windows; each window's
    relative residual weighted by the square root of its ``independent`` samples (a variance estimate's
    relative error shrinks so); tau between the shortest window and 4 times the longest."""
    windows_s, variances = np.asarray(windows_s, dtype=float), np.asarray(variances, dtype=float)
    weights = np.sqrt(independent)

    def residual(parameters):
        return weights * (integrated_variance(windows_s, *parameters) / variances - 1.0)

    bounds = ([0.0, 0.0, windows_s[0]], [np.inf, np.inf, 4 * windows_s[-1]])
    start = [math.sqrt(variances[0] / windows_s[0]), math.sqrt(variances[-1]) / windows_s[-1], windows_s[-1]]
    q, sigma, tau = optimize.least_squares(residual, start, bounds=bounds).x
    return float(q), float(sigma), float(tau)


def landmark_errors(dataset: MRCLAMDataset, robot: int, offset_s: float = 0.0, odometry_offset_s: float = 0.0) -> dict:
    """Errors of ``robot``'s landmark measurements against the ground-truth geometry: arrays over the measurements
    with valid ground truth, ``time`` [s] (shifted by ``offset_s``), ``target`` (landmark subject), ``range`` and
    ``bearing`` (measured) [m, rad], ``range_error`` [m], ``bearing_error`` [rad], ``travelled`` [m] (forward progress
    by odometry shifted by ``odometry_offset_s``: the distance driven between two looks is the difference, the robots
    drive forward)."""
    rows, odometry = dataset.landmark_measurements[robot], dataset.odometry[robot]
    poses, valid = groundtruth_at(dataset.groundtruth[robot], rows[:, 0] + offset_s)
    offsets = dataset.landmarks[dataset.landmark_index(rows[:, 1])] - poses[:, :2]
    true_range = np.hypot(offsets[:, 0], offsets[:, 1])
    true_bearing = np.arctan2(offsets[:, 1], offsets[:, 0]) - poses[:, 2]
    return {
        "time": (rows[:, 0] + offset_s)[valid],
        "target": rows[valid, 1].astype(int),
        "range": rows[valid, 2],
        "bearing": rows[valid, 3],
        "range_error": (rows[:, 2] - true_range)[valid],
        "bearing_error": wrap_angle(rows[:, 3] - true_bearing)[valid],
        "travelled": held_integral(odometry[:, 0] + odometry_offset_s, odometry[:, 1], (rows[:, 0] + offset_s)[valid]),
    }


def fit_measurement_offset(dataset: MRCLAMDataset, robot: int) -> float:
    """The measurement clock offset [s] with the least robust spread of the bearing error."""
    spreads = [robust_std(landmark_errors(dataset, robot, offset)["bearing_error"]) for offset in OFFSET_GRID_S]
    return float(OFFSET_GRID_S[int(np.argmin(spreads))])


def look_pairs(measurement_errors: list[dict], same_target: bool, steps=PAIR_STEPS) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(first, second)``, into the robots' concatenated errors, of looks ``k`` looks apart within each robot's
    errors, for each ``k`` in ``steps``: at the same target (time order within each target: pairs from consecutive
    looks to far-apart ones) or, not ``same_target``, at different targets in time order (their covariance is the
    error the targets share)."""
    firsts, seconds, offset = [], [], 0
    for errors in measurement_errors:
        if same_target:
            order = np.lexsort((errors["time"], errors["target"]))
        else:
            order = np.argsort(errors["time"], kind="stable")
        targets = errors["target"][order]
        for step in steps:
            keep = (targets[step:] == targets[:-step]) == same_target
            firsts.append(order[:-step][keep] + offset)
            seconds.append(order[step:][keep] + offset)
        offset += len(errors["time"])
    return np.concatenate(firsts), np.concatenate(seconds)


def systematic_design(channel: str, range_m, bearing_rad) -> np.ndarray:
    """Columns of the systematic error model: range ``1, b, b^2, r, r b, r b^2``; bearing ``1, b, b^2, b^3``."""
    b = np.asarray(bearing_rad, dtype=float)
    image = np.column_stack([np.ones_like(b), b, b**2])
    if channel == "range":
        return np.column_stack([image, np.asarray(range_m, dtype=float)[:, None] * image])
    return np.column_stack([image, b**3])


def fit_systematic(error, design) -> np.ndarray:
    """Least-squares coefficients of ``error ~ design``, refitted once without the errors beyond 4 robust std."""
    coefficients = np.linalg.lstsq(design, error, rcond=None)[0]
    for _ in range(2):
        residual = error - design @ coefficients
        inlier = np.abs(residual - np.median(residual)) < OUTLIER_Z * robust_std(residual)
        coefficients = np.linalg.lstsq(design[inlier], error[inlier], rcond=None)[0]
    return coefficients


def fit_channel(channel: str, errors: dict, pairs, cross_pairs) -> tuple[dict, dict]:
    """The ``RobotNoise`` fields of one error channel (``range`` or ``bearing``) from ``landmark_errors`` arrays, and
    their diagnostics: systematic coefficients, white std (in range ``r``: ``a + c r^2``, a range read from the
    target's apparent size errs by ``r^2 / (f H)`` times its pixel error), the per-target and the shared bias's std
    and correlation length, outlier fraction; ``pairs`` are looks at the same target, ``cross_pairs`` at different
    ones."""
    range_m, time_s, travelled_m, targets = errors["range"], errors["time"], errors["travelled"], errors["target"]
    error, design = errors[f"{channel}_error"], systematic_design(channel, range_m, errors["bearing"])
    coefficients = fit_systematic(error, design)
    centred = error - design @ coefficients
    first, second = pairs
    short = time_s[second] - time_s[first] < SHORT_LAG_S
    differences, pair_range = (centred[second] - centred[first])[short], 0.5 * (range_m[first] + range_m[second])[short]
    if channel == "range":
        edges = np.quantile(pair_range, np.linspace(0, 1, RANGE_BINS + 1))
        bin_of = np.clip(np.searchsorted(edges, pair_range, side="right") - 1, 0, RANGE_BINS - 1)
        bins = [bin_of == b for b in range(RANGE_BINS) if np.sum(bin_of == b) >= MIN_BIN]
        centres = np.array([pair_range[b].mean() for b in bins])
        stds = np.array([robust_std(differences[b]) / math.sqrt(2) for b in bins])
        weights = np.array([b.sum() for b in bins], dtype=float)
        squares = centres**2
        slope, intercept = np.polyfit(squares, stds, 1, w=np.sqrt(weights))
        if slope < 0:
            slope, intercept = 0.0, float(np.average(stds, weights=weights))
        elif intercept < 0:  # the line through the origin, by weighted least squares
            slope, intercept = float(np.sum(weights * squares * stds) / np.sum(weights * squares**2)), 0.0
        range_bins = {"range_m": centres.tolist(), "white_std": stds.tolist(), "n": weights.astype(int).tolist()}
    else:
        slope, intercept, range_bins = 0.0, robust_std(differences) / math.sqrt(2), None
    white = intercept + slope * range_m**2
    inlier = np.abs(centred) < OUTLIER_Z * np.sqrt(white**2 + robust_std(centred) ** 2)
    travel_bins = covariance_by_travel(centred, pairs, inlier, travelled_m, targets)
    shared_bins = covariance_by_travel(centred, cross_pairs, inlier, travelled_m, targets)
    shared_variance, shared_length = _fit_exponential(shared_bins)
    own_bins = [  # a look pair at one target shares its bias and the shared one: take the shared part out
        (s, c - shared_variance * math.exp(-s / shared_length), n, m) for s, c, n, m in travel_bins
    ]
    bias_variance, correlation_length = _fit_exponential(own_bins)
    model_std = np.sqrt(white**2 + bias_variance + shared_variance)
    standardized = centred / model_std
    dof, _, t_scale = stats.t.fit(standardized[np.isfinite(standardized)], floc=0.0)
    unit = "m" if channel == "range" else "rad"
    fields = dict(zip(SYSTEMATIC_FIELDS[channel], coefficients.tolist())) | {
        f"{channel}_white_std_{unit}": float(intercept),
        f"{channel}_bias_std_{unit}": math.sqrt(bias_variance),
        f"{channel}_correlation_distance_m": float(correlation_length),
        f"{channel}_shared_std_{unit}": math.sqrt(shared_variance),
        f"{channel}_shared_correlation_distance_m": float(shared_length),
        f"{channel}_outlier_fraction": float(np.mean(np.abs(standardized) > OUTLIER_Z)),
    }
    if channel == "range":
        fields["range_white_std_per_m2"] = float(slope)
    return fields, {
        "n": int(len(error)),
        "n_short_lag_pairs": int(short.sum()),
        "robust_std_before_systematic": robust_std(error),
        "robust_std": robust_std(centred),
        "std": float(np.std(centred)),
        "student_t_dof": float(dof),
        "student_t_scale": float(t_scale),
        "white_std_by_range": range_bins,
        "covariance_by_travel": _bin_records(travel_bins),
        "shared_covariance_by_travel": _bin_records(shared_bins),
    }


def covariance_by_travel(centred, pairs, inlier, travelled_m, targets) -> list[tuple[float, float, int, int]]:
    """The mean product of the errors of look pairs (both inliers) in bins of the distance driven between
    them (``TRAVEL_EDGES_M``): ``(mean distance, covariance, pairs, independent looks)`` per bin with
    ``MIN_BIN`` pairs. Looks at one target within ``INDEPENDENT_CELL_M`` of travel count once (a parked
    robot repeats one error: its many pairs are one sample)."""
    first, second = pairs
    both = inlier[first] & inlier[second]
    driven = np.abs(travelled_m[second] - travelled_m[first])
    cells = targets[first] * 1_000_000 + np.floor(travelled_m[first] / INDEPENDENT_CELL_M).astype(int)
    bins = []
    for low, high in zip(TRAVEL_EDGES_M[:-1], TRAVEL_EDGES_M[1:]):
        chosen = both & (driven >= low) & (driven < high)
        if chosen.sum() >= MIN_BIN:
            covariance = float(np.mean(centred[first[chosen]] * centred[second[chosen]]))
            bins.append((float(driven[chosen].mean()), covariance, int(chosen.sum()), len(np.unique(cells[chosen]))))
    return bins


def _bin_records(bins) -> list[dict]:
    keys = ("travelled_m", "covariance", "n", "independent_looks")
    return [dict(zip(keys, values)) for values in bins]


def _fit_exponential(bins) -> tuple[float, float]:
    """``(sigma^2, l)`` of ``c(s) = sigma^2 exp(-s / l)`` fitted to ``(s, c, n, m)`` bins by least squares,
    each bin weighted by its ``m`` independent looks; ``(mean c, NO_DECAY_LENGTH_M)`` when the covariance
    does not decay."""
    if len(bins) < 2:
        return max(bins[0][1], 0.0) if bins else 0.0, NO_DECAY_LENGTH_M
    distances, covariances, _, counts = (np.array(column, dtype=float) for column in zip(*bins))
    start = (max(covariances[0], 1e-12), max(distances.mean(), 1e-3))
    try:
        (variance, length), _ = optimize.curve_fit(
            lambda s, v, ell: v * np.exp(-s / ell),
            distances,
            covariances,
            p0=start,
            sigma=1.0 / np.sqrt(counts),
            bounds=(0, np.inf),
        )
    except RuntimeError:  # no convergence: no decay to speak of
        return float(max(covariances.mean(), 0.0)), NO_DECAY_LENGTH_M
    return float(variance), float(min(length, NO_DECAY_LENGTH_M))


def fit_robot(
    odometry_samples, measurement_errors: list[dict], offsets: tuple[float, float, float]
) -> tuple[RobotNoise, dict]:
    """``RobotNoise`` (and its diagnostics) from odometry window samples and landmark errors of one robot
    or several (pooled: pairs are formed within each robot's errors); ``offsets``: odometry and measurement
    clock offsets [s] and the travel heading offset [rad]."""
    values, by_window = fit_odometry(odometry_samples)
    merged = {key: np.concatenate([errors[key] for errors in measurement_errors]) for key in measurement_errors[0]}
    pairs, cross_pairs = (look_pairs(measurement_errors, same_target) for same_target in (True, False))
    diagnostics = {"odometry_variance_by_window": by_window}
    for channel in ("range", "bearing"):
        fields, diagnostics[channel] = fit_channel(channel, merged, pairs, cross_pairs)
        values.update(fields)
    offset_fields = ("odometry_time_offset_s", "measurement_time_offset_s", "travel_heading_offset_rad")
    return RobotNoise(**dict(zip(offset_fields, offsets)), **values), diagnostics


def calibrate(dataset: MRCLAMDataset, command: str = "", progress: bool = False) -> tuple[NoiseModel, dict]:
    """Fit the noise model of every robot of ``dataset`` with ground truth, and the pooled model; ``command``: the
    command line that ran this, recorded in the model; ``progress``: a tqdm bar. Returns ``(model, errors)``: the model
    (its ``diagnostics`` hold the fits' evidence) and, per robot subject, the landmark errors at the fitted clock
    offset (for the residual plot); ``ValueError`` if no robot has ground truth and landmark measurements."""
    from tqdm.auto import tqdm

    robots = [r for r in dataset.robots if r in dataset.groundtruth and len(dataset.landmark_measurements[r])]
    if not robots:
        raise ValueError(f"{dataset.path}: no robot has both ground truth and landmark measurements to calibrate on")
    models, diagnostics, errors, samples, offsets = {}, {}, {}, [], []
    for robot in tqdm(robots, desc="calibrate", unit="robot", disable=not progress):
        odometry, groundtruth = dataset.odometry[robot], dataset.groundtruth[robot]
        robot_offsets = (
            fit_odometry_offset(odometry, groundtruth),
            fit_measurement_offset(dataset, robot),
            fit_travel_heading_offset(groundtruth),
        )
        windows = (odometry_errors(odometry, groundtruth, robot_offsets[0], window) for window in NOISE_WINDOWS_S)
        robot_samples = [(errors + truth, truth) for errors, truth in windows]  # (measured, truth) increments
        errors[robot] = landmark_errors(dataset, robot, robot_offsets[1], robot_offsets[0])
        models[robot], diagnostics[str(robot)] = fit_robot(robot_samples, [errors[robot]], robot_offsets)
        samples.append(robot_samples)
        offsets.append(robot_offsets)
    pooled_samples = [tuple(np.concatenate([s[w][i] for s in samples]) for i in (0, 1)) for w in range(len(samples[0]))]
    pooled_offsets = tuple(float(np.median(column)) for column in zip(*offsets))
    pooled, diagnostics["pooled"] = fit_robot(pooled_samples, [errors[r] for r in robots], pooled_offsets)
    return NoiseModel(
        robots=models,
        pooled=pooled,
        source=str(dataset.path),
        description=f"MRCLAM noise model fitted on {dataset.path.name} against its motion-capture ground truth",
        command=command,
        diagnostics=diagnostics,
    ), errors
