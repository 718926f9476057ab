"""The registration's neighbour search: small_gicp's k-d tree on one thread, chosen by measurement (issue 26).

On ``registration_timing``'s 39k-point cloud, 20 neighbours of every point (tree included) took 120 CPU ms with
``scipy.spatial.cKDTree``, 74 with pykdtree and 73 with ``small_gicp.KdTree`` (the same neighbours); GICP
covariances 127, 87 and 81 (small_gicp's own: 107). A GICP registration then takes 0.88 of small_gicp's time.
"""

from __future__ import annotations

import numpy as np
import small_gicp

from infonav_gym.compiled import contiguous

THREADS = 1  # small_gicp's threads: one, as every other part of a registration


def check_points(points, name: str) -> np.ndarray:
    """``points`` as a finite float (K, 3) array with K >= 3, or ``ValueError`` naming ``name``."""
    array = np.asarray(points, dtype=float)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"{name} must be an (N, 3) array of points, got shape {array.shape}")
    if array.shape[0] < 3:
        raise ValueError(f"{name} needs at least 3 points to fix a rigid motion, got {array.shape[0]}")
    if not np.all(np.isfinite(array)):
        bad = int(np.count_nonzero(~np.all(np.isfinite(array), axis=1)))
        raise ValueError(f"{name} must be finite, but {bad} of its {array.shape[0]} points hold NaN or inf")
    return array


class KdTree:
    """small_gicp's k-d tree of ``points``, a finite float (M, 3) array (``check_points``), queried as
    ``scipy.spatial.cKDTree`` is."""

    def __init__(self, points: np.ndarray):
        self.data, self.n = contiguous(points), points.shape[0]
        self._tree = small_gicp.KdTree(self.data, num_threads=THREADS)

    def __getstate__(self) -> dict:
        """Pickled as its points (small_gicp's tree does not pickle); rebuilt on load."""
        return {"data": self.data}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["data"])

    def query(self, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Distances and indices (Q, k) of the ``k`` (<= M) nearest points of each of ``queries`` (Q, 3), nearest
        first: ``cKDTree.query``'s (up to exact ties)."""
        index, squared = self._tree.batch_knn_search(contiguous(queries), k, num_threads=THREADS)
        return np.sqrt(squared), index.view(np.int64)
