"""Points of a range image, for registration: sensor frame x forward (azimuth 0), y left, z up."""

from __future__ import annotations

import numpy as np

from infonav_gym.registration.icp import check_rigid_transform
from infonav_gym.sensors.pixel_grid import unit_directions


def range_image_to_points(ranges_m, azimuth_rad, elevation_rad, no_return=None, sensor_pose=None) -> np.ndarray:
    """Points (N, 3) [m] of the pixels with a return (row-major): ``ranges_m[r, c]`` (R, C) along column azimuth
    ``azimuth_rad[c]`` (C,) and row elevation ``elevation_rad[r]`` (R,) [rad] in the sensor frame, moved by the
    (4, 4) rigid ``sensor_pose`` if given. ``no_return`` (R, C) defaults to the non-finite ranges; ``ValueError``
    for mismatched shapes, a non-finite return or a non-rigid pose."""
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
