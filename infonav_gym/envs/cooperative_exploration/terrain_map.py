"""The coverage map of ``cooperative_exploration_v0``: a grid of terrain heights, each a Gaussian, mapped by scans.

Cell ``c`` holds the variance ``v_c`` of its terrain height estimate [m^2], ``prior_std_m^2`` before any scan.
A robot's scan measures the height of every cell whose centre lies within ``scan_radius_m`` of it, with noise
variance ``r = scan_std_m^2 + (terrain_slope * sigma)^2``: a position error ``sigma`` [m] puts the height at the
wrong place, and on terrain of slope ``terrain_slope`` [m/m] that is a height error. Scans of one step fuse in
information form, ``1 / v_c' = 1 / v_c + sum_k 1 / r_k``, and the map information they bring is the entropy
reduction ``0.5 sum_c ln(v_c / v_c')`` [nats], exact before the measured heights are known. A cell is covered
once its std is at most ``covered_std_m``. Numpy on arrays with any leading batch dimensions; the scan gains
are compiled (``terrain_map_kernels``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from infonav_gym.envs.cooperative_exploration import terrain_map_kernels


@dataclass(frozen=True)
class TerrainMapModel:
    """The static part of the coverage map (its state is the cell variances, an array the env keeps): the cell
    centres' coordinate along each axis ``ticks`` (K,) [m] (the G = K^2 cells row-major from the lower left corner),
    and the config keys of the same names (see the module)."""

    ticks: np.ndarray
    prior_std_m: float
    scan_radius_m: float
    scan_std_m: float
    terrain_slope: float
    covered_std_m: float

    @classmethod
    def square(cls, size_m: float, cells_per_side: int, **parameters) -> TerrainMapModel:
        """The model of a square field of side ``size_m`` [m] cut into ``cells_per_side`` x ``cells_per_side`` cells."""
        return cls((np.arange(cells_per_side) + 0.5) * size_m / cells_per_side, **parameters)

    @property
    def centers(self) -> np.ndarray:
        """The cell centres (G, 2) [m], row-major from the lower left corner."""
        x, y = np.meshgrid(self.ticks, self.ticks)
        return np.column_stack([x.ravel(), y.ravel()])

    @property
    def n_cells(self) -> int:
        return len(self.ticks) ** 2

    def prior_variances(self) -> np.ndarray:
        """A fresh map: every cell at the prior variance (G,) [m^2]."""
        return np.full(self.n_cells, self.prior_std_m**2)

    def scan_noise_variances(self, position_std_m) -> np.ndarray:
        """Height noise variance [m^2] of a scan from a position known to ``position_std_m`` [m] (any shape)."""
        return self.scan_std_m**2 + (self.terrain_slope * np.asarray(position_std_m)) ** 2

    def scan_gains(self, variances: np.ndarray, positions: np.ndarray, noise_variances: np.ndarray) -> np.ndarray:
        """Map information [nats] each scan (B, E) would bring alone: ``0.5 sum_c ln(1 + v_c / r)`` over the cells
        it sees, from positions (B, E, 2) [m] with noise variances (B, E) [m^2] on each copy's cell
        variances (B, G) [m^2] (compiled: only the cells a scan sees are visited)."""
        return terrain_map_kernels.scan_gains(*self._kernel_arguments(variances, positions, noise_variances))

    def fused(self, variances, positions, noise_variances, scanning) -> tuple[np.ndarray, np.ndarray]:
        """The cell variances (B, G) [m^2] after the scans of the ``scanning`` robots (B, S) from ``positions``
        (B, S, 2) [m] with noise variances (B, S) [m^2], and the map information they bring (B,) [nats]."""
        arguments = self._kernel_arguments(variances, positions, noise_variances)
        return terrain_map_kernels.fused_scans(*arguments, np.ascontiguousarray(scanning, dtype=bool))

    def _kernel_arguments(self, variances, positions, noise_variances) -> tuple:
        """The grid, the squared scan radius and the arrays in the one layout ``terrain_map_kernels`` compiles for."""
        arrays = (np.ascontiguousarray(array, dtype=float) for array in (variances, positions, noise_variances))
        return self.ticks, float(self.scan_radius_m) ** 2, *arrays

    def coverage(self, variances: np.ndarray) -> np.ndarray:
        """The fraction of cells covered (height std at most ``covered_std_m``) (...)."""
        return np.mean(variances <= self.covered_std_m**2, axis=-1)
