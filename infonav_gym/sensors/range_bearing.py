"""Range-bearing sensor (laser or stereo) with a limited range and field of view."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from infonav_gym.compiled import contiguous, inline, kernel
from infonav_gym.config import check_number, from_config
from infonav_gym.geometry import wrap_angle_kernel as wrap

MIN_RANGE_STD_M = 1e-4  # finer noise makes the covariance numerically singular [m]
MAX_RANGE_STD_M = 100.0  # [m]
MIN_BEARING_STD_RAD = 1e-5  # [rad]
MAX_SENSOR_RANGE_M = 1000.0  # [m]


@dataclass(frozen=True)
class RangeBearingSensor:
    """Range and bearing to point landmarks; range noise grows with distance. ``ParameterError`` for a bad field."""

    range_std_m: float = 0.1  # at zero range [m]
    range_std_per_m: float = 0.01  # its growth per metre of range [m/m]
    bearing_std_rad: float = math.radians(2.0)
    max_range_m: float = 15.0  # farther landmarks are not detected
    fov_rad: float = math.pi  # full field of view centred on the heading (2 pi: all around)

    def __post_init__(self):
        owner = type(self).__name__
        check_number(owner, "range_std_m", self.range_std_m, MIN_RANGE_STD_M, MAX_RANGE_STD_M, unit="m")
        check_number(owner, "range_std_per_m", self.range_std_per_m, 0.0, 1.0, unit="m/m")
        check_number(owner, "bearing_std_rad", self.bearing_std_rad, MIN_BEARING_STD_RAD, math.pi, unit="rad")
        check_number(owner, "max_range_m", self.max_range_m, 0.0, MAX_SENSOR_RANGE_M, open_low=True, unit="m")
        check_number(owner, "fov_rad", self.fov_rad, 0.0, 2 * math.pi, open_low=True, unit="rad")

    def noise_covariance(self, ranges) -> np.ndarray:
        """Measurement noise covariance at each range: (N,) -> (N, 2, 2)."""
        ranges = contiguous(np.atleast_1d(np.asarray(ranges, dtype=float)))
        return noise_covariances(ranges, *self.noise_stds)

    @property
    def noise_stds(self) -> tuple[float, float, float]:
        """``(range_std_m, range_std_per_m, bearing_std_rad)`` as floats, the arguments of ``noise_covariances``."""
        return float(self.range_std_m), float(self.range_std_per_m), float(self.bearing_std_rad)

    def in_coverage(self, measurements) -> np.ndarray:
        """Which noise-free ``[range, bearing]`` rows fall inside the range and field of view."""
        return (measurements[:, 0] <= self.max_range_m) & (np.abs(measurements[:, 1]) <= 0.5 * self.fov_rad)

    def measure(self, pose, landmark, np_random: np.random.Generator) -> np.ndarray:
        """A noisy ``[range, bearing]`` of ``landmark`` seen from ``pose``."""
        noise = np_random.standard_normal(2)
        return self.measure_with_noise(np.asarray(pose)[None], np.asarray(landmark)[None], noise[None])[0]

    def measure_with_noise(self, poses, landmarks, noise) -> np.ndarray:
        """``measure`` of N pose-landmark pairs given its standard normals: (N, 3), (N, 2), (N, 2) -> (N, 2)."""
        arrays = (contiguous(np.asarray(array, dtype=float)) for array in (poses, landmarks, noise))
        return noisy_ranges_bearings(*arrays, self.noise_stds)


CONFIG_KEYS = {  # the env config key of each attribute: the noise's by their own names, the coverage's sensor_*
    **{attribute: attribute for attribute in ("range_std_m", "range_std_per_m", "bearing_std_rad")},
    "max_range_m": "sensor_max_range_m",
    "fov_rad": "sensor_fov_rad",
}


def range_bearing_sensor_from_config(config: dict, owner: str) -> RangeBearingSensor:
    """The sensor described by an env config's ``CONFIG_KEYS``; a bad value's ``ValueError`` names its key."""
    return from_config(RangeBearingSensor, config, CONFIG_KEYS, owner)


@kernel
def noise_covariances(ranges, range_std_m, range_std_per_m, bearing_std_rad):
    """``RangeBearingSensor.noise_covariance`` at each range (M,): (M, 2, 2), the range std growing with the range."""
    covariance = np.zeros((len(ranges), 2, 2))
    for index in range(len(ranges)):
        range_std = range_std_m + range_std_per_m * ranges[index]
        covariance[index, 0, 0] = range_std * range_std
        covariance[index, 1, 1] = bearing_std_rad * bearing_std_rad
    return covariance


@kernel
def noisy_ranges_bearings(poses, landmarks, noise, noise_stds):
    """``RangeBearingSensor.measure_with_noise`` of the sensor's ``noise_stds`` (``noisy_range_bearing`` per row)."""
    measured = np.empty((len(poses), 2))
    for i in range(len(poses)):
        dx, dy = landmarks[i, 0] - poses[i, 0], landmarks[i, 1] - poses[i, 1]
        noisy_range_bearing(dx, dy, poses[i, 2], noise_stds, noise[i], measured[i])
    return measured


@inline
def noisy_range_bearing(dx, dy, heading, noise_stds, noise, out):
    """The noisy ``[range, bearing]`` into ``out`` of a landmark ``(dx, dy)`` [m] off a pose of ``heading`` [rad],
    given the two standard normals ``noise`` and the sensor's ``noise_stds``; the range noise grows with the range."""
    distance = math.hypot(dx, dy)
    out[0] = distance + (noise_stds[0] + noise_stds[1] * distance) * noise[0]
    out[1] = wrap(math.atan2(dy, dx) - heading + noise_stds[2] * noise[1])
