"""Iterative closest point (ICP) registration of two 3D point sets (the paper's Section V).

As the paper summarises [its ref. 7]: from an initial motion, pair each source point with the
closest target point under the current transform, compute the incremental motion that best
aligns the pairs, apply it, and repeat until the increment falls below a threshold.

Correspondences come from a ``KdTree`` (``kdtree`` module) built once per call on the target. A pair
is an inlier when it is closer than ``max_correspondence_distance`` and passes a robust test:
with ``d`` the distances of the pairs inside that limit, pairs beyond
``median(d) + ROBUST_K * 1.4826 * MAD(d)`` are dropped (``1.4826 * MAD`` estimates a standard
deviation without being moved by the outliers it is meant to find; ``ROBUST_K = 3``). A few
junk points thus cannot pull the solution, while an inlier distribution (the Maxwell-like
distances of well-aligned noisy points) loses well under 1% of its pairs.

The increment is solved in closed form on the inliers: ``point_to_point`` by the SVD of the
cross-covariance (Kabsch / Umeyama without scale, with the reflection fix); ``point_to_plane``
by the small-angle linearisation ``n . (p + w x p + v - q)`` in least squares, on target
normals estimated once per call by PCA of each target point's ``normals.NORMAL_NEIGHBOURS`` nearest
neighbours (their sign does not matter), the angle ``w`` then applied as an exact rotation;
``gicp`` by one Gauss-Newton step of generalized ICP (``gicp`` module) on per-point covariances of both
clouds (passed in, computed once per cloud, or computed here for each point the first time a pair uses
it: the same covariances, for the 70-90 % of the points that take part). For ``point_to_plane`` and
``gicp`` a ``robust_kernel`` (``robust_kernels`` module) reweights the inlier pairs by their residuals
in every step (iteratively reweighted least squares).

Acceleration (after Besl & McKay, 1992): point-to-point ICP creeps along a steady direction,
each step a fraction ``rho`` of the last. When a step continues the previous one (their 6-vectors,
rotation vector [rad] and translation, within ``STEADY_ANGLE_DEG``) and shrinks, it is applied
scaled by ``1 / (1 - rho)`` (the geometric series' sum, at most ``MAX_EXTRAPOLATION``); an
overshoot is undone by the next closest-point step. On a LADAR frame pair this cuts 29 steps to 12.

Coarse to fine: most of the time goes into k-d tree queries, and the early steps, which are large,
need no more than a fraction of the points to point the right way. So a source of at least
``COARSE_STRIDE * COARSE_MIN_POINTS`` points is first registered on the fixed subsample of every
``COARSE_STRIDE``-th point (in a LADAR frame's row-major order, every 4th column of each scan line),
with the same pairing, robust test and acceleration. That coarse phase ends at the first step
smaller (rotation [rad] and translation, as in the convergence rule) than the subsample's
resolution, the standard error ``rms / sqrt(pairs)`` of its inlier pair distances, but at least
``tolerance``: a smaller step on the subsample would chase its noise. That step is not applied; the
full set takes over from the same transform, reusing the subsample's cached closest points, and
iterates to the convergence rule below, so the final transform, ``rmse`` and ``fitness`` are those of
all points. On a 4,900-point LADAR frame pair (warm start) this halves the time.

Convergence rule: stop as soon as the transform moved by less than ``tolerance`` -- rotation
angle below ``tolerance`` [rad] *and* translation norm below ``tolerance`` [length unit] -- over
the last increment, or over the last two increments together. The first is a fixed point; the
second a two-cycle, where the pairing flips between two sets and the transform between two
states that close together (point-to-plane, and the robust test, can enter one, since neither
decreases one cost monotonically); the later state is returned. ``converged`` is then True and
``iterations`` counts the increments applied in both phases, that one included (so identical
clouds converge in exactly 1: their coarse step is below ``tolerance`` and not applied).
Otherwise stop after ``max_iterations`` with ``converged=False``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from infonav_gym.compiled import contiguous
from infonav_gym.geometry import rotation_angle
from infonav_gym.registration.gicp import (
    GICP_NEIGHBOURS,
    check_neighbours,
    gicp_step,
    pair_information,
    plane_covariances,
)
from infonav_gym.registration.kdtree import KdTree, check_points
from infonav_gym.registration.normals import estimate_normals
from infonav_gym.registration.robust_kernels import check_robust_kernel, robust_weights

METHODS = ("point_to_point", "point_to_plane", "gicp")
DEFAULT_KERNEL_SCALE = 0.1  # robust kernel scale [length unit]
ROBUST_K = 3.0  # robust scale multiples beyond the median pair distance that mark an outlier
MAD_TO_STD = 1.4826  # standard deviation of a Gaussian per unit median absolute deviation


@dataclass(frozen=True)
class RegistrationResult:
    """The outcome of ``icp``.

    Attributes:
        transform: (4, 4) rigid transform mapping source points onto the target: ``target ~ R @ source + t``.
        rmse: root mean square distance of the inlier pairs under ``transform`` [same unit as the points];
            ``inf`` when fewer than 3 pairs are inliers.
        fitness: inlier pairs under ``transform`` as a fraction of the source points, in [0, 1].
        iterations: incremental motions applied.
        converged: whether the last increment fell below ``tolerance`` before ``max_iterations``.
    """

    transform: np.ndarray
    rmse: float
    fitness: float
    iterations: int
    converged: bool


def check_rigid_transform(matrix, name: str, atol: float = 1e-6) -> np.ndarray:
    """``matrix`` as a float (4, 4) rigid transform (rotation, translation, last row 0 0 0 1), or ``ValueError``."""
    array = np.asarray(matrix, dtype=float)
    if array.shape != (4, 4):
        raise ValueError(f"{name} must be a (4, 4) rigid transform, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite, got {array.tolist()}")
    if not np.allclose(array[3], [0.0, 0.0, 0.0, 1.0], rtol=0.0, atol=atol):
        raise ValueError(f"{name} must have last row [0, 0, 0, 1], got {array[3].tolist()}")
    rotation = array[:3, :3]
    if not np.allclose(rotation.T @ rotation, np.eye(3), rtol=0.0, atol=atol) or np.linalg.det(rotation) < 0:
        raise ValueError(
            f"{name} must be rigid: its upper-left 3 x 3 block must be a rotation (orthonormal, det +1), "
            f"got {rotation.tolist()} with det {np.linalg.det(rotation):.6g}"
        )
    return array


def check_kernel_method(robust_kernel: str | None, method: str) -> None:
    """``ValueError`` for a robust kernel with ``point_to_point``, which has no residual scale for it to weigh."""
    if robust_kernel is not None and method == "point_to_point":
        raise ValueError(f"robust_kernel {robust_kernel!r} applies to method point_to_plane or gicp, not {method}")


def _check_settings(max_iterations, tolerance, max_correspondence_distance, method) -> float:
    """``ValueError`` for a bad setting; returns the correspondence distance limit (``inf`` for none)."""
    if method not in METHODS:
        raise ValueError(f"unknown ICP method {method!r}; expected one of {', '.join(METHODS)}")
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, (int, np.integer)) or max_iterations < 1:
        raise ValueError(f"max_iterations must be a positive integer, got {max_iterations!r}")
    if isinstance(tolerance, bool) or not (isinstance(tolerance, (int, float, np.number)) and tolerance > 0):
        raise ValueError(f"tolerance must be a positive number, got {tolerance!r}")
    if max_correspondence_distance is None:
        return math.inf
    limit = max_correspondence_distance
    if isinstance(limit, bool) or not (isinstance(limit, (int, float, np.number)) and limit > 0):
        raise ValueError(f"max_correspondence_distance must be positive or None (no limit), got {limit!r}")
    return float(limit)


def rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """Axis times angle [rad] of a 3 x 3 rotation matrix with angle below pi."""
    axis = np.array([rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0], rotation[1, 0] - rotation[0, 1]])
    angle = rotation_angle(rotation)
    sine = math.sin(angle)
    return axis * (0.5 if sine < 1e-12 else 0.5 * angle / sine)


def rotation_from_vector(rotation_vector: np.ndarray) -> np.ndarray:
    """The rotation matrix of ``rotation_vector`` (axis times angle [rad]), by Rodrigues' formula."""
    angle = float(np.linalg.norm(rotation_vector))
    if angle == 0.0:
        return np.eye(3)
    x, y, z = rotation_vector / angle
    cross = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * cross + (1.0 - math.cos(angle)) * (cross @ cross)


class _Covariances:
    """The GICP covariances of a cloud: ``given`` (checked to be (N, 3, 3) and finite), or computed for each point
    the first time a pair uses it (in a LADAR frame pair about 90 % of the source points and 70 % of the target's)."""

    def __init__(self, points: np.ndarray, given, neighbours, name: str, tree: KdTree | None = None):
        count = points.shape[0]
        self.missing = np.zeros(count, dtype=bool)
        if given is not None:
            self.values = contiguous(np.asarray(given, dtype=float))
            if self.values.shape != (count, 3, 3) or not np.all(np.isfinite(self.values)):
                raise ValueError(
                    f"{name}_covariances must be finite, one (3, 3) covariance per {name} point: shape "
                    f"{(count, 3, 3)}, got {self.values.shape}"
                )
            return
        self.neighbours = check_neighbours(neighbours, count, name)
        self.tree = KdTree(points) if tree is None else tree
        self.values, self.missing[:] = np.empty((count, 3, 3)), True

    def of(self, index: np.ndarray) -> np.ndarray:
        """All covariances (N, 3, 3), those of the points ``index`` computed."""
        needed = index[self.missing[index]]
        if needed.size:
            new = np.unique(needed)
            self.values[new] = plane_covariances(self.tree.data, self.neighbours, self.tree, new)
            self.missing[new] = False
        return self.values


class _ClosestPoints:
    """Closest target point of each moved source point, re-queried only where it may have changed.

    A query asks for the two closest target points, at distances ``d1 <= d2``. While a point stays
    within ``(d2 - d1) / 2`` of where it was queried, the first is still its closest (triangle
    inequality), so only the points that moved farther are queried again: near convergence almost
    none. The result equals a full query every time (up to exact ties). With a distance limit,
    ``SEARCH_BOUND_FACTOR`` times it stands in for a farther ``d2``, and a point with nothing inside
    that bound stays unmatched while it moves less than bound - limit.
    The cache covers all source points; ``update`` serves a basic slice of them (the coarse subsample),
    whose entries the full set later reuses.
    """

    SEARCH_BOUND_FACTOR = 1.5

    def __init__(self, tree: KdTree, count: int, limit: float):
        self.tree, self.limit = tree, limit
        self.bound = limit * self.SEARCH_BOUND_FACTOR
        self.unmatched_safe = self.bound - limit if math.isfinite(limit) else 0.0
        self.index = np.full(count, tree.n)
        self.closest = np.full((count, 3), np.inf)  # coordinates of the closest target point; inf when unmatched
        self.anchor = np.zeros((count, 3))
        self.safe_squared = np.full(count, -1.0)  # squared safe radius; negative forces the first query

    def update(self, moved: np.ndarray, rows: slice = slice(None)) -> np.ndarray:
        """Distances (N,) from ``moved`` (N, 3), the source points ``rows`` (a slice) moved, to their closest target
        points (``self.index[rows]``, ``self.closest[rows]``), ``inf`` where the closest is at or beyond the distance
        limit (its index then meaningless)."""
        index, closest, anchor = self.index[rows], self.closest[rows], self.anchor[rows]  # views: writes persist
        safe_squared = self.safe_squared[rows]
        drift = moved - anchor
        stale = np.flatnonzero(np.einsum("ij,ij->i", drift, drift) >= safe_squared)
        if stale.size:
            moved_stale = np.take(moved, stale, axis=0)
            distance, nearest = self.tree.query(moved_stale, k=2)
            first, second = distance[:, 0], np.minimum(distance[:, 1], self.bound)
            found = first < self.bound
            safe = np.where(found, 0.5 * (second - first), self.unmatched_safe)
            index[stale], anchor[stale], safe_squared[stale] = nearest[:, 0], moved_stale, safe**2
            closest[stale] = np.inf
            closest[stale[found]] = np.take(self.tree.data, nearest[found, 0], axis=0)
        offset = moved - closest
        distance = np.sqrt(np.einsum("ij,ij->i", offset, offset))
        distance[distance >= self.limit] = np.inf
        return distance


def _median(values: np.ndarray) -> float:
    """Median of a non-empty 1D array (``np.median`` without its overhead)."""
    half = values.size // 2
    if values.size % 2:
        return float(np.partition(values, half)[half])
    lower, upper = np.partition(values, (half - 1, half))[half - 1 : half + 1]
    return 0.5 * (float(lower) + float(upper))


def _inliers(distance: np.ndarray) -> np.ndarray:
    """Indices of the pairs inside the distance limit (finite ``distance``) that pass the robust MAD test."""
    candidates = np.flatnonzero(np.isfinite(distance))
    if candidates.size == 0:
        return candidates
    inside = distance[candidates]
    median = _median(inside)
    threshold = median + ROBUST_K * MAD_TO_STD * _median(np.abs(inside - median))
    return candidates[inside <= threshold]


def _point_to_point(moved: np.ndarray, matched: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and translation minimising ``sum |R p + t - q|^2`` (Kabsch, reflection-safe)."""
    count = moved.shape[0]
    weights = np.full(count, 1.0 / count)
    moved_mean, matched_mean = weights @ moved, weights @ matched  # faster than mean(axis=0)
    cross_covariance = moved.T @ matched - count * np.outer(moved_mean, matched_mean)
    u, _, vt = np.linalg.svd(cross_covariance)
    rotation = vt.T @ u.T
    if np.linalg.det(rotation) < 0:  # best proper rotation: flip the axis of least singular value
        vt[2] = -vt[2]
        rotation = vt.T @ u.T
    return rotation, matched_mean - rotation @ moved_mean


def _point_to_plane(
    moved: np.ndarray, matched: np.ndarray, normals: np.ndarray, robust_kernel=None, kernel_scale=1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and translation minimising ``sum rho(n . (R p + t - q))``, linearised in the rotation.

    ``rho`` is the square, or ``robust_kernel`` by one IRLS step. The rotation is about the centroid of
    ``moved`` (better conditioned than about the origin).
    """
    centre = np.full(moved.shape[0], 1.0 / moved.shape[0]) @ moved  # faster than mean(axis=0)
    arm = moved - centre
    residual = np.einsum("ij,ij->i", moved - matched, normals)
    jacobian = np.hstack([np.cross(arm, normals), normals])
    weighted = jacobian
    if robust_kernel is not None:
        weighted = jacobian * robust_weights(residual, robust_kernel, kernel_scale)[:, None]
    solution = np.linalg.lstsq(weighted.T @ jacobian, -(weighted.T @ residual), rcond=None)[0]
    return _step_about(centre, solution)


def _step_about(centre: np.ndarray, solution: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and translation of the small motion ``solution`` (rotation vector [rad], shift) about ``centre``."""
    rotation = rotation_from_vector(solution[:3])
    return rotation, centre + solution[3:] - rotation @ centre


MAX_EXTRAPOLATION = 5.0  # largest factor a step is scaled by
STEADY_ANGLE_DEG = 10.0  # most angle between two steps' 6-vectors that counts as one steady direction
COARSE_STRIDE = 4  # the coarse phase registers every COARSE_STRIDE-th source point
COARSE_MIN_POINTS = 500  # fewest subsample points for a coarse phase; below, queries no longer dominate the time


def _extrapolate(raw, previous_raw, step_rotation, step_translation):
    """The step, scaled by ``1 / (1 - rho)`` if it continues the last one and shrank by ``rho`` (module docstring)."""
    norm, previous_norm = float(np.linalg.norm(raw)), float(np.linalg.norm(previous_raw))
    if (
        norm == 0.0
        or previous_norm == 0.0
        or raw @ previous_raw < math.cos(math.radians(STEADY_ANGLE_DEG)) * norm * previous_norm
    ):
        return step_rotation, step_translation
    ratio = norm / previous_norm
    if ratio >= 1.0:
        return step_rotation, step_translation
    factor = min(MAX_EXTRAPOLATION, 1.0 / (1.0 - ratio))
    return rotation_from_vector(factor * raw[:3]), factor * raw[3:]


def icp(
    source,
    target,
    init=None,
    *,
    max_iterations: int = 50,
    tolerance: float = 1e-6,
    max_correspondence_distance: float | None = None,
    method: str = "point_to_point",
    robust_kernel: str | None = None,
    kernel_scale: float = DEFAULT_KERNEL_SCALE,
    covariance_neighbours: int = GICP_NEIGHBOURS,
    source_covariances=None,
    target_covariances=None,
) -> RegistrationResult:
    """Rigid transform that maps ``source`` onto ``target`` by iterative closest point; see the module docstring.

    Args:
        source: (N, 3) points to move.
        target: (M, 3) points to align them with.
        init: (4, 4) rigid transform to start from (a warm start); default identity.
        max_iterations: most incremental motions to apply, >= 1.
        tolerance: an increment with rotation below this [rad] and translation below this [length]
            ends the iteration as converged; > 0.
        max_correspondence_distance: pairs at least this far apart are not correspondences; ``None``
            for no limit.
        method: ``"point_to_point"``, ``"point_to_plane"`` or ``"gicp"`` (generalized ICP, ``gicp`` module).
        robust_kernel: ``None`` (least squares) or one of ``ROBUST_KERNELS`` (``robust_kernels`` module),
            for ``"point_to_plane"`` and ``"gicp"``.
        kernel_scale: the robust kernel's scale ``c`` [length unit], > 0.
        covariance_neighbours: points per GICP covariance (``gicp_covariances``), >= 3.
        source_covariances, target_covariances: (N, 3, 3) and (M, 3, 3) symmetric GICP covariances computed before
            (``gicp_covariances``, e.g. of a whole frame whose control points are ``source``); default:
            computed here from each cloud's ``covariance_neighbours`` nearest points.

    Returns:
        A ``RegistrationResult``; ``rmse`` and ``fitness`` are evaluated under the final transform.

    Raises:
        ValueError: for points not (K, 3) with K >= 3, NaN / inf, a non-rigid ``init``, an unknown
            ``method`` or ``robust_kernel``, a kernel with ``"point_to_point"``, a non-positive setting,
            fewer points than ``covariance_neighbours`` or covariances of the wrong shape (``"gicp"``).
    """
    source = check_points(source, "source")
    target = check_points(target, "target")
    transform = np.eye(4) if init is None else check_rigid_transform(init, "init").copy()
    limit = _check_settings(max_iterations, tolerance, max_correspondence_distance, method)
    check_robust_kernel(robust_kernel, kernel_scale)
    check_kernel_method(robust_kernel, method)

    tree = KdTree(target)
    normals = estimate_normals(target, tree) if method == "point_to_plane" else None
    if method == "gicp":
        source_covariances = _Covariances(source, source_covariances, covariance_neighbours, "source")
        target_covariances = _Covariances(target, target_covariances, covariance_neighbours, "target", tree)
    rotation, translation = transform[:3, :3].copy(), transform[:3, 3].copy()
    closest = _ClosestPoints(tree, source.shape[0], limit)

    def correspondences(rows: slice) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Inlier pairs of the source points ``rows``: moved points, closest target points, distances, indices."""
        moved = source[rows] @ rotation.T + translation
        distance = closest.update(moved, rows)
        inliers = _inliers(distance)
        matched = np.take(closest.closest[rows], inliers, axis=0)
        return np.take(moved, inliers, axis=0), matched, distance[inliers], inliers

    def increment(moved, matched, inliers, rows) -> tuple[np.ndarray, np.ndarray]:
        if method == "point_to_point":
            return _point_to_point(moved, matched)
        matched_index = closest.index[rows][inliers]
        if method == "point_to_plane":
            return _point_to_plane(moved, matched, normals[matched_index], robust_kernel, kernel_scale)
        source_index = np.arange(source.shape[0])[rows][inliers]
        information = pair_information(
            source_covariances.of(source_index),
            target_covariances.of(matched_index),
            source_index,
            matched_index,
            rotation,
        )
        centre = np.full(moved.shape[0], 1.0 / moved.shape[0]) @ moved
        return _step_about(centre, gicp_step(moved, matched, information, robust_kernel, kernel_scale))

    def smaller_than(threshold: float, step_rotation: np.ndarray, step_translation: np.ndarray) -> bool:
        return rotation_angle(step_rotation) < threshold and float(np.linalg.norm(step_translation)) < threshold

    iterations, previous_raw = 0, None
    if source.shape[0] >= COARSE_STRIDE * COARSE_MIN_POINTS:
        rows = slice(None, None, COARSE_STRIDE)
        while iterations < max_iterations:
            moved, matched, distance, inliers = correspondences(rows)
            if inliers.size < 3:
                break
            step_rotation, step_translation = increment(moved, matched, inliers, rows)
            standard_error = math.sqrt(float(distance @ distance)) / inliers.size  # rms / sqrt(pairs)
            if smaller_than(max(standard_error, tolerance), step_rotation, step_translation):
                break
            raw = np.concatenate([rotation_vector(step_rotation), step_translation])
            if previous_raw is not None:
                step_rotation, step_translation = _extrapolate(raw, previous_raw, step_rotation, step_translation)
            rotation = step_rotation @ rotation
            translation = step_rotation @ translation + step_translation
            iterations, previous_raw = iterations + 1, raw

    rows, converged, previous_step, previous_raw = slice(None), False, None, None
    moved, matched, distance, inliers = correspondences(rows)
    while iterations < max_iterations and inliers.size >= 3:
        step_rotation, step_translation = increment(moved, matched, inliers, rows)
        raw = np.concatenate([rotation_vector(step_rotation), step_translation])
        if previous_raw is not None:
            step_rotation, step_translation = _extrapolate(raw, previous_raw, step_rotation, step_translation)
        rotation = step_rotation @ rotation
        translation = step_rotation @ translation + step_translation
        iterations += 1
        moved, matched, distance, inliers = correspondences(rows)
        if smaller_than(tolerance, step_rotation, step_translation) or (
            previous_step is not None
            and smaller_than(
                tolerance, step_rotation @ previous_step[0], step_rotation @ previous_step[1] + step_translation
            )
        ):
            converged = True
            break
        previous_step, previous_raw = (step_rotation, step_translation), raw

    transform = np.eye(4)
    transform[:3, :3], transform[:3, 3] = rotation, translation
    rmse = float(np.sqrt(np.mean(distance**2))) if inliers.size >= 3 else math.inf
    return RegistrationResult(transform, rmse, inliers.size / source.shape[0], iterations, converged)
