"""Surface normals of a point cloud: the least-variance axis of each point's nearest points, compiled.

In closed form (``least_variance_axis``): as accurate as ``np.linalg.eigh`` (1e-14), whose per-matrix LAPACK call
dominates on stacks of 3 x 3. The sign of an axis is arbitrary.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import contiguous, inline, kernel

NORMAL_NEIGHBOURS = 10  # points per normal


@inline
def least_variance_axis(scatter, out):
    """Unit eigenvector of the smallest eigenvalue of the symmetric 3 x 3 ``scatter`` into ``out`` (3,): the
    trigonometric root of ``B = (scatter - q I) / p``'s cubic, the longest cross product of two rows of ``B - beta I``
    (Smith 1961; Kopp 2008). A multiple of the identity gives ``e_x``, as ``eigh``."""
    q = (scatter[0, 0] + scatter[1, 1] + scatter[2, 2]) / 3.0
    b00, b11, b22 = scatter[0, 0] - q, scatter[1, 1] - q, scatter[2, 2] - q
    b01, b02, b12 = scatter[0, 1], scatter[0, 2], scatter[1, 2]
    p = math.sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (b01 * b01 + b02 * b02 + b12 * b12)) / 6.0)
    out[0], out[1], out[2] = 1.0, 0.0, 0.0
    if p == 0.0:
        return
    b00, b11, b22, b01, b02, b12 = b00 / p, b11 / p, b22 / p, b01 / p, b02 / p, b12 / p
    half_det = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02))
    beta = 2.0 * math.cos(math.acos(min(1.0, max(-1.0, half_det))) / 3.0 + 2.0 * math.pi / 3.0)  # smallest root
    b00, b11, b22 = b00 - beta, b11 - beta, b22 - beta
    best = 0.0
    for x, y, z in (
        (b01 * b12 - b02 * b11, b02 * b01 - b00 * b12, b00 * b11 - b01 * b01),  # row 0 x row 1
        (b01 * b22 - b02 * b12, b02 * b02 - b00 * b22, b00 * b12 - b01 * b02),  # row 0 x row 2
        (b11 * b22 - b12 * b12, b12 * b02 - b01 * b22, b01 * b12 - b11 * b02),  # row 1 x row 2
    ):
        length = x * x + y * y + z * z
        if length > best:
            best, out[0], out[1], out[2] = length, x, y, z
    if best > 0.0:
        length = math.sqrt(best)
        out[0], out[1], out[2] = out[0] / length, out[1] / length, out[2] / length


@kernel
def least_variance_axes(points, index):
    """Unit least-variance axes (N, 3) of the patches ``points[index[n]]`` (``index`` (N, k)); the scatter summed
    about the patch's first point, so nothing cancels."""
    count, size = index.shape
    normals = np.empty((count, 3))
    offset, total, scatter = np.empty(3), np.empty(3), np.empty((3, 3))
    for n in range(count):
        origin = points[index[n, 0]]
        total[:] = 0.0
        scatter[:] = 0.0
        for m in range(size):
            for i in range(3):
                offset[i] = points[index[n, m], i] - origin[i]
                total[i] += offset[i]
            for i in range(3):
                for j in range(i, 3):
                    scatter[i, j] += offset[i] * offset[j]
        for i in range(3):
            for j in range(i, 3):
                scatter[i, j] -= total[i] * total[j] / size
                scatter[j, i] = scatter[i, j]
        least_variance_axis(scatter, normals[n])
    return normals


def estimate_normals(points: np.ndarray, tree, neighbours: int = NORMAL_NEIGHBOURS, rows=slice(None)) -> np.ndarray:
    """Unit normals (R, 3) of ``points[rows]`` (all by default): the least-variance axis of each one's ``neighbours``
    nearest points (at most M) of ``points`` (M, 3); ``tree`` is a ``KdTree`` (or a ``scipy.spatial.cKDTree``) of
    ``points``."""
    points = contiguous(np.asarray(points, dtype=float))
    queries = points[rows]
    k = min(neighbours, points.shape[0])
    _, index = tree.query(queries, k=k)
    return least_variance_axes(points, index.reshape(queries.shape[0], k))
