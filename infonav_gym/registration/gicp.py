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
    return np.einsum("nki,nkj->nij", patches, patches) / (neighbours - 1)


def plane_covariances(covariances: np.ndarray) -> np.ndarray:
    """``covariances`` (N, 3, 3) with their eigenvalues replaced by ``(PLANE_EPSILON, 1, 1)``, smallest first."""
    _, axes = np.linalg.eigh(covariances)
    scaled = axes * np.array([PLANE_EPSILON, 1.0, 1.0])
    return np.einsum("nik,njk->nij", scaled, axes)


def gicp_covariances(points, neighbours: int = GICP_NEIGHBOURS, tree: cKDTree | None = None) -> np.ndarray:
    """The plane-regularised covariances (N, 3, 3) GICP uses for ``points`` (N, 3); compute once per cloud."""
    return plane_covariances(neighbour_covariances(np.asarray(points, dtype=float), neighbours, tree))


def gicp_step(
    moved: np.ndarray,
    matched: np.ndarray,
    combined: np.ndarray,
    robust_kernel: str | None = None,
    kernel_scale: float = 1.0,
) -> np.ndarray:
    """The Gauss-Newton step ``(w, v)`` (6,) for the pairs ``moved`` -> ``matched`` (K, 3).

    ``combined`` (K, 3, 3) holds ``C_q + R C_p R^T`` per pair; the step's rotation ``w`` [rad] is about
    the centroid of ``moved``, its translation ``v`` moves that centroid.
    """
    information = np.linalg.inv(combined)
    difference = matched - moved
    if robust_kernel is not None:
        squared = np.einsum("ni,nij,nj->n", difference, information, difference)
        weights = robust_weights(np.sqrt(2.0 * PLANE_EPSILON * np.maximum(squared, 0.0)), robust_kernel, kernel_scale)
        information = information * weights[:, None, None]
    arm = moved - np.full(moved.shape[0], 1.0 / moved.shape[0]) @ moved
    jacobian = np.zeros((moved.shape[0], 3, 6))  # d(difference) / d(w, v) = [[arm]_x, -I]
    jacobian[:, 0, 1], jacobian[:, 0, 2] = -arm[:, 2], arm[:, 1]
    jacobian[:, 1, 0], jacobian[:, 1, 2] = arm[:, 2], -arm[:, 0]
    jacobian[:, 2, 0], jacobian[:, 2, 1] = -arm[:, 1], arm[:, 0]
    jacobian[:, :, 3:] = -np.eye(3)
    weighted = np.einsum("nki,nkl->nil", jacobian, information)
    hessian = np.einsum("nil,nlj->ij", weighted, jacobian)
    gradient = np.einsum("nil,nl->i", weighted, difference)
    return np.linalg.lstsq(hessian, -gradient, rcond=None)[0]
