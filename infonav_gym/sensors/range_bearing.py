"""Range-bearing sensor (laser or stereo) with a limited range and field of view."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from infonav_gym.geometry import wrap_angle


@dataclass(frozen=True)
class RangeBearingSensor:
    """Range and bearing to point landmarks; range noise grows with distance.

    Attributes:
        range_std_m: range noise standard deviation at zero range [m].
        range_std_per_m: growth of that standard deviation per metre of range [m/m].
        bearing_std_rad: bearing noise standard deviation [rad].
        max_range_m: landmarks farther than this are not detected [m].
        fov_rad: full field of view, centred on the heading [rad] (2 pi = all around).
    """

    range_std_m: float = 0.1
    range_std_per_m: float = 0.01
    bearing_std_rad: float = math.radians(2.0)
    max_range_m: float = 15.0
    fov_rad: float = math.pi

    def __post_init__(self):
        if not (self.range_std_m > 0 and self.range_std_per_m >= 0 and self.bearing_std_rad > 0):
            raise ValueError(f"range-bearing noise must be positive, got {self}")
        if not (self.max_range_m > 0 and 0 < self.fov_rad <= 2 * math.pi):
            raise ValueError(f"need max_range_m > 0 and 0 < fov_rad <= 2 pi, got {self}")

    def noise_covariance(self, ranges) -> np.ndarray:
        """Measurement noise covariance at each range: (N,) -> (N, 2, 2)."""
        ranges = np.atleast_1d(ranges)
        covariance = np.zeros((len(ranges), 2, 2))
        covariance[:, 0, 0] = (self.range_std_m + self.range_std_per_m * ranges) ** 2
        covariance[:, 1, 1] = self.bearing_std_rad**2
        return covariance

    def in_coverage(self, measurements) -> np.ndarray:
        """Which noise-free ``[range, bearing]`` rows fall inside the range and field of view."""
        return (measurements[:, 0] <= self.max_range_m) & (np.abs(measurements[:, 1]) <= 0.5 * self.fov_rad)

    def measure(self, pose, landmark, np_random: np.random.Generator) -> np.ndarray:
        """A noisy ``[range, bearing]`` of ``landmark`` seen from ``pose``."""
        dx, dy = landmark[0] - pose[0], landmark[1] - pose[1]
        distance = math.hypot(dx, dy)
        range_noise, bearing_noise = np_random.standard_normal(2)
        return np.array(
            [
                distance + (self.range_std_m + self.range_std_per_m * distance) * range_noise,
                wrap_angle(math.atan2(dy, dx) - pose[2] + self.bearing_std_rad * bearing_noise),
            ]
        )


def range_bearing_sensor_from_config(config: dict) -> RangeBearingSensor:
    """The sensor described by an env config's ``range_std_m``, ``range_std_per_m``, ``bearing_std_rad``,
    ``sensor_max_range_m`` and ``sensor_fov_rad`` keys."""
    return RangeBearingSensor(
        config["range_std_m"],
        config["range_std_per_m"],
        config["bearing_std_rad"],
        config["sensor_max_range_m"],
        config["sensor_fov_rad"],
    )
