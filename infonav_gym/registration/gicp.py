"""Generalized ICP (Segal, Haehnel and Thrun, 2009): plane-to-plane registration with per-point covariances.

Each point gets the covariance of its ``neighbours`` nearest points (itself included), regularised
to a plane: its eigenvalues are replaced by ``(PLANE_EPSILON, 1, 1)``, keeping the eigenvectors, so
the covariance is thin along the local normal and wide in the tangent plane whatever the sampling
density. A pair ``(p, q)`` under the motion ``(R, t)``, with ``d = q - (R p + t)``, then costs the
Mahalanobis term ``d^T (C_q + R C_p R^T)^-1 d``; the step minimising the sum is one Gauss-Newton
step on SE(3): a small motion ``(w, v)`` about the centroid of the moved points, ``w`` then applied
as an exact rotation (as point-to-plane in ``icp``).

The residual a robust kernel sees is ``r = sqrt(2 PLANE_EPSILON d^T M d)`` with ``M`` that inverse: for
two coplanar points it equals their distance along the normal (up to ``PLANE_EPSILON`` times the
tangential part), so a kernel scale means the same length for GICP as for point-to-plane.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from infonav_gym.geometry import cross
from infonav_gym.registration.robust_kernels import robust_weights

GICP_NEIGHBOURS = 20  # points per covariance
PLANE_EPSILON = 1e-3  # eigenvalue along the normal of a regularised covariance (the tangent ones are 1)
QUERY_WORKERS = 1  # cKDTree.query threads, as in icp


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


def neighbour_covariances(points: np.ndarray, neighbours: int, tree: cKDTree | None = None) -> np.ndarray:
    """Sample covariance (N, 3, 3) of each point's ``neighbours`` nearest points (itself included), as ``np.cov``.

    Args:
        points: (N, 3) points, N >= ``neighbours``.
        neighbours: points per covariance, >= 3.
        tree: a ``cKDTree`` of ``points`` if one is at hand.
    """
    neighbours = check_neighbours(neighbours, points.shape[0], "points")
    tree = cKDTree(points) if tree is None else tree
    _, index = tree.query(points, k=neighbours, workers=QUERY_WORKERS)
    patches = points[index]
    patches -= patches.mean(axis=1, keepdims=True)
    return np.swapaxes(patches, 1, 2) @ patches / (neighbours - 1)


def plane_covariances(covariances: np.ndarray) -> np.ndarray:
    """``covariances`` (N, 3, 3) with their eigenvalues replaced by ``(PLANE_EPSILON, 1, 1)``, smallest first."""
    _, axes = np.linalg.eigh(covariances)
    scaled = axes * np.array([PLANE_EPSILON, 1.0, 1.0])
    return np.einsum("nik,njk->nij", scaled, axes)


def gicp_covariances(points, neighbours: int = GICP_NEIGHBOURS, tree: cKDTree | None = None) -> np.ndarray:
    """The plane-regularised covariances (N, 3, 3) GICP uses for ``points`` (N, 3); compute once per cloud."""
    return plane_covariances(neighbour_covariances(np.asarray(points, dtype=float), neighbours, tree))


def symmetric_inverse(matrices: np.ndarray) -> np.ndarray:
    """Inverses (K, 3, 3) of symmetric (K, 3, 3) ``matrices`` by the adjugate (faster than ``np.linalg.inv``)."""
    a, b, c = matrices[:, 0, 0], matrices[:, 0, 1], matrices[:, 0, 2]
    d, e, f = matrices[:, 1, 1], matrices[:, 1, 2], matrices[:, 2, 2]
    cofactors = [d * f - e * e, c * e - b * f, b * e - c * d, a * f - c * c, b * c - a * e, a * d - b * b]
    scale = 1.0 / (a * cofactors[0] + b * cofactors[1] + c * cofactors[2])
    first, second, third, fourth, fifth, sixth = (cofactor * scale for cofactor in cofactors)
    return np.stack([first, second, third, second, fourth, fifth, third, fifth, sixth], axis=1).reshape(-1, 3, 3)


def gicp_step(
    moved: np.ndarray,
    matched: np.ndarray,
    combined: np.ndarray,
    robust_kernel: str | None = None,
    kernel_scale: float = 1.0,
) -> np.ndarray:
    """The Gauss-Newton step ``(w, v)`` (6,) for the pairs ``moved`` -> ``matched`` (K, 3).

    ``combined`` (K, 3, 3) holds ``C_q + R C_p R^T`` per pair (symmetric); the step's rotation ``w``
    [rad] is about the centroid of ``moved``, its translation ``v`` moves that centroid. With
    ``d = matched - moved`` and the arm ``a`` from the centroid, ``d(d)/d(w, v) = J = [[a]_x, -I]``;
    the normal equations ``sum J^T M J step = -sum J^T M d`` are summed in blocks by cross products.
    """
    information = symmetric_inverse(combined)
    difference = matched - moved
    pulled = np.einsum("nij,nj->ni", information, difference)  # M d
    if robust_kernel is not None:
        squared = np.maximum(np.einsum("ni,ni->n", difference, pulled), 0.0)
        weights = robust_weights(np.sqrt(2.0 * PLANE_EPSILON * squared), robust_kernel, kernel_scale)
        information, pulled = information * weights[:, None, None], pulled * weights[:, None]
    arm = (moved - np.full(moved.shape[0], 1.0 / moved.shape[0]) @ moved)[:, None, :]
    arm_information = cross(arm, information)  # -M [a]_x per pair: its rows are a x M_j
    hessian = np.empty((6, 6))
    hessian[:3, :3] = cross(arm, np.swapaxes(arm_information, 1, 2)).sum(axis=0).T  # [a]_x^T M [a]_x
    hessian[3:, :3] = arm_information.sum(axis=0)  # -M [a]_x
    hessian[:3, 3:] = hessian[3:, :3].T
    hessian[3:, 3:] = information.sum(axis=0)
    gradient = np.concatenate([cross(pulled, arm[:, 0]).sum(axis=0), -pulled.sum(axis=0)])
    return np.linalg.lstsq(hessian, -gradient, rcond=None)[0]
