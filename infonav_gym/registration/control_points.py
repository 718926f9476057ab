"""ICP control points chosen by their information about the frame-to-frame motion (Section V-A).

The paper proposes choosing registration control points "by implicitly accounting for vehicle
position uncertainty", like the landmarks of Section III. Made precise here. A return ``p`` with
surface normal ``n`` (sensor frame) observes the small motion ``x = (t [m], w [rad])`` of its frame
through the point-to-plane residual ``n . (p + w x p + t - q)``, with Jacobian
``J = [n^T, (p x n)^T]``. With the prior motion covariance ``P`` (the odometry uncertainty,
``L L^T = P``), control points whose residual errors have covariance ``C`` bring the mutual
information ``0.5 ln det(I + L^T J^T C^-1 J L)`` [nats] about the motion: Section III's
``ic = im_post - im_prior`` (Eq. 3) for a linear Gaussian update. With independent errors of
standard deviation ``sigma`` this is ``0.5 ln det(I + P sum_i J_i^T J_i / sigma^2)``.

Error model of a control point (all from its own range image, before any correspondence): independent
errors of variance ``a_i = (2 sigma_r^2 + normal_i^2 + curvature_i^2 + footprint_i^2) * f_i``:

- range noise in both frames, ``sigma_r`` the scan's ``range_std_m`` (its LADAR's);
- ``normal_i``, the error of the matched point's normal when the ``NORMAL_SAMPLES`` nearest samples
  span one scan line (anisotropic sampling, e.g. grazing ground: the normal's angle error
  ``sqrt(2) sigma_r / width`` times the offset to the matched sample);
- ``curvature_i``, how far the point lies off the chords to its row and column neighbours along its
  normal (a bump or trunk between the target's samples puts the point off their tangent plane);
- ``footprint_i = FOOTPRINT_BIAS * range * pixel angle``: the matched sample is up to a pixel
  footprint away, and the target's surface and normal are only known at that resolution, so a far
  point's residual is biased in proportion to its footprint (measured on simulator pairs, seeds
  >= 1000: the point-to-plane residuals at the true motion grow from about 2 cm at 5-10 m to 5 cm at
  20-30 m);
- ``f_i = max(1, spread_i / structure_i)^2`` inflates all of it for ambiguous correspondences (the
  spread rule): ``spread_i = sqrt(J_i P J_i^T)`` is how far the prior motion uncertainty moves the
  point along its normal (a far point moves by ``|p| * angle``); ``structure_i`` is its distance to
  the nearest depth edge (a range step above ``DEPTH_JUMP_RATIO`` of the range, a pixel without a
  return, or the image border), ``(edge distance [pixel steps] + 1/2) * range * pixel angle``. A
  point whose spread reaches past the edge of its surface may be matched with another surface or
  with nothing, so its errors grow with the ratio; within its structure it is unaffected.
- a point without all four neighbours (edges, image border) has no usable normal: no information.

The ``"entropy"`` strategy splits the image into ``PATCH_SHAPE`` patches, orders each patch's
points by their error (most reliable first) in chunks of ``CHUNK_POINTS``, and adds chunks
greedily by mutual-information gain per point, each gain conditioned on everything chosen so far
(ground fixes z, roll and pitch; walls and trunks complement it with x, y and yaw), so the control
points spread over the patches that tell about different motions. For speed at most
``MAX_GREEDY_ROUNDS`` rounds are run: a round takes the next chunk of each of the
``ceil(k / (CHUNK_POINTS * MAX_GREEDY_ROUNDS))`` patches with the best gains.

The field's standard selectors, for comparison at the same budget:

- ``"random"``: drawn without replacement; ``"uniform"``: evenly spaced in row-major order (a grid over the image);
- ``"normal_space"``, normal-space sampling (Rusinkiewicz and Levoy, "Efficient variants of the ICP algorithm",
  3DIM 2001): the usable returns are bucketed by the direction of their normal (``NORMAL_SPACE_BINS``: bands of
  equal area on the sphere by the normal's z, times sectors of its azimuth) and drawn from the buckets in turn,
  one random return of every non-empty bucket per round, so that rare orientations (a wall in a field of ground)
  are as well represented as common ones;
- ``"covariance"``, covariance (stability) sampling (Gelfand, Ikemoto, Rusinkiewicz and Levoy, "Geometrically
  stable sampling for the ICP algorithm", 3DIM 2003; libpointmatcher's and PCL's ``CovarianceSampling``): each
  usable return constrains the motion by ``F = [(p - c) x n / L, n]`` (torque first, rotation about the
  centroid ``c``; torques normalised by ``L``, the mean distance of the points from ``c``, libpointmatcher's
  default); with ``C = sum F F^T = X diag(lambda) X^T``, returns are picked greedily for the eigen-direction
  whose summed squared constraint ``sum (F . x_j)^2`` over the picks is lowest, each time the untaken return
  that constrains it most, which balances the six directions and keeps the condition number of the picks'
  ``C`` low (what stability sampling minimises).

Ties (equal constraints or totals, within ``decisions.DECISION_RTOL``) go to the lower index, so a last-digit
difference between CPUs does not change the picks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_cdt, uniform_filter

from infonav_gym.compiled import kernel
from infonav_gym.decisions import DECISION_ATOL, DECISION_RTOL, descending_tied, top_k_tied
from infonav_gym.geometry import cross
from infonav_gym.information import information_gain_of_information, log_det_spd
from infonav_gym.sensors.ladar import LadarScan
from infonav_gym.sensors.pixel_grid import unit_directions

CONTROL_POINT_STRATEGIES = ("entropy", "random", "uniform", "normal_space", "covariance", "all")
NEEDS_NP_RANDOM = ("random", "normal_space")  # the strategies that draw
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
    """What each return tells about the motion of its frame, in row-major order of the returns.

    Attributes:
        points_m: the returns in the sensor frame (N, 3) [m].
        normals: unit surface normals facing the sensor (N, 3).
        jacobians: point-to-plane Jacobians ``[n^T, (p x n)^T]`` (N, 6).
        error_var_m2: variance ``a_i`` of the residual error (N,) [m^2]; ``inf`` if unusable.
        spread_m: how far the prior motion uncertainty moves each point along its normal, ``sqrt(J P J^T)`` (N,) [m].
        structure_m: distance to the nearest depth edge, image border or missing return (N,) [m].
        patch: index of each point's patch (N,), row-major over the ``PATCH_SHAPE`` grid.
        pose_covariance: the prior motion covariance ``P`` (6, 6) [m^2, rad^2].
    """

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
    if axis == 0:
        spacing[:-1] = step
        spacing[1:] = np.fmin(spacing[1:], step)
    else:
        spacing[:, :-1] = step
        spacing[:, 1:] = np.fmin(spacing[:, 1:], step)
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
    """Unit normals (rows, columns, 3) facing the sensor, from the ``NORMAL_WINDOW`` box means of the returns.

    Central differences of the box means; NaN or zero (no normal) on the image border and next to a
    pixel without a return.
    """
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
    """How far each pixel's point lies off the chords to its row and column neighbours, along its normal [m].

    (rows, columns); NaN without all four neighbours.
    """
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
    """Residual error [m] from a matched point's normal estimated from ``NORMAL_SAMPLES`` samples.

    The samples fill a disc of radius ``sqrt(NORMAL_SAMPLES * s_h * s_v / pi)``; narrower than the
    coarser spacing, they lie on one scan line and leave the normal undetermined (angle error 1 rad).
    The angle error times the typical offset to the matched sample ``(s_h + s_v) / 4`` is the error;
    ``range_std_m`` is the range noise [m].
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
    """Normals, Jacobians and the error model of every return (see the module docstring).

    Args:
        range_image: the range image with its pixel angles and range noise.
        pose_covariance: prior covariance (6, 6) of the frame's motion over (x, y, z [m], rotation
            about x, y, z [rad]); default ``DEFAULT_POSE_COVARIANCE`` (0.2 m and 2 degrees on every axis).
    """
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
    curvature = np.where(usable, curvature, 0.0)
    normals = np.where(usable[:, None], normals, 0.0)
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
    strategy: str = "entropy",
    *,
    pose_covariance=None,
    np_random: np.random.Generator | None = None,
) -> np.ndarray:
    """Indices of ``k`` control points among the returns of a range image.

    Args:
        range_image: the range image with its pixel geometry.
        k: how many control points, >= 1; ``"all"`` ignores it and returns every return.
        strategy: one of ``CONTROL_POINT_STRATEGIES``: ``"entropy"`` (the most information about
            the motion, see the module docstring), ``"random"`` (drawn without replacement from
            ``np_random``), ``"uniform"`` (evenly spaced in row-major order, about every
            ``N / k``-th return), ``"normal_space"`` (Rusinkiewicz and Levoy 2001, drawn from
            ``np_random``), ``"covariance"`` (Gelfand et al. 2003's stability sampling), ``"all"``.
        pose_covariance: prior covariance (6, 6) of the frame-to-frame motion over (x, y, z [m],
            rotation about x, y, z [rad]) for ``"entropy"``; default ``DEFAULT_POSE_COVARIANCE``.
        np_random: the generator of ``"random"`` and ``"normal_space"`` (required there, unused otherwise).

    Returns:
        Sorted unique int64 indices into the row-major list of returns (the rows of
        ``point_cloud(range_image)`` and ``range_image_to_points``), ``min(k, N)`` of them
        (all ``N`` for ``"all"``, or when ``k >= N``).

    Raises:
        ValueError: for an unknown strategy, ``k < 1``, a bad ``pose_covariance``, a range image
            without returns, ``"random"`` or ``"normal_space"`` without ``np_random``, or a range image
            with fewer than ``k`` returns that have a surface normal (``k < N``) for the strategies that
            need normals (``"entropy"``, ``"normal_space"``, ``"covariance"``).
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
    return _most_informative(geometry, k)


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
    """Covariance sampling's greedy loop: ``k`` distinct rows of ``squared`` (U, 6), each the strongest untaken row
    (by ``orders`` (6, U)) of the direction whose summed ``squared`` over the picks is lowest (ties within
    ``rtol`` / ``atol`` to the lower direction)."""
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
