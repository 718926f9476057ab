"""Scanning LADAR on a pan-tilt platform: a range image of a 2.5D ``Terrain`` (the paper's Section IV).

Pixel convention: row 0 is the top row (highest elevation), column 0 the leftmost (largest
azimuth, azimuths counterclockwise). Pixel ``(r, c)`` looks along the centre of its angular
cell: elevation ``vertical_fov/2 - (r + 1/2) * vertical_fov/rows - tilt`` above the horizontal
and azimuth ``heading + pan + horizontal_fov/2 - (c + 1/2) * horizontal_fov/columns``. The tilt
lowers every row's elevation by the same angle (a nodding scanner), so each column's rays stay in
one vertical plane.
"""

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
    """One range image.

    Attributes:
        ranges_m: measured range per pixel (rows, columns), float32 [m]; ``max_range_m`` where no return.
        no_return: True where nothing was hit within ``max_range_m`` (rows, columns).
        azimuth_rad: azimuth of each column relative to the vehicle heading, pan included (columns,) [rad].
        elevation_rad: elevation of each row above the horizontal, tilt included (rows,) [rad].
        vehicle_pose: true ``[x, y, heading]`` of the vehicle when the scan was taken [m, m, rad].
        sensor_position_m: ``(x, y, z)`` of the optical centre when the scan was taken [m].
        max_range_m: the sensor's maximum range [m].
        attitude_rad: the vehicle's ``(roll, pitch)`` when the scan was taken [rad] (see
            ``infonav_gym.world.attitude``); azimuths and elevations are in its body frame.
        range_std_m: standard deviation of the range noise the scan was taken with [m] (its ``Ladar``'s).
    """

    ranges_m: np.ndarray
    no_return: np.ndarray
    azimuth_rad: np.ndarray
    elevation_rad: np.ndarray
    vehicle_pose: np.ndarray
    sensor_position_m: np.ndarray
    max_range_m: float
    attitude_rad: tuple[float, float] = (0.0, 0.0)
    range_std_m: float = DEFAULT_RANGE_STD_M

    @property
    def world_from_sensor(self) -> np.ndarray:
        """The (4, 4) transform from the scan's body frame at the optical centre to the world frame."""
        roll, pitch = self.attitude_rad
        return rigid_transform(rotation_matrix(roll, pitch, self.vehicle_pose[2]), self.sensor_position_m)


@dataclass(frozen=True)
class Ladar(PanTiltGrid):
    """A LADAR producing a ``rows x columns`` range image (defaults: the XUV's 32 x 180, 20 x 80 degrees).

    Attributes:
        rows: image rows.
        columns: image columns.
        vertical_fov_rad: vertical field of view [rad], in (0, pi).
        horizontal_fov_rad: horizontal field of view [rad], in (0, pi).
        mount_height_m: optical centre above the ground under the vehicle [m].
        max_range_m: farthest return [m].
        range_std_m: standard deviation of the Gaussian range noise [m], in [0, 10].
        tilt_rad: depression of the optical axis, positive = looking down [rad].
        pan_rad: azimuth of the optical axis from the vehicle heading, positive = left [rad].
    """

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
        """Range image of ``terrain`` seen from ``vehicle_pose`` ``[x, y, heading]`` [m, m, rad].

        The optical centre is ``mount_height_m`` along the body's up axis above the ground
        under the vehicle, whose ``(roll, pitch)`` is ``attitude_rad`` (e.g. from
        ``terrain_attitude``). Each pixel's range is the first hit of its ray plus Gaussian
        noise from ``np_random``, clipped to ``[0, max_range_m]``; pixels without a hit read
        ``max_range_m``. A level vehicle's columns are vertical planes, cast together; a rolled
        or pitched one's rays are cast one by one (about 15 times slower).
        """
        pose = check_pose(vehicle_pose)
        roll, pitch = (float(angle) for angle in attitude_rad)
        if not (math.isfinite(roll) and math.isfinite(pitch) and max(abs(roll), abs(pitch)) < math.pi / 2):
            raise ValueError(f"LADAR attitude_rad must be finite (roll, pitch) within +-pi/2, got {attitude_rad!r}")
        azimuth, elevation = self.pixel_angles(pan_rad, tilt_rad)
        rotation = rotation_matrix(roll, pitch, pose[2])
        ground = np.array([pose[0], pose[1], float(terrain.height_at(pose[:2]))])
        sensor_position = ground + rotation[:, 2] * self.mount_height_m
        if roll == 0.0 and pitch == 0.0:
            hits = terrain.cast_rays(sensor_position, pose[2] + azimuth, elevation, self.max_range_m)
            range_m = hits.range_m
        else:
            directions = unit_directions(azimuth, elevation) @ rotation.T
            world_azimuth = np.arctan2(directions[..., 1], directions[..., 0]).ravel()
            world_elevation = np.arcsin(np.clip(directions[..., 2], -1.0, 1.0)).reshape(1, -1)
            hits = terrain.cast_rays(sensor_position, world_azimuth, world_elevation, self.max_range_m)
            range_m = hits.range_m.reshape(self.rows, self.columns)
        noise = self.range_std_m * np_random.standard_normal(range_m.shape)
        no_return = ~np.isfinite(range_m)
        noisy = np.clip(range_m + noise, 0.0, self.max_range_m)
        ranges = np.where(no_return, self.max_range_m, noisy).astype(np.float32)
        return LadarScan(
            ranges,
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
    """The paper's display convention: uint8 (rows, columns), 0 at range 0 (dark = near) to 255 at max range.

    Gray levels are linear in range; pixels without a return are 255.
    """
    levels = np.rint(255.0 * np.clip(scan.ranges_m / scan.max_range_m, 0.0, 1.0)).astype(np.uint8)
    levels[scan.no_return] = 255
    return levels


def sensor_points(scan: LadarScan) -> np.ndarray:
    """Points (N, 3) [m] of the pixels with a return in the scan's body frame at the optical centre, row-major."""
    returns = ~scan.no_return
    directions = unit_directions(scan.azimuth_rad, scan.elevation_rad)
    return directions[returns] * scan.ranges_m[returns, None].astype(float)


def point_cloud(scan: LadarScan, vehicle_pose=None) -> np.ndarray:
    """World points (N, 3) [m] of the pixels with a return, in row-major pixel order.

    Args:
        scan: the range image.
        vehicle_pose: ``[x, y, heading]`` to place the points from (e.g. an estimate, for
            registration); default: the true pose of the scan. The sensor's elevation and the
            vehicle's roll and pitch are the scan's in either case.
    """
    pose = scan.vehicle_pose if vehicle_pose is None else check_pose(vehicle_pose)
    origin = scan.sensor_position_m + np.append(pose[:2] - scan.vehicle_pose[:2], 0.0)
    if scan.attitude_rad == (0.0, 0.0):
        directions = unit_directions(pose[2] + scan.azimuth_rad, scan.elevation_rad)
        returns = ~scan.no_return
        return origin + directions[returns] * scan.ranges_m[returns, None].astype(float)
    return origin + sensor_points(scan) @ rotation_matrix(*scan.attitude_rad, pose[2]).T
