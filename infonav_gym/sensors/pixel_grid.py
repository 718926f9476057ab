"""The equiangular pixel grid of the LADAR and the camera on a pan-tilt platform.

Pixel ``(r, c)`` (row 0 on top, column 0 leftmost) looks at elevation ``vfov/2 - (r + 1/2) vfov/rows - tilt`` and
azimuth ``heading + pan + hfov/2 - (c + 1/2) hfov/columns`` (counterclockwise). Tilt lowers every row alike, so
each column's rays stay in one vertical plane: ``Terrain.cast_rays`` casts the image in one call.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.config import ParameterError, check_integer, check_number

MAX_ROWS = 1080  # image rows at most (full HD)
MAX_COLUMNS = 1920  # image columns at most (full HD)
MAX_MOUNT_HEIGHT_M = 100.0  # [m]
MAX_SENSOR_RANGE_M = 1000.0  # [m]


def check_pose(vehicle_pose) -> np.ndarray:
    """``vehicle_pose`` as a finite float array ``[x, y, heading]``, or ``ValueError``."""
    pose = np.asarray(vehicle_pose, dtype=float)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"vehicle_pose must be finite [x, y, heading] [m, m, rad], got {vehicle_pose!r}")
    return pose


def unit_directions(azimuth_rad: np.ndarray, elevation_rad: np.ndarray) -> np.ndarray:
    """World unit vectors (R, C, 3) for column azimuths (C,) and row elevations (R,)."""
    cos_elevation, sin_elevation = np.cos(elevation_rad).reshape(-1, 1), np.sin(elevation_rad).reshape(-1, 1)
    cos_azimuth, sin_azimuth = np.cos(azimuth_rad).reshape(-1), np.sin(azimuth_rad).reshape(-1)
    up = np.broadcast_to(sin_elevation, (sin_elevation.shape[0], cos_azimuth.shape[0]))
    return np.stack([cos_elevation * cos_azimuth, cos_elevation * sin_azimuth, up], axis=-1)


def check_pan_tilt(sensor: str, pan_rad: float, tilt_rad: float, vertical_fov_rad: float) -> None:
    """``ParameterError`` (naming ``sensor``) unless the pan is in [-2 pi, 2 pi], the tilt keeping rows off vertical."""
    check_number(sensor, "pan_rad", pan_rad, -2 * math.pi, 2 * math.pi, unit="rad")
    if not (math.isfinite(tilt_rad) and abs(tilt_rad) + vertical_fov_rad / 2 < math.pi / 2):
        requirement = (
            f"such that |tilt_rad| + vertical_fov_rad / 2 stays below pi/2, the rows short of vertical "
            f"(vertical_fov_rad={vertical_fov_rad!r})"
        )
        raise ParameterError(sensor, "tilt_rad", requirement, tilt_rad)


class PanTiltGrid:
    """Pixel angles and checks of a sensor dataclass with ``rows``, ``columns``, fields of view in (0, pi) [rad],
    ``mount_height_m`` above the ground, ``max_range_m``, ``pan_rad`` (left positive) and ``tilt_rad`` (down
    positive); ``SENSOR_NAME`` names it in errors."""

    SENSOR_NAME = "sensor"

    def _check_image_size(self) -> None:
        """``ParameterError`` naming the field unless ``rows`` is in [1, 1080] and ``columns`` in [1, 1920]."""
        check_integer(self.SENSOR_NAME, "rows", self.rows, 1, MAX_ROWS)
        check_integer(self.SENSOR_NAME, "columns", self.columns, 1, MAX_COLUMNS)

    def _check_grid(self) -> None:
        """``ParameterError`` naming the field unless the grid, mount, range, pan and tilt are valid."""
        name = self.SENSOR_NAME
        self._check_image_size()
        for key in ("horizontal_fov_rad", "vertical_fov_rad"):
            check_number(name, key, getattr(self, key), 0.0, math.pi, open_low=True, open_high=True, unit="rad")
        check_number(name, "mount_height_m", self.mount_height_m, 0.0, MAX_MOUNT_HEIGHT_M, open_low=True, unit="m")
        check_number(name, "max_range_m", self.max_range_m, 0.0, MAX_SENSOR_RANGE_M, open_low=True, unit="m")
        check_pan_tilt(name, self.pan_rad, self.tilt_rad, self.vertical_fov_rad)

    def pixel_angles(
        self, pan_rad: float | None = None, tilt_rad: float | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Column azimuths from the heading (columns,) and row elevations (rows,) [rad]; ``pan_rad`` / ``tilt_rad``
        override the platform's for this call."""
        pan_rad = self.pan_rad if pan_rad is None else float(pan_rad)
        tilt_rad = self.tilt_rad if tilt_rad is None else float(tilt_rad)
        check_pan_tilt(self.SENSOR_NAME, pan_rad, tilt_rad, self.vertical_fov_rad)
        column_step = self.horizontal_fov_rad / self.columns
        row_step = self.vertical_fov_rad / self.rows
        azimuth = pan_rad + self.horizontal_fov_rad / 2 - (np.arange(self.columns) + 0.5) * column_step
        return azimuth, self.vertical_fov_rad / 2 - (np.arange(self.rows) + 0.5) * row_step - tilt_rad
