"""Consecutive LADAR frames of a vehicle pitching and rolling over terrain, with the true and odometry motion.

Points are in each frame's body frame at the optical centre (``sensor_points``); registering the current frame
(source) onto the previous (target) estimates ``previous_from_current``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from infonav_gym.config import check_number
from infonav_gym.geometry import invert_transform, rigid_transform, transform_error
from infonav_gym.sensors.ladar import Ladar, LadarScan
from infonav_gym.world.attitude import terrain_attitude
from infonav_gym.world.terrain import Terrain
from infonav_gym.world.terrain_scenario import terrain_loop
from infonav_gym.world.world import World

MOTION_AXES = ("x", "y", "z", "roll", "pitch", "yaw")  # order of motion vectors and covariances
DEFAULT_ODOMETRY_STD = (0.1, 0.1, 0.05, math.radians(0.5), math.radians(0.5), math.radians(1.0))  # [m] x3, [rad] x3
MAX_ODOMETRY_STD = (10.0, 10.0, 10.0, math.pi / 4, math.pi / 4, math.pi / 4)  # [m] x3, [rad] x3
ODOMETRY_STD_UNITS = ("m", "m", "m", "rad", "rad", "rad")
LEVER_ARM_M = 10.0  # a rotation error counts as the displacement it causes this far away [m]
# the registration of frame pairs (RangeRegistration-v0, Fig. 6), by recall first: results/registration_recall.md
FRAME_PAIR_ICP = {
    "method": "gicp",
    "robust_kernel": "tukey",
    "kernel_scale": 0.094,  # [m]: 4.685 (Tukey's 95%-efficiency constant) times the LADAR's 0.02 m range noise
    "max_correspondence_distance": 1.0,  # [m]
}


@dataclass(frozen=True)
class FramePair:
    """Two consecutive range images and the motion between them."""

    previous: LadarScan  # the registration target
    current: LadarScan  # the source
    true_motion: np.ndarray  # previous_from_current (4, 4)
    odometry_motion: np.ndarray  # its dead-reckoning estimate (4, 4), the ICP warm start
    motion_covariance: np.ndarray  # of the odometry error over MOTION_AXES (6, 6) [m^2, rad^2]


def motion_between(previous: LadarScan, current: LadarScan) -> np.ndarray:
    """``previous_from_current`` (4, 4): the true motion of the optical centre from one frame to the next."""
    return invert_transform(previous.world_from_sensor) @ current.world_from_sensor


def perturbed_motion(motion: np.ndarray, error: np.ndarray) -> np.ndarray:
    """``motion`` followed by the small motion ``error`` = (x, y, z [m], rotation vector [rad]) in the later frame."""
    return motion @ rigid_transform(Rotation.from_rotvec(error[3:]).as_matrix(), error[:3])


def registration_error(estimate: np.ndarray, truth: np.ndarray, lever_arm_m: float = LEVER_ARM_M) -> float:
    """How wrong a motion estimate is [m]: ``sqrt(e_t^2 + (lever_arm_m * e_r)^2)``, translation error ``e_t`` and
    how far the rotation error ``e_r`` moves a point ``lever_arm_m`` away (a typical LADAR range)."""
    translation, rotation = transform_error(estimate, truth)
    return math.hypot(translation, lever_arm_m * rotation)


def scan_on_terrain(ladar: Ladar, terrain: Terrain, vehicle_pose, np_random: np.random.Generator) -> LadarScan:
    """A frame from ``vehicle_pose`` with the vehicle's roll and pitch taken from the ground under its wheels."""
    return ladar.scan(terrain, vehicle_pose, np_random, attitude_rad=terrain_attitude(terrain, vehicle_pose))


def check_odometry_std(odometry_std) -> np.ndarray:
    """``odometry_std`` as a float array (6,), or ``ValueError`` (a ``ParameterError`` naming the axis) unless
    each entry is in (0, ``MAX_ODOMETRY_STD``] (10 m along x, y, z; pi/4 rad about them)."""
    std = np.asarray(odometry_std, dtype=float)
    if std.shape != (6,):
        raise ValueError(f"odometry_std must be 6 numbers, one per axis {MOTION_AXES}, got {odometry_std!r}")
    for axis, value, high, unit in zip(MOTION_AXES, std.tolist(), MAX_ODOMETRY_STD, ODOMETRY_STD_UNITS):
        check_number("frame_pair odometry_std", axis, value, 0.0, high, open_low=True, unit=unit)
    return std


def frame_pair(
    previous: LadarScan, current: LadarScan, np_random: np.random.Generator, odometry_std=DEFAULT_ODOMETRY_STD
) -> FramePair:
    """The pair with its true motion and an odometry estimate, its error drawn from ``np_random`` with standard
    deviations ``odometry_std`` along ``MOTION_AXES``."""
    std = check_odometry_std(odometry_std)
    truth = motion_between(previous, current)
    odometry = perturbed_motion(truth, std * np_random.standard_normal(6))
    return FramePair(previous, current, truth, odometry, np.diag(std**2))


def terrain_frame_pair(
    np_random: np.random.Generator, roughness: float = 0.7, drive_steps: int = 4, time_step_s: float = 0.5
) -> FramePair:
    """Frames ``drive_steps`` and ``drive_steps + 1`` of a vehicle driving a random ``terrain_loop`` at 2 m/s."""
    scene = terrain_loop(np_random, roughness=roughness)
    world = World()
    world.reset(scene.scenario)
    for _ in range(drive_steps):
        world.step(time_step_s)
    ladar = Ladar()
    previous = scan_on_terrain(ladar, scene.terrain, world.pose, np_random)
    world.step(time_step_s)
    return frame_pair(previous, scan_on_terrain(ladar, scene.terrain, world.pose, np_random), np_random)
