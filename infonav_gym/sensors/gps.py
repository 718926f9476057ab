"""DGPS: an absolute position fix that drops out on a time schedule and inside GPS-denied zones."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from infonav_gym.config import check_number

MIN_POSITION_STD_M = 1e-3  # finer fixes make the pose covariance numerically singular [m]
MAX_POSITION_STD_M = 100.0  # [m]


@dataclass(frozen=True)
class GPSSensor:
    """Measures the position ``[x, y]`` with isotropic Gaussian noise, when satellites are available."""

    position_std_m: float = 0.1  # per coordinate [m] (DGPS: centimetres to decimetres)
    outages: tuple[tuple[float, float], ...] = ()  # spans start_s <= t < end_s without a fix [s]

    def __post_init__(self):
        check_number(
            type(self).__name__, "position_std_m", self.position_std_m, MIN_POSITION_STD_M, MAX_POSITION_STD_M, unit="m"
        )
        for span in self.outages:
            if len(span) != 2 or not span[0] < span[1]:
                raise ValueError(f"a GPS outage must be a span (start_s, end_s) with start_s < end_s, got {span!r}")

    def available(self, time_s: float, in_denied_zone: bool = False) -> bool:
        """Whether a fix can be had at ``time_s`` (not in an outage span, not inside a GPS-denied zone)."""
        return not in_denied_zone and not any(start <= time_s < end for start, end in self.outages)

    def noise_covariance(self) -> np.ndarray:
        """Covariance of a fix's noise (2, 2)."""
        return np.eye(2) * self.position_std_m**2

    def measure(self, positions, np_random: np.random.Generator) -> np.ndarray:
        """Noisy fixes of true positions ``[x, y]``: (2,) -> (2,) or (k, 2) -> (k, 2)."""
        positions = np.asarray(positions, dtype=float)
        return self.measure_with_noise(positions, np_random.standard_normal(positions.shape))

    def measure_with_noise(self, positions, noise) -> np.ndarray:
        """``measure`` given its standard normals ``noise`` (the shape of ``positions``, (..., 2))."""
        return positions + self.position_std_m * noise
