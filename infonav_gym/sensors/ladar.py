"""Scanning LADAR on a pan-tilt platform (pixels: ``pixel_grid``): a range image of a 2.5D ``Terrain`` (Section IV)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from infonav_gym.config import check_number
from infonav_gym.geometry import rigid_transform, rotation_matrix
from infonav_gym.sensors.pixel_grid import PanTiltGrid, check_pose, unit_directions
from infonav_gym.world.terrain import Terrain

DEFAULT_RANGE_STD_M = 0.02  # range noise of the XUV's LADAR [m]
MAX_RANGE_STD_M = 10.0  # [m]


@dataclass(frozen=True)
class LadarScan:
    """One range image; angles in the vehicle's body frame, pan and tilt included."""

    ranges_m: np.ndarray  # (rows, columns) float32 [m]; max_range_m where no return
    no_return: np.ndarray  # (rows, columns) bool
    azimuth_rad: np.ndarray  # per column, from the vehicle heading (columns,) [rad]
    elevation_rad: np.ndarray  # per row (rows,) [rad]
    vehicle_pose: np.ndarray  # true [x, y, heading] [m, m, rad]
    sensor_position_m: np.ndarray  # the optical centre (x, y, z) [m]
    max_range_m: float
    attitude_rad: tuple[float, float] = (0.0, 0.0)  # the vehicle's (roll, pitch) [rad]
    range_std_m: float = DEFAULT_RANGE_STD_M  # its Ladar's range noise [m]

    @property
    def world_from_sensor(self) -> np.ndarray:
        """The (4, 4) transform from the scan's body frame at the optical centre to the world frame."""
        roll, pitch = self.attitude_rad
        return rigid_transform(rotation_matrix(roll, pitch, self.vehicle_pose[2]), self.sensor_position_m)


@dataclass(frozen=True)
class Ladar(PanTiltGrid):
    """A LADAR producing a ``rows x columns`` range image (defaults: the XUV's 32 x 180, 20 x 80 degrees); the
    grid's fields as ``PanTiltGrid``'s, ``range_std_m`` the Gaussian range noise [m] in [0, 10]."""

    SENSOR_NAME = "LADAR"

    rows: int = 32
    columns: int = 180
    vertical_fov_rad: float = math.radians(20.0)
    horizontal_fov_rad: float = math.radians(80.0)
    mount_height_m: float = 2.0
    max_range_m: float = 60.0
    range_std_m: float = DEFAULT_RANGE_STD_M
    tilt_rad: float = math.radians(10.0)
    pan_rad: float = 0.0

    def __post_init__(self):
        self._check_grid()
        check_number(self.SENSOR_NAME, "range_std_m", self.range_std_m, 0.0, MAX_RANGE_STD_M, unit="m")

    def scan(
        self,
        terrain: Terrain,
        vehicle_pose,
        np_random: np.random.Generator,
        pan_rad: float | None = None,
        tilt_rad: float | None = None,
        attitude_rad=(0.0, 0.0),
    ) -> LadarScan:
        """Range image of ``terrain`` from ``vehicle_pose`` ``[x, y, heading]`` at ``attitude_rad`` (roll, pitch), the
        optical centre ``mount_height_m`` up the body's axis, noisy ranges clipped to ``[0, max_range_m]``. A rolled
        or pitched vehicle's rays are cast one by one (about 15 times slower)."""
        pose = check_pose(vehicle_pose)
        roll, pitch = (float(angle) for angle in attitude_rad)
        if not (math.isfinite(roll) and math.isfinite(pitch) and max(abs(roll), abs(pitch)) < math.pi / 2):
            raise ValueError(f"LADAR attitude_rad must be finite (roll, pitch) within +-pi/2, got {attitude_rad!r}")
        azimuth, elevation = self.pixel_angles(pan_rad, tilt_rad)
        rotation = rotation_matrix(roll, pitch, pose[2])
        ground = np.array([pose[0], pose[1], float(terrain.height_at(pose[:2]))])
        sensor_position = ground + rotation[:, 2] * self.mount_height_m
        if roll == 0.0 and pitch == 0.0:
            range_m = terrain.cast_rays(sensor_position, pose[2] + azimuth, elevation, self.max_range_m).range_m
        else:
            directions = unit_directions(azimuth, elevation) @ rotation.T
            world_azimuth = np.arctan2(directions[..., 1], directions[..., 0]).ravel()
            world_elevation = np.arcsin(np.clip(directions[..., 2], -1.0, 1.0)).reshape(1, -1)
            hits = terrain.cast_rays(sensor_position, world_azimuth, world_elevation, self.max_range_m)
            range_m = hits.range_m.reshape(self.rows, self.columns)
        noisy = np.clip(range_m + self.range_std_m * np_random.standard_normal(range_m.shape), 0.0, self.max_range_m)
        no_return = ~np.isfinite(range_m)
        return LadarScan(
            np.where(no_return, self.max_range_m, noisy).astype(np.float32),
            no_return,
            azimuth,
            elevation,
            pose,
            sensor_position,
            self.max_range_m,
            (roll, pitch),
            self.range_std_m,
        )


def to_display_image(scan: LadarScan) -> np.ndarray:
    """The paper's display: uint8 (rows, columns) linear in range, 0 at 0 (dark = near), 255 at max or no return."""
    levels = np.rint(255.0 * np.clip(scan.ranges_m / scan.max_range_m, 0.0, 1.0)).astype(np.uint8)
    levels[scan.no_return] = 255
    return levels


def sensor_points(scan: LadarScan) -> np.ndarray:
    """Points (N, 3) [m] of the pixels with a return in the scan's body frame at the optical centre, row-major."""
    return _points_along(scan, unit_directions(scan.azimuth_rad, scan.elevation_rad))


def _points_along(scan: LadarScan, directions: np.ndarray) -> np.ndarray:
    returns = ~scan.no_return
    return directions[returns] * scan.ranges_m[returns, None].astype(float)


def point_cloud(scan: LadarScan, vehicle_pose=None) -> np.ndarray:
    """World points (N, 3) [m] of the pixels with a return, row-major, placed from ``vehicle_pose`` (e.g. an
    estimate; default the scan's true pose) at the scan's sensor height, roll and pitch."""
    pose = scan.vehicle_pose if vehicle_pose is None else check_pose(vehicle_pose)
    origin = scan.sensor_position_m + np.append(pose[:2] - scan.vehicle_pose[:2], 0.0)
    if scan.attitude_rad == (0.0, 0.0):
        return origin + _points_along(scan, unit_directions(pose[2] + scan.azimuth_rad, scan.elevation_rad))
    return origin + sensor_points(scan) @ rotation_matrix(*scan.attitude_rad, pose[2]).T
