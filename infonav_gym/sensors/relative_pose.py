"""Relative-pose sensing of a teammate: its range, bearing and relative heading (laser- or vision-based)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from infonav_gym.compiled import contiguous, inline, kernel, stacked
from infonav_gym.config import check_number
from infonav_gym.estimation.models import relative_pose
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.sensors.range_bearing import MIN_BEARING_STD_RAD, RangeBearingSensor


@dataclass(frozen=True)
class RelativePoseSensor:
    """Measures ``[range, bearing, relative heading]`` of a teammate's pose from the observer's."""

    range_bearing: RangeBearingSensor  # noise, range and field of view of the first two
    heading_std_rad: float  # relative-heading noise at zero range [rad]
    heading_std_per_m: float = 0.0  # its growth per metre of range [rad/m]

    def __post_init__(self):
        owner = type(self).__name__
        check_number(owner, "heading_std_rad", self.heading_std_rad, MIN_BEARING_STD_RAD, math.pi, unit="rad")
        check_number(owner, "heading_std_per_m", self.heading_std_per_m, 0.0, 0.1, unit="rad/m")

    @property
    def max_range_m(self) -> float:
        return self.range_bearing.max_range_m

    def noise_parameters(self) -> np.ndarray:
        """``[range_std_m, range_std_per_m, bearing_std_rad, heading_std_rad, heading_std_per_m]`` (5,)."""
        return np.array([*self.range_bearing.noise_stds, self.heading_std_rad, self.heading_std_per_m])

    def noise_covariance(self, ranges) -> np.ndarray:
        """Measurement noise covariance at each range: (M,) -> (M, 3, 3)."""
        return noise_covariances(self.noise_parameters(), np.atleast_1d(ranges))

    def in_coverage(self, measurements) -> np.ndarray:
        """Which noise-free ``[range, bearing, ...]`` rows fall inside the range and field of view."""
        return self.range_bearing.in_coverage(measurements)

    def measure(self, observer_pose, target_pose, np_random: np.random.Generator) -> np.ndarray:
        """A noisy ``[range, bearing, relative heading]`` of ``target_pose`` seen from ``observer_pose``."""
        truth = relative_pose(observer_pose, target_pose)
        return noisy_relative_poses(truth, self.noise_parameters()[None], np_random)[0]


def noise_standard_deviations(parameters, ranges) -> np.ndarray:
    """Noise standard deviations ``[range, bearing, relative heading]`` (M, 3) at ``ranges`` (M,) [m] of sensors'
    ``noise_parameters()`` (5,) or one row per range (M, 5)."""
    ranges = np.asarray(ranges, dtype=float)
    return standard_deviations(stacked(np.reshape(parameters, (-1, 5)), (len(ranges), 5)), contiguous(ranges))


@kernel
def standard_deviations(parameters, ranges):
    """``noise_standard_deviations`` of one parameter row (M, 5) per range (M,)."""
    std = np.empty((len(ranges), 3))
    for m in range(len(ranges)):
        row_standard_deviations(parameters[m], ranges[m], std[m])
    return std


@inline
def row_standard_deviations(sensor, range_m, std):
    """Write the noise stds (3,) of a sensor's ``noise_parameters()`` (5,) at ``range_m`` into ``std``."""
    std[0] = sensor[0] + sensor[1] * range_m
    std[1] = sensor[2]
    std[2] = sensor[3] + sensor[4] * range_m


@inline
def relative_pose_measured(truth, sensor, noise, measured):
    """Write one row of ``relative_poses_with_noise`` into ``measured`` (3,): ``truth`` (3,), the sensor's
    ``noise_parameters()`` (5,), its standard normals ``noise`` (3,); usable inside kernels."""
    row_standard_deviations(sensor, truth[0], measured)
    measured[0] = truth[0] + measured[0] * noise[0]
    measured[1] = wrap(truth[1] + measured[1] * noise[1])
    measured[2] = wrap(truth[2] + measured[2] * noise[2])


def noise_covariances(parameters, ranges) -> np.ndarray:
    """Diagonal noise covariances (M, 3, 3) at ``ranges`` (see ``noise_standard_deviations``)."""
    covariance = np.zeros((len(ranges), 3, 3))
    covariance[:, _DIAGONAL, _DIAGONAL] = noise_standard_deviations(parameters, ranges) ** 2
    return covariance


def noisy_relative_poses(truth, parameters, np_random: np.random.Generator) -> np.ndarray:
    """Noisy measurements of the true relative poses (M, 3), per-row sensor ``parameters`` (M, 5); draws (M, 3)."""
    return relative_poses_with_noise(truth, parameters, np_random.standard_normal(truth.shape))


def relative_poses_with_noise(truth, parameters, noise) -> np.ndarray:
    """``noisy_relative_poses`` given its standard normals ``noise`` (M, 3)."""
    truth = np.asarray(truth, dtype=float)
    parameters = stacked(np.reshape(parameters, (-1, 5)), (len(truth), 5))
    return measured_relative_poses(contiguous(truth), parameters, contiguous(np.asarray(noise, dtype=float)))


@kernel
def measured_relative_poses(truth, parameters, noise):
    """``relative_poses_with_noise`` of one parameter row (M, 5) per true relative pose (M, 3)."""
    measured = np.empty(truth.shape)
    for m in range(len(truth)):
        relative_pose_measured(truth[m], parameters[m], noise[m], measured[m])
    return measured


_DIAGONAL = np.arange(3)


RELATIVE_POSE_SENSORS = {
    # Scanning laser range finder: long range, all around, accurate range; the teammate's outline gives its orientation.
    "laser": RelativePoseSensor(
        RangeBearingSensor(
            range_std_m=0.05,
            range_std_per_m=0.0,
            bearing_std_rad=math.radians(1.0),
            max_range_m=30.0,
            fov_rad=2 * math.pi,
        ),
        heading_std_rad=math.radians(3.0),
    ),
    # Camera (vision-based): narrow field of view, shorter range; range and orientation from the image, worse farther.
    "vision": RelativePoseSensor(
        RangeBearingSensor(
            range_std_m=0.02,
            range_std_per_m=0.05,
            bearing_std_rad=math.radians(0.5),
            max_range_m=15.0,
            fov_rad=math.radians(60.0),
        ),
        heading_std_rad=math.radians(2.0),
        heading_std_per_m=math.radians(0.5),
    ),
}
