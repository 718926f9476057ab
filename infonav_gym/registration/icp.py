"""Iterative closest point (ICP) registration of two 3D point sets (the paper's Section V).

Pair each source point with its closest target point (a ``KdTree``), solve the increment that best aligns the
inlier pairs (within ``max_correspondence_distance`` and below ``median(d) + ROBUST_K * MAD_TO_STD * MAD(d)``, a
robust sigma: junk points cannot pull the solution), apply it, repeat. Increments: ``point_to_point`` by Kabsch's
SVD; ``point_to_plane`` by small-angle least squares on PCA target normals; ``gicp`` by one Gauss-Newton step of
generalized ICP on per-point covariances (given, or computed when a pair first uses a point); the last two take a
``robust_kernel`` (IRLS).

Speed-ups: a step continuing the last one is extrapolated (``_extrapolate``, Besl & McKay 1992; 29 steps to 12 on
a LADAR pair); a large source is first registered on every ``COARSE_STRIDE``-th point until a step is below the
subsample's resolution, then on all points, so the result is theirs (halves the time on a 4,900-point pair).
Converged when the last increment, or the last two together (a two-cycle of the pairing), rotates [rad] and moves
less than ``tolerance``; ``iterations`` counts the increments of both phases (identical clouds: 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from infonav_gym.compiled import contiguous
from infonav_gym.geometry import rigid_transform, rotation_angle
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
    """The outcome of ``icp``: ``transform`` (4, 4) maps source onto target; ``rmse`` of the inlier pairs (``inf``
    below 3 pairs) and ``fitness`` (inlier fraction of the source) under it; increments applied; converged."""

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
    """A cloud's GICP covariances: ``given`` (checked), or computed for a point the first time a pair uses it."""

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

    With the two closest at ``d1 <= d2``, a point that moved less than ``(d2 - d1) / 2`` keeps its closest
    (triangle inequality), so results equal a full query. With a limit, ``SEARCH_BOUND_FACTOR`` times it stands
    in for a farther ``d2``. ``update`` serves a slice (the coarse subsample) of the cache of all source points.
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
        """Distances (N,) of ``moved`` (source points ``rows``) to their closest target points; ``inf`` past limit."""
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


def _checked_normals(normals, target: np.ndarray) -> np.ndarray:
    """``normals`` as a finite float (M, 3) array, one per ``target`` point, or ``ValueError``."""
    array = np.asarray(normals, dtype=float)
    if array.shape != target.shape or not np.all(np.isfinite(array)):
        raise ValueError(
            f"target_normals must be finite, one normal per target point: {target.shape}, got {array.shape}"
        )
    return array


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
    return candidates[inside <= median + ROBUST_K * MAD_TO_STD * _median(np.abs(inside - median))]


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
    """Rotation and translation minimising ``sum rho(n . (R p + t - q))`` (``rho``: square or ``robust_kernel`` by
    one IRLS step), linearised in the rotation about the centroid (better conditioned than the origin)."""
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


def _extrapolate(step_rotation, step_translation, previous_raw):
    """The step, scaled by ``1 / (1 - rho)`` (at most ``MAX_EXTRAPOLATION``) if it continues the last one
    (``previous_raw``) within ``STEADY_ANGLE_DEG`` and shrank by ``rho``; and its 6-vector."""
    raw = np.concatenate([rotation_vector(step_rotation), step_translation])
    if previous_raw is None:
        return step_rotation, step_translation, raw
    norm, previous_norm = float(np.linalg.norm(raw)), float(np.linalg.norm(previous_raw))
    if (
        norm == 0.0
        or previous_norm == 0.0
        or raw @ previous_raw < math.cos(math.radians(STEADY_ANGLE_DEG)) * norm * previous_norm
        or norm / previous_norm >= 1.0
    ):
        return step_rotation, step_translation, raw
    factor = min(MAX_EXTRAPOLATION, 1.0 / (1.0 - norm / previous_norm))
    return rotation_from_vector(factor * raw[:3]), factor * raw[3:], raw


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
    target_normals=None,
    target_tree: KdTree | None = None,
) -> RegistrationResult:
    """Rigid transform that maps ``source`` (N, 3) onto ``target`` (M, 3) by ICP (module docstring).

    Args:
        init: (4, 4) rigid transform to start from; default identity.
        tolerance: an increment below this in rotation [rad] and translation converges; > 0.
        max_correspondence_distance: pairs this far apart or farther are not paired; ``None``: no limit.
        robust_kernel: ``None`` or one of ``ROBUST_KERNELS``, for ``"point_to_plane"`` and ``"gicp"``.
        source_covariances, target_covariances: (N, 3, 3), (M, 3, 3) GICP covariances computed before
            (``gicp_covariances``); default: computed here from ``covariance_neighbours`` points each.
        target_normals: (M, 3) unit normals of the target for ``"point_to_plane"`` (e.g. a map's own); default:
            estimated here (``estimate_normals``).
        target_tree: a ``KdTree`` of ``target`` built before (e.g. once for a map); default: built here.

    Raises:
        ValueError: for points not (K >= 3, 3) or not finite, a non-rigid ``init``, an unknown method or kernel, a
            kernel with ``"point_to_point"``, a non-positive setting, or bad GICP covariances or neighbours.
    """
    source, target = check_points(source, "source"), check_points(target, "target")
    transform = np.eye(4) if init is None else check_rigid_transform(init, "init").copy()
    limit = _check_settings(max_iterations, tolerance, max_correspondence_distance, method)
    check_robust_kernel(robust_kernel, kernel_scale)
    check_kernel_method(robust_kernel, method)

    tree = KdTree(target) if target_tree is None else target_tree
    normals = None
    if method == "point_to_plane":
        normals = estimate_normals(target, tree) if target_normals is None else _checked_normals(target_normals, target)
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
        covariances = source_covariances.of(source_index), target_covariances.of(matched_index)
        information = pair_information(*covariances, source_index, matched_index, rotation)
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
            step_rotation, step_translation, raw = _extrapolate(step_rotation, step_translation, previous_raw)
            rotation, translation = step_rotation @ rotation, step_rotation @ translation + step_translation
            iterations, previous_raw = iterations + 1, raw

    rows, converged, previous_step, previous_raw = slice(None), False, None, None
    moved, matched, distance, inliers = correspondences(rows)
    while iterations < max_iterations and inliers.size >= 3:
        step_rotation, step_translation = increment(moved, matched, inliers, rows)
        step_rotation, step_translation, raw = _extrapolate(step_rotation, step_translation, previous_raw)
        rotation, translation = step_rotation @ rotation, step_rotation @ translation + step_translation
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

    rmse = float(np.sqrt(np.mean(distance**2))) if inliers.size >= 3 else math.inf
    return RegistrationResult(
        rigid_transform(rotation, translation), rmse, inliers.size / source.shape[0], iterations, converged
    )
