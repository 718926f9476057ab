"""Points of a range image, for registration: sensor frame x forward (azimuth 0), y left, z up."""

from __future__ import annotations

import numpy as np

from infonav_gym.registration.icp import check_rigid_transform
from infonav_gym.sensors.pixel_grid import unit_directions


def range_image_to_points(ranges_m, azimuth_rad, elevation_rad, no_return=None, sensor_pose=None) -> np.ndarray:
    """Points (N, 3) [m] of the pixels with a return, in row-major pixel order.

    Pixel ``(r, c)`` gives ``ranges_m[r, c] * [cos(el) cos(az), cos(el) sin(az), sin(el)]`` with
    ``el = elevation_rad[r]`` and ``az = azimuth_rad[c]``: the sensor frame, unless ``sensor_pose``
    (a (4, 4) rigid transform from the sensor frame to another) moves them.

    Args:
        ranges_m: (R, C) ranges [m].
        azimuth_rad: (C,) column azimuths, counterclockwise from the sensor's x axis [rad].
        elevation_rad: (R,) row elevations above its x-y plane [rad].
        no_return: (R, C) bool, True where the pixel saw nothing; default: pixels with a non-finite range.
        sensor_pose: optional (4, 4) rigid transform applied to the points.

    Raises:
        ValueError: for mismatched shapes, a non-finite range at a pixel with a return, or a non-rigid pose.
    """
    ranges = np.asarray(ranges_m, dtype=float)
    azimuth, elevation = np.asarray(azimuth_rad, dtype=float), np.asarray(elevation_rad, dtype=float)
    if azimuth.ndim != 1 or elevation.ndim != 1 or ranges.shape != (elevation.size, azimuth.size):
        raise ValueError(
            f"ranges_m must be (rows, columns) = (elevation_rad.size, azimuth_rad.size), got ranges_m "
            f"{ranges.shape}, azimuth_rad {azimuth.shape}, elevation_rad {elevation.shape}"
        )
    returns = np.isfinite(ranges) if no_return is None else ~np.asarray(no_return, dtype=bool)
    if returns.shape != ranges.shape:
        raise ValueError(f"no_return must have the shape of ranges_m {ranges.shape}, got {returns.shape}")
    if not (np.all(np.isfinite(ranges[returns])) and np.all(np.isfinite(azimuth)) and np.all(np.isfinite(elevation))):
        raise ValueError("ranges_m at pixels with a return, azimuth_rad and elevation_rad must be finite")
    points = unit_directions(azimuth, elevation)[returns] * ranges[returns, None]
    if sensor_pose is None:
        return points
    pose = check_rigid_transform(sensor_pose, "sensor_pose")
    return points @ pose[:3, :3].T + pose[:3, 3]
