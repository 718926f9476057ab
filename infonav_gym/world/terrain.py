"""A 2.5D scene for range and image sensors: a height map plus solid obstacles with heights.

The scene is independent of Pymunk: the obstacles' footprints (circles, rectangles) are what
a 2D ``World`` would collide with. Coordinates are world metres, ``z`` up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from infonav_gym.compiled import contiguous
from infonav_gym.world import terrain_kernels

MATERIALS = ("ground", "vegetation", "rock", "building")
NO_HIT = terrain_kernels.NO_HIT  # material index of a ray that hits nothing within range


def finite_vector(value, length: int, name: str) -> tuple[float, ...]:
    """``value`` as a tuple of ``length`` finite floats, or ``ValueError`` naming it."""
    vector = np.asarray(value, dtype=float)
    if vector.shape != (length,) or not np.all(np.isfinite(vector)):
        raise ValueError(f"{name} must be {length} finite numbers, got {value!r}")
    return tuple(float(v) for v in vector)


def _check_material(material: str, owner: str) -> None:
    if material not in MATERIALS[1:]:
        raise ValueError(f"{owner} material must be one of {MATERIALS[1:]}, got {material!r}")


@dataclass(frozen=True)
class Cylinder:
    """A vertical solid cylinder (a tree, a rock); lengths [m], material one of ``MATERIALS[1:]``."""

    center_m: tuple[float, float]  # (x, y) of the axis
    radius_m: float
    bottom_m: float  # elevation of the base
    top_m: float
    material: str = "vegetation"

    def __post_init__(self):
        object.__setattr__(self, "center_m", finite_vector(self.center_m, 2, "cylinder center_m"))
        if not (math.isfinite(self.radius_m) and self.radius_m > 0):
            raise ValueError(f"cylinder radius_m must be positive and finite, got {self.radius_m!r}")
        if not (math.isfinite(self.bottom_m) and math.isfinite(self.top_m) and self.bottom_m < self.top_m):
            raise ValueError(f"cylinder needs finite bottom_m < top_m, got {self.bottom_m!r} and {self.top_m!r}")
        _check_material(self.material, "cylinder")


@dataclass(frozen=True)
class Box:
    """An axis-aligned solid box (a wall, a building) between two (x, y, z) corners [m]; material as a Cylinder's."""

    min_corner_m: tuple[float, float, float]
    max_corner_m: tuple[float, float, float]
    material: str = "building"

    def __post_init__(self):
        low = finite_vector(self.min_corner_m, 3, "box min_corner_m")
        high = finite_vector(self.max_corner_m, 3, "box max_corner_m")
        if not all(a < b for a, b in zip(low, high, strict=True)):
            raise ValueError(f"box min_corner_m {low} must be below max_corner_m {high} on every axis")
        object.__setattr__(self, "min_corner_m", low)
        object.__setattr__(self, "max_corner_m", high)
        _check_material(self.material, "box")


@dataclass(frozen=True)
class RayHits:
    """Where a grid of rays first meets the scene (R, C)."""

    range_m: np.ndarray  # [m]; inf for no hit within range
    material_index: np.ndarray  # into MATERIALS; NO_HIT for none
    obstacle_index: np.ndarray  # into cylinders + boxes; -1 for the ground and for none


@dataclass(frozen=True, eq=False)
class Terrain:
    """A height map plus solid obstacles: ``heights_m[i, j]`` is the ground at ``(x0 + j * cell_m, y0 + i * cell_m)``,
    bilinear between grid points, the edge heights extended beyond."""

    heights_m: np.ndarray  # (H, W), H, W >= 2 [m]
    origin_m: tuple[float, float] = (0.0, 0.0)  # (x0, y0) [m]
    cell_m: float = 1.0  # [m]
    cylinders: tuple[Cylinder, ...] = ()
    boxes: tuple[Box, ...] = ()
    # for terrain_kernels: ((heights, x0, y0, cell_m), obstacle table (M, 9), materials (M,) int8, n_cylinders)
    arrays: tuple = field(init=False, repr=False)

    def __post_init__(self):
        heights = np.array(self.heights_m, dtype=float)
        if heights.ndim != 2 or min(heights.shape) < 2:
            raise ValueError(f"terrain heights_m must be a 2D grid of at least 2 x 2 points, got shape {heights.shape}")
        if not np.all(np.isfinite(heights)):
            raise ValueError("terrain heights_m contains NaN or infinite values")
        if not (math.isfinite(self.cell_m) and self.cell_m > 0):
            raise ValueError(f"terrain cell_m must be positive and finite, got {self.cell_m!r}")
        heights.flags.writeable = False
        object.__setattr__(self, "heights_m", heights)
        object.__setattr__(self, "origin_m", finite_vector(self.origin_m, 2, "terrain origin_m"))
        object.__setattr__(self, "cylinders", tuple(self.cylinders))
        object.__setattr__(self, "boxes", tuple(self.boxes))
        obstacles = self.cylinders + self.boxes
        for obstacle in obstacles:
            if not isinstance(obstacle, (Cylinder, Box)):
                raise ValueError(f"terrain obstacles must be Cylinder or Box, got {obstacle!r}")
        table = np.array(
            [(*c.center_m, c.radius_m, 0.0, 0.0, c.bottom_m, 0.0, 0.0, c.top_m) for c in self.cylinders]
            + [(0.0, 0.0, 0.0, *b.min_corner_m, *b.max_corner_m) for b in self.boxes]
        ).reshape(-1, terrain_kernels.OBSTACLE_COLUMNS)
        materials = np.array([MATERIALS.index(o.material) for o in obstacles], dtype=np.int8)
        grid = (heights.copy(), *self.origin_m, float(self.cell_m))  # a writeable copy: one kernel type
        object.__setattr__(self, "arrays", (grid, table, materials, len(self.cylinders)))

    @property
    def bounds_m(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)`` covered by the height grid [m]."""
        rows, columns = self.heights_m.shape
        x0, y0 = self.origin_m
        return x0, y0, x0 + (columns - 1) * self.cell_m, y0 + (rows - 1) * self.cell_m

    def with_obstacles(self, cylinders=(), boxes=()) -> Terrain:
        """A copy with ``cylinders`` and ``boxes`` added to the existing obstacles."""
        return replace(self, cylinders=self.cylinders + tuple(cylinders), boxes=self.boxes + tuple(boxes))

    def height_at(self, xy) -> np.ndarray:
        """Bilinear ground elevation [m] at points ``xy`` (..., 2) -> (...)."""
        points = np.asarray(xy, dtype=float)
        if points.ndim < 1 or points.shape[-1] != 2 or not np.all(np.isfinite(points)):
            raise ValueError(f"terrain query points must be finite (..., 2) [m], got shape {points.shape}")
        return terrain_kernels.ground_at(self.arrays[0], contiguous(points.reshape(-1, 2)))[0].reshape(
            points.shape[:-1]
        )[()]

    def cast_rays(self, origin_m, azimuth_rad, elevation_rad, max_range_m: float) -> RayHits:
        """First hits (R, C) within ``max_range_m`` of rays from ``origin_m`` ``(x, y, z)`` [m] at world azimuths
        ``azimuth_rad`` (C,) and elevations ``elevation_rad`` (R,) or (R, C) in (-pi/2, pi/2) [rad]: compiled
        ``terrain_kernels.first_hits``."""
        origin = np.array(finite_vector(origin_m, 3, "ray origin_m"))
        azimuth, elevation = np.asarray(azimuth_rad, dtype=float), np.asarray(elevation_rad, dtype=float)
        if azimuth.ndim != 1 or not np.all(np.isfinite(azimuth)):
            raise ValueError(f"azimuth_rad must be a finite (C,) array, got shape {azimuth.shape}")
        if elevation.ndim == 1:
            elevation = elevation[:, None]
        if elevation.ndim != 2 or elevation.shape[1] not in (1, azimuth.size):
            raise ValueError(f"elevation_rad must be (R,) or (R, C={azimuth.size}), got shape {elevation.shape}")
        if not np.all(np.abs(elevation) < math.pi / 2):
            raise ValueError("elevation_rad must lie strictly inside (-pi/2, pi/2)")
        if not (math.isfinite(max_range_m) and max_range_m > 0):
            raise ValueError(f"max_range_m must be positive and finite, got {max_range_m!r}")
        if not origin[2] > self.height_at(origin[:2]):
            raise ValueError(f"ray origin_m {tuple(origin)} is not above the ground")
        range_m, material, obstacle = terrain_kernels.first_hits(
            self.arrays, origin, contiguous(azimuth), contiguous(elevation), float(max_range_m)
        )
        return RayHits(range_m, material, obstacle)
