"""Grayscale camera on a pan-tilt platform: a Lambertian-shaded uint8 image of a 2.5D ``Terrain``.

The LADAR's equiangular pixel grid (``pixel_grid``), which approximates a pinhole (angular spacing differs by at most
~30 % at 60 degrees; the radiometry the histogram entropy measures is unaffected). A ray hitting nothing within
``max_range_m`` sees the sky, ``exposure * sky_luminance``; a hit reads ``exposure * albedo * (ambient + (1 - ambient) *
max(0, n . sun))``. Gaussian noise [gray levels] is added, then rounded and clipped to 0..255.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from infonav_gym.compiled import contiguous
from infonav_gym.config import check_number
from infonav_gym.sensors import camera_kernels
from infonav_gym.sensors.pixel_grid import PanTiltGrid, check_pose, unit_directions
from infonav_gym.world.terrain import MATERIALS, Terrain

_TEXTURE_OCTAVES = ((0.5, 0.5), (2.0, 0.3), (8.0, 0.2))  # (cell [m], weight) of the ground value noise
MAX_SKY_LUMINANCE = 100.0
MAX_EXPOSURE = 1e6  # [gray levels]
MAX_NOISE_STD = 1000.0  # [gray levels]
_TEXTURE = (  # what camera_kernels.texture takes: the lattice table (fixed), the octaves' cells [m] and weights
    np.random.default_rng(20240917).random((len(_TEXTURE_OCTAVES), camera_kernels.TEXTURE_TABLE_SIZE**2)),
    np.array([cell_m for cell_m, _ in _TEXTURE_OCTAVES]),
    np.array([weight for _, weight in _TEXTURE_OCTAVES]),
)


def ground_texture(xy) -> np.ndarray:
    """Deterministic texture in [-1, 1] of world positions ``xy`` (..., 2) [m]: value noise in ``_TEXTURE_OCTAVES``."""
    points = np.asarray(xy, dtype=float)
    return camera_kernels.textures(contiguous(points.reshape(-1, 2)), *_TEXTURE).reshape(points.shape[:-1])


@dataclass(frozen=True)
class Camera(PanTiltGrid):
    """A grayscale camera producing a ``rows x columns`` uint8 image; the grid's fields as ``PanTiltGrid``'s."""

    SENSOR_NAME = "camera"

    rows: int = 120
    columns: int = 160
    horizontal_fov_rad: float = math.radians(60.0)
    vertical_fov_rad: float | None = None  # None: a square-pixel pinhole's, 2 atan(tan(h/2) rows/columns)
    mount_height_m: float = 2.0
    tilt_rad: float = math.radians(5.0)
    pan_rad: float = 0.0
    max_range_m: float = 100.0  # far plane: pixels beyond it show sky [m]
    sun_azimuth_rad: float = math.radians(135.0)  # world azimuth towards the sun, from +x [rad]
    sun_elevation_rad: float = math.radians(45.0)  # in (0, pi/2] [rad]
    sky_luminance: float = 1.1  # relative to a white surface lit head-on
    ground_albedo: float = 0.45  # mean reflectances, in [0, 1]
    vegetation_albedo: float = 0.2
    rock_albedo: float = 0.5
    building_albedo: float = 0.75
    ground_texture_contrast: float = 0.5  # albedo at xy: ground_albedo * (1 + contrast * ground_texture(xy))
    ambient: float = 0.3  # diffuse fraction of the light
    exposure: float = 200.0  # gray level of a white surface lit head-on
    noise_std: float = 2.0  # [gray levels]

    def __post_init__(self):
        self._check_image_size()
        if self.vertical_fov_rad is None and 0 < self.horizontal_fov_rad < math.pi:
            derived = 2 * math.atan(math.tan(self.horizontal_fov_rad / 2) * self.rows / self.columns)
            object.__setattr__(self, "vertical_fov_rad", derived)
        self._check_grid()
        name = self.SENSOR_NAME
        check_number(name, "sun_azimuth_rad", self.sun_azimuth_rad, -2 * math.pi, 2 * math.pi, unit="rad")
        check_number(name, "sun_elevation_rad", self.sun_elevation_rad, 0.0, math.pi / 2, open_low=True, unit="rad")
        for key in ("ground_albedo", "vegetation_albedo", "rock_albedo", "building_albedo", "ambient"):
            check_number(name, key, getattr(self, key), 0.0, 1.0)
        check_number(name, "ground_texture_contrast", self.ground_texture_contrast, 0.0, 1.0, open_high=True)
        check_number(name, "sky_luminance", self.sky_luminance, 0.0, MAX_SKY_LUMINANCE)
        check_number(name, "exposure", self.exposure, 0.0, MAX_EXPOSURE)
        check_number(name, "noise_std", self.noise_std, 0.0, MAX_NOISE_STD, unit="gray levels")

    @property
    def sun_direction(self) -> np.ndarray:
        """World unit vector (3,) towards the sun."""
        return unit_directions(np.array([self.sun_azimuth_rad]), np.array([self.sun_elevation_rad]))[0, 0]

    @property
    def sky_level(self) -> float:
        """Noise-free gray level of the sky, before saturation."""
        return self.exposure * self.sky_luminance

    def albedo(self, material_index: int) -> float:
        """Mean reflectance of ``MATERIALS[material_index]``."""
        return getattr(self, f"{MATERIALS[material_index]}_albedo")

    @cached_property
    def _radiometry(self) -> tuple:
        """What ``camera_kernels.shade`` takes of this camera (fixed: the dataclass is frozen)."""
        albedos = np.array([self.albedo(index) for index in range(len(MATERIALS))], dtype=float)
        scalars = (self.ambient, self.exposure, self.ground_texture_contrast, self.sky_level)
        return albedos, self.sun_direction, *(float(value) for value in scalars)

    def radiance(
        self, terrain: Terrain, vehicle_pose, pan_rad: float | None = None, tilt_rad: float | None = None
    ) -> np.ndarray:
        """Noise-free, unclipped gray levels (rows, columns) float64 of ``terrain`` from ``vehicle_pose``."""
        pose = check_pose(vehicle_pose)
        azimuth, elevation = self.pixel_angles(pan_rad, tilt_rad)
        origin = np.array([pose[0], pose[1], float(terrain.height_at(pose[:2])) + self.mount_height_m])
        rays = origin, pose[2] + azimuth, elevation
        hits = terrain.cast_rays(*rays, self.max_range_m)
        return camera_kernels.shade(
            terrain.arrays, *rays, hits.range_m, hits.material_index, hits.obstacle_index, self._radiometry, _TEXTURE
        )

    def capture(
        self,
        terrain: Terrain,
        vehicle_pose,
        np_random: np.random.Generator,
        pan_rad: float | None = None,
        tilt_rad: float | None = None,
    ) -> np.ndarray:
        """Grayscale uint8 image (rows, columns) of ``terrain`` from ``vehicle_pose`` ``[x, y, heading]``; noise is
        drawn for every pixel even at ``noise_std`` 0, so the generator advances the same way."""
        levels = self.radiance(terrain, vehicle_pose, pan_rad, tilt_rad)
        levels += np_random.standard_normal(levels.shape) * self.noise_std
        return np.clip(np.rint(levels, out=levels), 0, 255, out=levels).astype(np.uint8)
