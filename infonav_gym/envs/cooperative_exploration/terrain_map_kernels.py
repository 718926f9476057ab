"""Compiled scan gains of the coverage map (``terrain_map``): each scan visits only the cells it sees.

A scan sees the cells with ``dx * dx + dy * dy <= radius^2`` (on the cell-centre ticks); the gain sums
``log1p(v_c / r)`` over those cells in row-major order.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import inline, kernel


@inline
def footprint(ticks, radius_squared, x, y, cells):
    """Write the cells a scan from (x, y) [m] sees into ``cells`` (row-major, ``row * K + col``); their count. The
    ticks ascend, so past (x, y) the first cell out of reach ends its row, the first row out of reach the grid;
    the rows and columns more than a cell out of reach before (x, y) are not visited (``first_near``)."""
    n_ticks, count = ticks.shape[0], 0
    reach = math.sqrt(radius_squared)
    first_col = first_near(ticks, x - reach)
    for row in range(first_near(ticks, y - reach), n_ticks):
        dy = y - ticks[row]
        dy_squared = dy * dy
        if dy_squared > radius_squared:
            if dy < 0.0:  # the ticks ascend: every later row is farther still
                break
            continue
        for col in range(first_col, n_ticks):
            dx = x - ticks[col]
            if dx * dx + dy_squared <= radius_squared:
                cells[count] = row * n_ticks + col
                count += 1
            elif dx < 0.0:
                break
    return count


@inline
def first_near(ticks, low):
    """The index of a tick at least a cell below the first tick >= ``low`` (0 for NaN): the ticks before it lie more
    than two cells below ``low``. ``ticks`` (K >= 2,) ascend evenly."""
    start = (low - ticks[0]) / (ticks[1] - ticks[0]) - 1.0
    return int(min(start, float(len(ticks)))) if start > 0.0 else 0


@kernel
def scan_gains(ticks, radius_squared, variances, ends, noise_variances):
    """``TerrainMapModel.scan_gains`` on the cell-centre ``ticks`` (K,) [m] and squared scan radius [m^2]."""
    n_copies, n_scans = ends.shape[0], ends.shape[1]
    gains = np.zeros((n_copies, n_scans))
    cells, terms = np.empty(variances.shape[1], dtype=np.int64), np.empty(variances.shape[1])
    noise_of_term = np.full(variances.shape[1], np.nan)  # each cell's term is kept for scans of the same noise
    for copy in range(n_copies):
        noise_of_term[:] = np.nan
        for scan in range(n_scans):
            noise, total = noise_variances[copy, scan], 0.0
            for k in range(footprint(ticks, radius_squared, ends[copy, scan, 0], ends[copy, scan, 1], cells)):
                cell = cells[k]
                if noise_of_term[cell] != noise:
                    terms[cell], noise_of_term[cell] = math.log1p(variances[copy, cell] / noise), noise
                total += terms[cell]
            gains[copy, scan] = 0.5 * total
    return gains


@kernel
def fused_scans(ticks, radius_squared, variances, positions, noise_variances, scanning):
    """The cell variances (B, G) after each copy's scans of one step, fused in information form, and the map information
    they bring (B,) [nats], ``0.5 sum_c ln(v_c / v_c')`` over the cells some scan sees (``TerrainMapModel.fused``; the
    others get ``1 / (1 / v_c + 0)``, as in numpy; ``ticks``, ``radius_squared`` as ``scan_gains`` takes them)."""
    n_copies, n_scans, n_cells = positions.shape[0], positions.shape[1], variances.shape[1]
    after, information = np.empty((n_copies, n_cells)), np.zeros(n_copies)
    added, cells = np.empty(n_cells), np.empty(n_cells, dtype=np.int64)
    for copy in range(n_copies):
        added[:] = 0.0
        for scan in range(n_scans):
            if scanning[copy, scan]:
                weight, x, y = 1.0 / noise_variances[copy, scan], positions[copy, scan, 0], positions[copy, scan, 1]
                for k in range(footprint(ticks, radius_squared, x, y, cells)):
                    added[cells[k]] += weight
        for cell in range(n_cells):  # apart from the sum below: a loop without calls, which the compiler vectorizes
            after[copy, cell] = 1.0 / (1.0 / variances[copy, cell] + added[cell])
        total = 0.0
        for cell in range(n_cells):
            if added[cell] != 0.0:
                total += math.log(variances[copy, cell] / after[copy, cell])
        information[copy] = 0.5 * total
    return after, information
