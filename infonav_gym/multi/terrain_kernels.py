"""Compiled scan gains of the coverage map (``multi.terrain_map``): each scan visits only the cells it sees.

The footprint test is ``TerrainMapModel.footprints``'s, operation for operation (``dx * dx + dy * dy <=
radius^2`` on the cell-centre ticks); the gain sums ``log1p(v_c / r)`` over those cells in row-major order.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import kernel


@kernel
def scan_gains(ticks, radius_squared, variances, ends, noise_variances):
    """``0.5 sum_c ln(1 + v_c / r)`` over the cells each scan sees (B, E) [nats].

    Args:
        ticks: the cell-centre coordinates along each axis (K,) [m]; cell ``row * K + col``.
        radius_squared: the squared scan radius [m^2].
        variances: the cell variances of each copy (B, K^2) [m^2].
        ends: where each scan is taken (B, E, 2) [m].
        noise_variances: each scan's height noise variance (B, E) [m^2].
    """
    n_copies, n_scans, n_ticks = ends.shape[0], ends.shape[1], ticks.shape[0]
    gains = np.zeros((n_copies, n_scans))
    for copy in range(n_copies):
        for scan in range(n_scans):
            x, y, noise = ends[copy, scan, 0], ends[copy, scan, 1], noise_variances[copy, scan]
            total = 0.0
            for row in range(n_ticks):
                dy = y - ticks[row]
                dy_squared = dy * dy
                if dy_squared > radius_squared:
                    continue
                for col in range(n_ticks):
                    dx = x - ticks[col]
                    if dx * dx + dy_squared <= radius_squared:
                        total += math.log1p(variances[copy, row * n_ticks + col] / noise)
            gains[copy, scan] = 0.5 * total
    return gains
