"""Generalized ICP (Segal, Haehnel and Thrun, 2009): plane-to-plane registration with per-point covariances.

Each point's covariance, of its ``neighbours`` nearest points, is regularised to a plane (eigenvalues
``(PLANE_EPSILON, 1, 1)``). A pair ``(p, q)`` with ``d = q - (R p + t)`` costs ``d^T (C_q + R C_p R^T)^-1 d``;
a step is one Gauss-Newton step on SE(3) about the moved points' centroid (as point-to-plane in ``icp``). A robust
kernel sees ``r = sqrt(2 PLANE_EPSILON d^T M d)``: for coplanar points their distance along the normal, so a kernel
scale means the same length as for point-to-plane.
"""

from __future__ import annotations

import numpy as np

from infonav_gym.compiled import contiguous, kernel
from infonav_gym.registration.kdtree import KdTree, check_points
from infonav_gym.registration.normals import estimate_normals
from infonav_gym.registration.robust_kernels import robust_weights

GICP_NEIGHBOURS = 20  # points per covariance
PLANE_EPSILON = 1e-3  # eigenvalue along the normal of a regularised covariance (the tangent ones are 1)


def check_neighbours(neighbours, count: int, name: str) -> int:
    """``neighbours`` as an int in [3, ``count``], or ``ValueError`` naming it and the points of ``name``."""
    if isinstance(neighbours, bool) or not isinstance(neighbours, (int, np.integer)) or neighbours < 3:
        raise ValueError(f"neighbours (points per covariance) must be an integer >= 3, got {neighbours!r}")
    if count < neighbours:
        raise ValueError(
            f"{name} has {count} points, too few for covariances from neighbours={neighbours} nearest points; "
            f"pass at least {neighbours} points or fewer neighbours"
        )
    return int(neighbours)


def gicp_covariances(
    points, neighbours: int = GICP_NEIGHBOURS, tree: KdTree | None = None, rows=slice(None)
) -> np.ndarray:
    """The plane-regularised covariances (R, 3, 3) of ``points[rows]`` (N, 3) from ``neighbours`` >= 3 nearest
    (itself included; ``tree``: a ``KdTree`` of ``points`` at hand); ``ValueError`` for bad points or neighbours."""
    points = check_points(points, "points")
    tree = KdTree(points) if tree is None else tree
    return plane_covariances(points, check_neighbours(neighbours, points.shape[0], "points"), tree, rows)


def plane_covariances(points: np.ndarray, neighbours: int, tree: KdTree, rows) -> np.ndarray:
    """``gicp_covariances`` of checked ``points`` and ``neighbours``, unchecked (what ``icp`` calls per iteration)."""
    normals = estimate_normals(points, tree, neighbours, rows)
    return np.eye(3) - (1.0 - PLANE_EPSILON) * normals[:, :, None] * normals[:, None, :]  # eigenvalues (eps, 1, 1)


@kernel
def pair_information(source_covariances, target_covariances, source_index, target_index, rotation):
    """``(C_q + R C_p R^T)^-1`` (K, 3, 3) of the pairs ``source_index`` -> ``target_index`` (K,) under ``rotation``.

    ``C_p`` and ``C_q`` are rows of ``source_covariances`` (N, 3, 3) and ``target_covariances`` (M, 3, 3), symmetric;
    the sum is inverted by its adjugate (faster than ``np.linalg.inv``).
    """
    information = np.empty((source_index.size, 3, 3))
    rotated, combined = np.empty((3, 3)), np.empty((3, 3))
    for n in range(source_index.size):
        source, target = source_covariances[source_index[n]], target_covariances[target_index[n]]
        for i in range(3):
            for j in range(3):
                rotated[i, j] = (
                    rotation[i, 0] * source[0, j] + rotation[i, 1] * source[1, j] + rotation[i, 2] * source[2, j]
                )
        for i in range(3):
            for j in range(3):
                combined[i, j] = target[i, j] + rotated[i, 0] * rotation[j, 0] + rotated[i, 1] * rotation[j, 1]
                combined[i, j] += rotated[i, 2] * rotation[j, 2]
        a, b, c = combined[0, 0], combined[0, 1], combined[0, 2]
        d, e, f = combined[1, 1], combined[1, 2], combined[2, 2]
        first, second, third = d * f - e * e, c * e - b * f, b * e - c * d
        scale = 1.0 / (a * first + b * second + c * third)
        inverse = information[n]
        inverse[0, 0], inverse[0, 1], inverse[0, 2] = first * scale, second * scale, third * scale
        inverse[1, 1] = (a * f - c * c) * scale
        inverse[1, 2] = (b * c - a * e) * scale
        inverse[2, 2] = (a * d - b * b) * scale
        inverse[1, 0], inverse[2, 0], inverse[2, 1] = inverse[0, 1], inverse[0, 2], inverse[1, 2]
    return information


@kernel
def normal_equations(moved, matched, information, weights):
    """``(sum w J^T M J, sum w J^T M d)`` ((6, 6), (6,)) of the pairs ``moved`` -> ``matched`` (K, 3), ``d`` their
    difference, ``M`` = ``information`` (K, 3, 3), ``w`` = ``weights`` (K,) and ``J = [[a]_x, -I]`` (``a`` the arm
    of ``moved`` from its centroid)."""
    count = moved.shape[0]
    centre = np.zeros(3)
    for n in range(count):
        for i in range(3):
            centre[i] += moved[n, i]
    for i in range(3):
        centre[i] /= count
    hessian, gradient = np.zeros((6, 6)), np.zeros(6)
    arm, pulled, skew, weighted = np.empty(3), np.empty(3), np.empty((3, 3)), np.empty((3, 3))
    for n in range(count):
        for i in range(3):
            arm[i] = moved[n, i] - centre[i]
        skew[0, 0], skew[0, 1], skew[0, 2] = 0.0, -arm[2], arm[1]  # [a]_x
        skew[1, 0], skew[1, 1], skew[1, 2] = arm[2], 0.0, -arm[0]
        skew[2, 0], skew[2, 1], skew[2, 2] = -arm[1], arm[0], 0.0
        for i in range(3):
            pulled[i] = 0.0
            for j in range(3):
                weighted[i, j] = weights[n] * information[n, i, j]
                pulled[i] += weighted[i, j] * (matched[n, j] - moved[n, j])  # w M d
        for i in range(3):
            for j in range(3):
                pushed = weighted[i, 0] * skew[0, j] + weighted[i, 1] * skew[1, j] + weighted[i, 2] * skew[2, j]
                hessian[3 + i, j] -= pushed  # -w M [a]_x
                hessian[3 + i, 3 + j] += weighted[i, j]
                for k in range(3):
                    hessian[k, j] += skew[i, k] * pushed  # [a]_x^T w M [a]_x
            gradient[i] += skew[0, i] * pulled[0] + skew[1, i] * pulled[1] + skew[2, i] * pulled[2]
            gradient[3 + i] -= pulled[i]
    for i in range(3):
        for j in range(3):
            hessian[i, 3 + j] = hessian[3 + j, i]
    return hessian, gradient


def gicp_step(
    moved: np.ndarray,
    matched: np.ndarray,
    information: np.ndarray,
    robust_kernel: str | None = None,
    kernel_scale: float = 1.0,
) -> np.ndarray:
    """The Gauss-Newton step ``(w [rad], v)`` (6,) about the centroid of ``moved`` for the pairs ``moved`` ->
    ``matched`` (K, 3) with ``information`` ``M`` (K, 3, 3): solves ``sum J^T M J step = -sum J^T M d``."""
    moved, matched, information = contiguous(moved), contiguous(matched), contiguous(information)
    weights = np.ones(moved.shape[0])
    if robust_kernel is not None:
        difference = matched - moved
        squared = np.maximum(np.einsum("ni,nij,nj->n", difference, information, difference), 0.0)
        weights = robust_weights(np.sqrt(2.0 * PLANE_EPSILON * squared), robust_kernel, kernel_scale)
    hessian, gradient = normal_equations(moved, matched, information, weights)
    return np.linalg.lstsq(hessian, -gradient, rcond=None)[0]
