"""Grayscale camera on a pan-tilt platform: a Lambertian-shaded uint8 image of a 2.5D ``Terrain``.

Pixel model: the same equiangular grid as the ``Ladar`` (see ``infonav_gym.sensors.ladar``).
Row 0 is the top row, column 0 the leftmost; pixel ``(r, c)`` looks at elevation
``vertical_fov/2 - (r + 1/2) * vertical_fov/rows - tilt`` and azimuth
``heading + pan + horizontal_fov/2 - (c + 1/2) * horizontal_fov/columns``. Each column is one
vertical plane, so ``Terrain.cast_rays`` renders the whole image in one vectorized call. This
approximates a pinhole camera: a pinhole's pixels are equally spaced on the image plane (angles
``atan`` of linear offsets) and a tilted pinhole's columns lean off the vertical. At the default
60 degree field of view the angular spacing differs by at most ~30 % between centre and edge, and
the scene's radiometry (what the histogram entropy measures) is unaffected.

Radiometry: a pixel whose ray hits nothing within ``max_range_m`` (a far plane, like haze) sees the
sky, gray level ``exposure * sky_luminance``; a hit pixel reads
``exposure * albedo(material, position) * (ambient + (1 - ambient) * max(0, n . sun))`` with ``n``
the outward surface normal at the hit and ``sun`` the unit vector towards the sun. Gaussian sensor
noise (in gray levels) from ``np_random`` is added, then levels are rounded and clipped to 0..255
(saturation, never wrapping).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from infonav_gym.config import check_number
from infonav_gym.sensors.pixel_grid import PanTiltGrid, check_pose, pixel_directions, unit_directions
from infonav_gym.world.terrain import MATERIALS, Cylinder, Terrain, blend_in_place

_GROUND = MATERIALS.index("ground")
_TEXTURE_OCTAVES = ((0.5, 0.5), (2.0, 0.3), (8.0, 0.2))  # (cell [m], weight) of the ground value noise
_SHADED_PIXELS_PER_BLOCK = 4096  # hit pixels shaded at once: temporaries stay small and cache-resident


MAX_SKY_LUMINANCE = 100.0
MAX_EXPOSURE = 1e6  # [gray levels]
MAX_NOISE_STD = 1000.0  # [gray levels]
_TEXTURE_TABLE_SIZE = 256  # lattice values repeat every 256 cells (128 m at the finest octave)
_TEXTURE_TABLE = np.random.default_rng(20240917).random((len(_TEXTURE_OCTAVES), _TEXTURE_TABLE_SIZE**2))  # fixed


def ground_texture(xy) -> np.ndarray:
    """Deterministic texture of world position ``xy`` (..., 2) [m] -> (...) in [-1, 1].

    Smoothly interpolated value noise in three octaves (0.5 m, 2 m and 8 m cells), so the ground
    looks like patchy soil and grass at any distance and two views of one spot agree.
    """
    points = np.asarray(xy, dtype=float)
    flat = points.reshape(-1, 2)
    total = np.zeros(flat.shape[0])
    for octave, (cell_m, weight) in enumerate(_TEXTURE_OCTAVES):
        value = blend_in_place(*_lattice_corners(_TEXTURE_TABLE[octave], flat[:, 0] / cell_m, flat[:, 1] / cell_m))
        value *= 2
        value -= 1
        value *= weight
        total += value
    return (total / sum(weight for _, weight in _TEXTURE_OCTAVES)).reshape(points.shape[:-1])


def _lattice_corners(table: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, ...]:
    """Lattice values around points ``(x, y)`` in cells and their smoothstep weights, for ``blend_in_place``.

    Lattice point ``(i, j)`` holds ``table[(j % size) * size + i % size]``; overwrites ``x`` and ``y``.
    """
    size = _TEXTURE_TABLE_SIZE
    wrap = size - 1  # & wrap == % size, also for negative cells
    corner_x, corner_y = np.floor(x), np.floor(y)
    column, row = corner_x.astype(np.int64), corner_y.astype(np.int64)
    column &= wrap
    row &= wrap
    row *= size
    next_column = column + 1
    next_column &= wrap
    next_row = row + size
    next_row &= wrap * size
    values = [table.take(r + c) for r in (row, next_row) for c in (column, next_column)]
    weights = []
    for fraction, corner in ((x, corner_x), (y, corner_y)):
        fraction -= corner
        np.multiply(fraction, -2, out=corner)
        corner += 3
        fraction *= fraction
        fraction *= corner  # smoothstep: fraction * fraction * (3 - 2 * fraction)
        weights.append(fraction)
    return (*values, *weights)


def _wall_distances(x, y, low, high) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances of points ``(x, y)`` to boxes' x walls and y walls, broadcast (negative inside)."""
    return np.maximum(x - high[..., 0], low[..., 0] - x), np.maximum(y - high[..., 1], low[..., 1] - y)


def _side_and_cap(points, low, high, centers, radii, is_cylinder) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances of ``points`` (..., 3) to obstacles' side walls and to their cap planes, broadcast."""
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    side = None if np.all(is_cylinder) else np.maximum(*_wall_distances(x, y, low, high))
    if np.any(is_cylinder):
        radial = np.hypot(x - centers[..., 0], y - centers[..., 1]) - radii
        side = radial if side is None else np.where(is_cylinder, radial, side)
    return side, np.maximum(z - high[..., 2], low[..., 2] - z)


def _obstacle_normals(terrain: Terrain, points: np.ndarray, material: np.ndarray) -> np.ndarray:
    """Outward unit normals (N, 3) at obstacle hit points (N, 3) of known material index (N,).

    ``cast_rays`` reports the material, not the obstacle, so each point is attributed to the
    obstacle of that material whose surface is nearest (by the bound ``|max(per-face distance)|``,
    0 on the surface; the first such obstacle on ties); the normal is the cylinder's radial
    direction or its cap's, or the normal of the box face nearest the point.
    """
    count = points.shape[0]
    if count == 0:
        return np.zeros((0, 3))
    obstacles = terrain.cylinders + terrain.boxes
    is_cylinder = np.array([isinstance(o, Cylinder) for o in obstacles])
    centers = np.array([o.center_m if isinstance(o, Cylinder) else (0.0, 0.0) for o in obstacles])
    radii = np.array([o.radius_m if isinstance(o, Cylinder) else 0.0 for o in obstacles])
    low = np.array([(0.0, 0.0, o.bottom_m) if isinstance(o, Cylinder) else o.min_corner_m for o in obstacles])
    high = np.array([(0.0, 0.0, o.top_m) if isinstance(o, Cylinder) else o.max_corner_m for o in obstacles])
    materials = np.array([MATERIALS.index(o.material) for o in obstacles], dtype=material.dtype)
    parameters = (low, high, centers, radii, is_cylinder)
    nearest, on_cap = np.zeros(count, dtype=np.intp), np.zeros(count, dtype=bool)
    for material_index in np.unique(material):  # compare each point with the obstacles of its own material only
        group, candidates = np.flatnonzero(material == material_index), np.flatnonzero(materials == material_index)
        side, cap = _side_and_cap(points[group, None], *(parameter[candidates] for parameter in parameters))
        best = np.abs(np.maximum(side, cap)).argmin(axis=1)
        rows = np.arange(group.size)
        nearest[group], on_cap[group] = candidates[best], cap[rows, best] > side[rows, best]
    middle = 0.5 * (low[nearest] + high[nearest])
    normals = np.zeros((count, 3))
    normals[:, 2] = np.where(on_cap, np.where(points[:, 2] >= middle[:, 2], 1.0, -1.0), 0.0)
    on_cylinder = ~on_cap & is_cylinder[nearest]
    radial = points[on_cylinder, :2] - centers[nearest[on_cylinder]]
    normals[on_cylinder, :2] = radial / np.linalg.norm(radial, axis=1, keepdims=True)
    on_box = ~on_cap & ~is_cylinder[nearest]
    box = points[on_box]
    wall_x, wall_y = _wall_distances(box[:, 0], box[:, 1], low[nearest[on_box]], high[nearest[on_box]])
    on_x = wall_x >= wall_y
    outward = np.where(box[:, :2] >= middle[on_box, :2], 1.0, -1.0)
    normals[on_box, 0] = np.where(on_x, outward[:, 0], 0.0)
    normals[on_box, 1] = np.where(on_x, 0.0, outward[:, 1])
    return normals


@dataclass(frozen=True)
class Camera(PanTiltGrid):
    """A grayscale camera producing a ``rows x columns`` uint8 image (default 120 x 160, 60 degrees wide).

    Attributes:
        rows: image rows.
        columns: image columns.
        horizontal_fov_rad: horizontal field of view [rad], in (0, pi).
        vertical_fov_rad: vertical field of view [rad], in (0, pi); ``None`` derives it from the
            aspect ratio as a pinhole with square pixels would: ``2 atan(tan(h/2) rows/columns)``.
        mount_height_m: optical centre above the ground under the vehicle [m].
        tilt_rad: depression of the optical axis, positive = looking down [rad].
        pan_rad: azimuth of the optical axis from the vehicle heading, positive = left [rad].
        max_range_m: far plane: nothing beyond it is rendered, those pixels show sky [m].
        sun_azimuth_rad: world azimuth towards the sun, counterclockwise from +x [rad], in [-2 pi, 2 pi].
        sun_elevation_rad: elevation of the sun above the horizon [rad], in (0, pi/2].
        sky_luminance: sky brightness relative to a white (albedo 1) surface lit head-on, in [0, 100].
        ground_albedo: mean reflectance of the ground, in [0, 1].
        vegetation_albedo: reflectance of trees, in [0, 1].
        rock_albedo: reflectance of rocks, in [0, 1].
        building_albedo: reflectance of walls and buildings, in [0, 1].
        ground_texture_contrast: relative amplitude of the ground texture, in [0, 1); the ground
            albedo at ``xy`` is ``ground_albedo * (1 + contrast * ground_texture(xy))``; 0 is uniform.
        ambient: fraction of the light that is diffuse (reaches surfaces facing away from the sun), in [0, 1].
        exposure: gray level of a white surface lit head-on (gain), in [0, 1e6].
        noise_std: standard deviation of the Gaussian sensor noise [gray levels], in [0, 1000].
        rows, columns, fields of view, mount height, range, pan and tilt: as checked by ``PanTiltGrid``.
    """

    SENSOR_NAME = "camera"

    rows: int = 120
    columns: int = 160
    horizontal_fov_rad: float = math.radians(60.0)
    vertical_fov_rad: float | None = None
    mount_height_m: float = 2.0
    tilt_rad: float = math.radians(5.0)
    pan_rad: float = 0.0
    max_range_m: float = 100.0
    sun_azimuth_rad: float = math.radians(135.0)
    sun_elevation_rad: float = math.radians(45.0)
    sky_luminance: float = 1.1
    ground_albedo: float = 0.45
    vegetation_albedo: float = 0.2
    rock_albedo: float = 0.5
    building_albedo: float = 0.75
    ground_texture_contrast: float = 0.5
    ambient: float = 0.3
    exposure: float = 200.0
    noise_std: float = 2.0

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

    def radiance(
        self, terrain: Terrain, vehicle_pose, pan_rad: float | None = None, tilt_rad: float | None = None
    ) -> np.ndarray:
        """Noise-free, unclipped gray levels (rows, columns) float64 of ``terrain`` from ``vehicle_pose``."""
        pose = check_pose(vehicle_pose)
        azimuth, elevation = self.pixel_angles(pan_rad, tilt_rad)
        ground_m = float(terrain.height_at(pose[:2]))
        origin = np.array([pose[0], pose[1], ground_m + self.mount_height_m])
        hits = terrain.cast_rays(origin, pose[2] + azimuth, elevation, self.max_range_m)
        levels = np.full(hits.range_m.shape, self.sky_level)
        hit_pixels = np.flatnonzero(np.isfinite(hits.range_m))
        for start in range(0, hit_pixels.size, _SHADED_PIXELS_PER_BLOCK):
            pixels = hit_pixels[start : start + _SHADED_PIXELS_PER_BLOCK]
            rows, columns = np.divmod(pixels, hits.range_m.shape[1])
            directions = pixel_directions(pose[2] + azimuth, elevation, rows, columns)
            points = origin + directions * hits.range_m.ravel()[pixels, None]
            levels.ravel()[pixels] = self._shade(terrain, points, hits.material_index.ravel()[pixels])
        return levels

    def _shade(self, terrain: Terrain, points: np.ndarray, material: np.ndarray) -> np.ndarray:
        """Noise-free gray levels (N,) of the hit points (N, 3) [m] with material indices (N,)."""
        on_ground = material == _GROUND
        normals = np.empty_like(points)
        normals[on_ground] = terrain.surface_normal_at(points[on_ground, :2])
        normals[~on_ground] = _obstacle_normals(terrain, points[~on_ground], material[~on_ground])
        albedo = np.array([self.albedo(index) for index in range(len(MATERIALS))])[material]
        if self.ground_texture_contrast > 0:
            texture = ground_texture(points[on_ground, :2])
            albedo[on_ground] *= 1 + self.ground_texture_contrast * texture
        shading = self.ambient + (1 - self.ambient) * np.maximum(normals @ self.sun_direction, 0.0)
        return self.exposure * albedo * shading

    def capture(
        self,
        terrain: Terrain,
        vehicle_pose,
        np_random: np.random.Generator,
        pan_rad: float | None = None,
        tilt_rad: float | None = None,
    ) -> np.ndarray:
        """Grayscale uint8 image (rows, columns) of ``terrain`` from ``vehicle_pose`` ``[x, y, heading]``.

        The optical centre is ``mount_height_m`` above the ground under the vehicle. Gaussian noise
        of ``noise_std`` gray levels is drawn from ``np_random`` for every pixel (also when the std
        is 0, so the generator advances the same way), then levels are rounded and clipped to 0..255.
        """
        levels = self.radiance(terrain, vehicle_pose, pan_rad, tilt_rad)
        noise = np_random.standard_normal(levels.shape)
        noise *= self.noise_std
        levels += noise
        return np.clip(np.rint(levels, out=levels), 0, 255, out=levels).astype(np.uint8)
