"""ICP control points chosen by their information about the frame-to-frame motion (Section V-A).

A return ``p`` with normal ``n`` observes the small motion ``x = (t [m], w [rad])`` through the point-to-plane
residual ``n . (p + w x p + t - q)``, Jacobian ``J = [n^T, (p x n)^T]``. With the prior (odometry) covariance
``P`` and independent residual errors of variance ``a_i``, points bring ``0.5 ln det(I + P sum_i J_i^T J_i / a_i)``
[nats] about the motion: Eq. 3's ``ic`` for a linear Gaussian update.

Error model, from each point's own range image: ``a_i = (2 sigma_r^2 + normal_i^2 + curvature_i^2 +
footprint_i^2) * f_i``, with ``sigma_r`` the range noise of both frames; ``normal_i`` the matched normal's error
when its ``NORMAL_SAMPLES`` samples span one scan line; ``curvature_i`` the point's offset from the chords to its
neighbours; ``footprint_i = FOOTPRINT_BIAS * range * pixel angle`` (the matched sample is up to a footprint away;
fit on simulator pairs, seeds >= 1000); ``f_i = max(1, spread_i / structure_i)^2`` for ambiguous matches, where
``spread_i = sqrt(J_i P J_i^T)`` and ``structure_i`` is the distance to the nearest depth edge. A point without
all four neighbours has no normal and no information.

``"entropy"`` orders each ``PATCH_SHAPE`` patch's points by error in chunks of ``CHUNK_POINTS`` and adds chunks
greedily by gain per point, conditioned on what is chosen (ground fixes z, roll, pitch; walls x, y, yaw), in at
most ``MAX_GREEDY_ROUNDS`` rounds. ``"stratified_information"`` splits the returns with a normal, row-major, into
``k`` stretches of near-equal length and takes from each the return that alone tells most about the motion,
``0.5 ln(1 + J_i P J_i^T / a_i)``: spread over the image like ``"uniform"``, weighted by information. For
comparison: ``"random"``, ``"uniform"`` (row-major grid), ``"normal_space"`` (Rusinkiewicz and Levoy, 3DIM 2001:
one return per ``NORMAL_SPACE_BINS`` normal bucket per round) and ``"covariance"`` (Gelfand et al., 3DIM 2003, as
libpointmatcher's ``CovarianceSampling``: picks the return that constrains the least constrained eigen-direction of
``sum F F^T``, ``F = [(p - c) x n / L, n]``).
Ties within ``decisions.DECISION_RTOL`` go to the lower index, so CPUs agree.
The default, ``DEFAULT_CONTROL_POINT_STRATEGY``, is ``"random"``: on ``results/registration_recall.md`` neither
information-based selector matches its 5 cm recall at 10 % and 25 % of the returns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_cdt, uniform_filter

from infonav_gym.compiled import kernel
from infonav_gym.decisions import DECISION_ATOL, DECISION_RTOL, argmax_tied, descending_tied, top_k_tied
from infonav_gym.geometry import cross
from infonav_gym.information import information_gain_of_information, log_det_spd
from infonav_gym.sensors.ladar import LadarScan
from infonav_gym.sensors.pixel_grid import unit_directions

CONTROL_POINT_STRATEGIES = (
    "entropy",
    "stratified_information",
    "random",
    "uniform",
    "normal_space",
    "covariance",
    "all",
)
NEEDS_NP_RANDOM = ("random", "normal_space")  # the strategies that draw
# the best selector measured, by 5 cm recall at 10 % and 25 % of the returns (results/registration_recall.md)
DEFAULT_CONTROL_POINT_STRATEGY = "random"
PATCH_SHAPE = (8, 10)  # rows x columns of pixels per patch of the "entropy" strategy
NORMAL_SPACE_BINS = (6, 12)  # "normal_space" buckets: equal-area bands of the normal's z x sectors of its azimuth
CHUNK_POINTS = 5  # points a patch contributes per greedy pick
MAX_GREEDY_ROUNDS = 10  # greedy rounds; a round picks several patches' chunks when k needs more
NORMAL_WINDOW = 5  # side of the pixel box whose points are averaged before taking normals
NORMAL_SAMPLES = 10  # nearest samples a registration uses for the normal of a matched point
DEPTH_JUMP_RATIO = 0.2  # a range step above this fraction of the range separates two surfaces
FOOTPRINT_BIAS = 0.5  # residual bias per pixel footprint (range * pixel angle) [m/m] (fit on seeds >= 1000)
DEFAULT_POSE_STD = (0.2, 0.2, 0.2, math.radians(2.0), math.radians(2.0), math.radians(2.0))  # [m] x3, [rad] x3
DEFAULT_POSE_COVARIANCE = np.diag(np.square(DEFAULT_POSE_STD))  # over (x, y, z, rotation about x, y, z)


@dataclass(frozen=True)
class ControlPointGeometry:
    """Per return (row-major; N): points_m, sensor-facing normals, Jacobians ``[n^T, (p x n)^T]`` (N, 6), error
    variance ``a_i`` [m^2] (``inf`` if unusable), spread and structure [m], patch index; the prior ``P`` (6, 6)."""

    points_m: np.ndarray
    normals: np.ndarray
    jacobians: np.ndarray
    error_var_m2: np.ndarray
    spread_m: np.ndarray
    structure_m: np.ndarray
    patch: np.ndarray
    pose_covariance: np.ndarray

    @property
    def error_std_m(self) -> np.ndarray:
        """Total standard deviation of each point's residual error (N,) [m]."""
        return np.sqrt(self.error_var_m2)

    def mutual_information(self, indices) -> float:
        """Mutual information [nats] between the motion and the residuals of the returns ``indices``."""
        chosen = np.asarray(indices, dtype=np.int64)
        jacobians = self.jacobians[chosen] / np.sqrt(self.error_var_m2[chosen])[:, None]
        return information_gain_of_information(np.linalg.cholesky(self.pose_covariance), jacobians.T @ jacobians)


def check_pose_covariance(pose_covariance) -> np.ndarray:
    """``pose_covariance`` as a (6, 6) SPD float array (``DEFAULT_POSE_COVARIANCE`` for None), or ``ValueError``."""
    if pose_covariance is None:
        return DEFAULT_POSE_COVARIANCE.copy()
    matrix = np.asarray(pose_covariance, dtype=float)
    if matrix.shape != (6, 6):
        raise ValueError(
            "pose_covariance must be a (6, 6) covariance over (x, y, z [m], rotation about x, y, z [rad]), "
            f"got shape {matrix.shape}"
        )
    log_det_spd(matrix, "pose_covariance")
    return matrix


def _check_scan(range_image) -> None:
    if not isinstance(range_image, LadarScan):
        raise ValueError(f"range_image must be a LadarScan (from Ladar.scan), got {type(range_image).__name__}")
    shape = np.shape(range_image.ranges_m)
    if len(shape) != 2 or np.shape(range_image.no_return) != shape:
        raise ValueError(
            f"range_image ranges_m {shape} and no_return {np.shape(range_image.no_return)} "
            "must be the same (rows, columns) image"
        )
    if np.all(range_image.no_return):
        raise ValueError("range_image has no returns: nothing to choose control points from")


def _neighbour_spacing(grid: np.ndarray, axis: int) -> np.ndarray:
    """Per pixel, the distance to the nearer of its two neighbours along ``axis`` (NaN if neither has a return)."""
    difference = np.diff(grid, axis=axis)
    step = np.sqrt(np.einsum("...i,...i->...", difference, difference))
    spacing = np.full(grid.shape[:2], np.nan)
    along, step = np.moveaxis(spacing, axis, 0), np.moveaxis(step, axis, 0)  # views: writes reach spacing
    along[:-1] = step
    along[1:] = np.fmin(along[1:], step)
    return spacing


def _depth_edges(ranges: np.ndarray, returns: np.ndarray) -> np.ndarray:
    """Pixels with a return next to a range jump, a pixel without a return, or the image border."""
    padded = np.pad(np.where(returns, ranges, np.nan), 1, constant_values=np.nan)
    centre = padded[1:-1, 1:-1]
    edge = np.zeros(ranges.shape, dtype=bool)
    for neighbour in (padded[:-2, 1:-1], padded[2:, 1:-1], padded[1:-1, :-2], padded[1:-1, 2:]):
        with np.errstate(invalid="ignore"):
            edge |= ~(np.abs(neighbour - centre) <= DEPTH_JUMP_RATIO * np.fmin(neighbour, centre))
    return edge & returns


def _smoothed_normals(grid: np.ndarray, returns: np.ndarray) -> np.ndarray:
    """Unit normals (rows, columns, 3) facing the sensor, by central differences of ``NORMAL_WINDOW`` box means;
    NaN or zero where there is none (border, next to a missing return)."""
    weights = uniform_filter(returns.astype(float), NORMAL_WINDOW, mode="constant")
    sums = uniform_filter(np.where(returns[..., None], grid, 0.0), (NORMAL_WINDOW, NORMAL_WINDOW, 1), mode="constant")
    smooth = sums / np.maximum(weights, 1e-12)[..., None]
    smooth[~returns] = np.nan
    along_row = np.zeros_like(smooth)
    along_row[:, 1:-1] = smooth[:, 2:] - smooth[:, :-2]
    along_column = np.zeros_like(smooth)
    along_column[1:-1] = smooth[2:] - smooth[:-2]
    normals = cross(along_row, along_column)
    length = np.sqrt(np.einsum("...i,...i->...", normals, normals))
    facing_away = np.einsum("...i,...i->...", normals, grid) > 0
    scale = np.where(facing_away, -1.0, 1.0) / np.where(length > 0, length, np.inf)  # NaN where no normal
    return normals * scale[..., None]


def _curvature(grid: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Per pixel, the point's distance along its normal from the chords to its neighbours [m]; NaN at the border."""
    curvature = np.full(grid.shape[:2], np.nan)
    centre, normal = grid[1:-1, 1:-1], normals[1:-1, 1:-1]
    row_chord = (grid[1:-1, :-2] + grid[1:-1, 2:]) / 2 - centre
    column_chord = (grid[:-2, 1:-1] + grid[2:, 1:-1]) / 2 - centre
    curvature[1:-1, 1:-1] = np.fmax(
        np.abs(np.einsum("...i,...i->...", row_chord, normal)),
        np.abs(np.einsum("...i,...i->...", column_chord, normal)),
    )
    return curvature


def _normal_error(row_spacing: np.ndarray, column_spacing: np.ndarray, range_std_m: float) -> np.ndarray:
    """Residual error [m] of a normal from ``NORMAL_SAMPLES`` samples: angle error times the offset ``(s_h + s_v) / 4``.

    The samples fill a disc of radius ``sqrt(NORMAL_SAMPLES * s_h * s_v / pi)``; narrower than the coarser
    spacing, they lie on one scan line and the angle is undetermined (1 rad).
    """
    radius = np.sqrt(NORMAL_SAMPLES * row_spacing * column_spacing / math.pi)
    determined = radius >= np.fmax(row_spacing, column_spacing)
    width = np.where(determined, radius, 1.0)
    angle = np.where(determined, np.minimum(1.0, math.sqrt(2.0) * range_std_m / width), 1.0)
    return angle * (row_spacing + column_spacing) / 4


def _pixel_angle(range_image: LadarScan) -> float:
    """Mean angular size of a pixel [rad] (the one step available for a single row or column)."""
    steps = [
        float(np.abs(np.diff(angles)).mean())
        for angles in (np.asarray(range_image.azimuth_rad), np.asarray(range_image.elevation_rad))
        if angles.size > 1
    ]
    return float(np.mean(steps)) if steps else 1e-3


def control_point_geometry(range_image: LadarScan, pose_covariance=None) -> ControlPointGeometry:
    """Normals, Jacobians and the error model of every return; ``pose_covariance`` (6, 6) over (x, y, z [m],
    rotations [rad]), default ``DEFAULT_POSE_COVARIANCE``."""
    _check_scan(range_image)
    return _geometry(range_image, check_pose_covariance(pose_covariance))


def _geometry(range_image: LadarScan, covariance: np.ndarray) -> ControlPointGeometry:
    returns = ~np.asarray(range_image.no_return, dtype=bool)
    ranges = np.asarray(range_image.ranges_m, dtype=float)
    grid = unit_directions(range_image.azimuth_rad, range_image.elevation_rad) * ranges[..., None]
    grid[~returns] = np.nan
    points = grid[returns]

    normal_grid = _smoothed_normals(grid, returns)
    curvature = _curvature(grid, normal_grid)[returns]
    normals = normal_grid[returns]
    row_spacing = _neighbour_spacing(grid, axis=1)[returns]
    column_spacing = _neighbour_spacing(grid, axis=0)[returns]
    edge_distance = distance_transform_cdt(~_depth_edges(ranges, returns), metric="taxicab")[returns]
    structure = (edge_distance + 0.5) * ranges[returns] * _pixel_angle(range_image)

    usable = np.isfinite(curvature) & np.isfinite(normals[:, 0]) & (np.abs(normals).sum(axis=1) > 0.5)
    curvature, normals = np.where(usable, curvature, 0.0), np.where(usable[:, None], normals, 0.0)
    jacobians = np.concatenate([normals, cross(points, normals)], axis=1)
    spread = np.sqrt(np.einsum("ni,ni->n", jacobians @ covariance, jacobians))
    ambiguity = np.maximum(1.0, spread / structure) ** 2
    range_std_m = range_image.range_std_m
    normal_error = np.where(usable, _normal_error(row_spacing, column_spacing, range_std_m), 0.0)
    footprint = FOOTPRINT_BIAS * ranges[returns] * _pixel_angle(range_image)
    variance = (2.0 * range_std_m**2 + normal_error**2 + curvature**2 + footprint**2) * ambiguity
    rows, columns = np.nonzero(returns)
    columns_of_patches = -(-ranges.shape[1] // PATCH_SHAPE[1])
    return ControlPointGeometry(
        points_m=points,
        normals=normals,
        jacobians=jacobians,
        error_var_m2=np.where(usable, variance, np.inf),
        spread_m=spread,
        structure_m=structure,
        patch=(rows // PATCH_SHAPE[0]) * columns_of_patches + columns // PATCH_SHAPE[1],
        pose_covariance=covariance,
    )


def _check_k(k) -> int:
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ValueError(f"k (the number of control points) must be an integer >= 1, got {k!r}")
    return int(k)


def select_control_points(
    range_image: LadarScan,
    k: int,
    strategy: str = DEFAULT_CONTROL_POINT_STRATEGY,
    *,
    pose_covariance=None,
    np_random: np.random.Generator | None = None,
) -> np.ndarray:
    """Indices of ``k`` control points among the returns of a range image.

    Args:
        range_image: the range image.
        k: how many, >= 1 (``"all"`` ignores it).
        strategy: one of ``CONTROL_POINT_STRATEGIES`` (module docstring); default
            ``DEFAULT_CONTROL_POINT_STRATEGY``, which needs ``np_random``.
        pose_covariance: (6, 6) prior motion covariance for ``"entropy"`` and ``"stratified_information"``;
            default ``DEFAULT_POSE_COVARIANCE``.
        np_random: the generator of ``NEEDS_NP_RANDOM``'s strategies (required there).

    Returns:
        Sorted int64 indices into the row-major returns (``range_image_to_points``' rows), ``min(k, N)`` of them.

    Raises:
        ValueError: for a bad strategy, ``k``, ``pose_covariance`` or scan, a missing ``np_random``, or fewer
            than ``k`` returns with a normal for the strategies that need normals.
    """
    if strategy not in CONTROL_POINT_STRATEGIES:
        raise ValueError(f"unknown control point strategy {strategy!r}; expected one of {CONTROL_POINT_STRATEGIES}")
    k = _check_k(k)
    _check_scan(range_image)
    covariance = check_pose_covariance(pose_covariance)
    if strategy in NEEDS_NP_RANDOM and np_random is None:
        raise ValueError(f"strategy {strategy!r} needs np_random (a numpy Generator) to draw the control points")
    count = int(np.count_nonzero(~np.asarray(range_image.no_return, dtype=bool)))
    if strategy == "all" or k >= count:
        return np.arange(count, dtype=np.int64)
    if strategy == "uniform":
        return np.floor((np.arange(k) + 0.5) * (count / k)).astype(np.int64)
    if strategy == "random":
        return np.sort(np_random.choice(count, size=k, replace=False)).astype(np.int64)
    geometry = _geometry(range_image, covariance)
    usable = np.flatnonzero(np.isfinite(geometry.error_var_m2))
    if len(usable) < k:
        raise ValueError(
            f"range_image has {len(usable)} returns with a surface normal (all four neighbours on one surface), "
            f"fewer than k = {k}: strategy {strategy!r} cannot choose k control points"
        )
    if strategy == "normal_space":
        return np.sort(usable[_normal_space_picks(geometry.normals[usable], k, np_random)])
    if strategy == "covariance":
        return np.sort(usable[_stability_picks(geometry.points_m[usable], geometry.normals[usable], k)])
    if strategy == "stratified_information":
        return np.sort(usable[_best_of_each_stretch(single_point_information(geometry)[usable], k)])
    return _most_informative(geometry, k)


def single_point_information(geometry: ControlPointGeometry) -> np.ndarray:
    """What each return alone tells about the motion: ``0.5 ln(1 + J_i P J_i^T / a_i)`` [nats] (N,), 0 if unusable."""
    return 0.5 * np.log1p(geometry.spread_m**2 / geometry.error_var_m2)


def stretches(count: int, k: int) -> np.ndarray:
    """``k`` runs of consecutive indices ``0 .. count - 1``, run ``j`` from ``floor(j count / k)`` on, as a (k, m)
    table padded with -1 (``m`` the longest run)."""
    bounds = np.floor(np.arange(k + 1) * (count / k)).astype(np.int64)
    sizes = np.diff(bounds)
    place = np.arange(int(sizes.max()))
    return np.where(place < sizes[:, None], bounds[:-1, None] + place, -1)


def _best_of_each_stretch(score: np.ndarray, k: int) -> np.ndarray:
    """The highest-``score`` row of each of ``stretches(len(score), k)`` (ties within ``DECISION_RTOL`` to the
    lower index)."""
    table = stretches(len(score), k)
    values = np.where(table >= 0, score[np.maximum(table, 0)], -np.inf)
    return table[np.arange(k), argmax_tied(values, axis=1)]


def _normal_space_picks(normals: np.ndarray, k: int, np_random: np.random.Generator) -> np.ndarray:
    """``k`` rows of ``normals`` (U, 3) drawn from their ``NORMAL_SPACE_BINS`` buckets in turn (random within each)."""
    bands, sectors = NORMAL_SPACE_BINS
    band = np.minimum(((normals[:, 2] + 1.0) / 2.0 * bands).astype(np.int64), bands - 1)  # z: equal-area bands
    azimuth = np.arctan2(normals[:, 1], normals[:, 0])
    sector = np.minimum(((azimuth + math.pi) / (2 * math.pi) * sectors).astype(np.int64), sectors - 1)
    bucket = band * sectors + sector
    shuffled = np_random.permutation(len(normals))
    grouped = shuffled[np.argsort(bucket[shuffled], kind="stable")]  # by bucket, random within each
    grouped_bucket = bucket[grouped]
    turn = np.arange(len(grouped)) - np.searchsorted(grouped_bucket, grouped_bucket)  # its place in its bucket
    return grouped[np.lexsort((grouped_bucket, turn))[:k]]  # every bucket's first, then every second, ...


def _stability_picks(points: np.ndarray, normals: np.ndarray, k: int) -> np.ndarray:
    """``k`` rows of ``points`` / ``normals`` (U, 3) by Gelfand et al.'s covariance sampling (the module docstring)."""
    centred = points - points.mean(axis=0)
    scale = float(np.mean(np.sqrt(np.einsum("ni,ni->n", centred, centred))))
    constraints = np.concatenate([cross(centred, normals) / max(scale, 1e-12), normals], axis=1)  # (U, 6)
    _, directions = np.linalg.eigh(constraints.T @ constraints)
    squared = (constraints @ directions) ** 2  # each return's constraint on each eigen-direction
    orders = np.stack([descending_tied(column) for column in squared.T])  # (6, U), strongest first
    return balanced_picks(squared, orders, k, DECISION_RTOL, DECISION_ATOL)


@kernel
def balanced_picks(squared, orders, k, rtol, atol):
    """Covariance sampling's greedy loop: ``k`` rows of ``squared`` (U, 6), each the strongest untaken one (by
    ``orders`` (6, U)) of the least constrained direction (ties within ``rtol`` / ``atol`` to the lower)."""
    n_points, n_directions = squared.shape
    taken = np.zeros(n_points, dtype=np.bool_)
    position = np.zeros(n_directions, dtype=np.int64)
    totals = np.zeros(n_directions)
    picks = np.empty(k, dtype=np.int64)
    for pick in range(k):
        least = totals.min()
        direction = 0
        while totals[direction] > least + rtol * abs(least) + atol:
            direction += 1
        while taken[orders[direction, position[direction]]]:
            position[direction] += 1
        point = orders[direction, position[direction]]
        taken[point] = True
        picks[pick] = point
        for column in range(n_directions):
            totals[column] += squared[point, column]
    return picks


def _most_informative(geometry: ControlPointGeometry, k: int) -> np.ndarray:
    """Greedy chunks of the most reliable points of each patch, by mutual-information gain per point."""
    usable = np.isfinite(geometry.error_var_m2)
    error = geometry.error_std_m
    reliability = np.where(usable, error / (1.0 + np.where(usable, error, 0.0)), 1.0)  # in [0, 1)
    order = np.argsort(geometry.patch + reliability / 2, kind="stable")  # by patch, most reliable first
    patch_of = geometry.patch[order]
    patches = int(patch_of[-1]) + 1
    members = np.bincount(patch_of, minlength=patches)
    first = np.concatenate([[0], np.cumsum(members)[:-1]])
    rank = np.arange(len(order)) - first[patch_of]
    chunks = -(-members // CHUNK_POINTS)
    slots = int(chunks.max())

    # whitened Jacobians J L / sqrt(a), padded to (patch, chunk, point in chunk)
    position = patch_of * (slots * CHUNK_POINTS) + rank
    rows = np.zeros((patches * slots * CHUNK_POINTS, 6))
    whitened = geometry.jacobians @ np.linalg.cholesky(geometry.pose_covariance)
    rows[position] = (whitened * np.where(usable, 1.0 / np.where(usable, error, 1.0), 0.0)[:, None])[order]
    rows = rows.reshape(patches, slots, CHUNK_POINTS, 6)
    # a patch's information when its first j + 1 chunks are taken: running sums of (J L)^T (J L) / a
    information = np.cumsum(np.swapaxes(rows, -1, -2) @ rows, axis=1)
    size = np.cumsum(
        np.bincount(patch_of * slots + rank // CHUNK_POINTS, minlength=patches * slots).reshape(patches, slots), axis=1
    )

    batch = max(1, -(-k // (CHUNK_POINTS * MAX_GREEDY_ROUNDS)))
    taken_chunks = np.zeros(patches, dtype=np.int64)
    total = np.eye(6)  # I + the whitened information chosen so far
    total_log_det = 0.0
    all_patches = np.arange(patches)
    taken = 0
    while taken < k:
        column = np.minimum(taken_chunks, slots - 1)
        previous = np.where(taken_chunks[:, None, None] > 0, information[all_patches, column - 1], 0.0)
        added_information = information[all_patches, column] - previous
        added = size[all_patches, column] - np.where(taken_chunks > 0, size[all_patches, column - 1], 0)
        gain = (np.linalg.slogdet(total + added_information)[1] - total_log_det) / np.maximum(added, 1)
        gain[taken_chunks >= chunks] = -np.inf
        best = top_k_tied(gain, batch)
        best = best[gain[best] > -np.inf]
        best = best[taken + np.cumsum(added[best]) - added[best] < k]  # stop once k points are taken
        taken += int(added[best].sum())
        total += added_information[best].sum(axis=0)
        taken_chunks[best] += 1
        last = best[-1]
        total_log_det = np.linalg.slogdet(total)[1]
    limit = np.minimum(taken_chunks * CHUNK_POINTS, members)
    limit[last] -= taken - k  # the last chunk may overshoot k: keep its most reliable points
    return np.sort(order[rank < limit[patch_of]]).astype(np.int64)
