"""Random and level ``Terrain`` scenes: rolling or rugged height maps with trees, rocks and buildings."""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import gaussian_filter

from infonav_gym.config import Interval, ParameterError, check_arguments, check_number
from infonav_gym.geometry import ClosedLoop
from infonav_gym.world.terrain import Box, Cylinder, Terrain, finite_vector

_MAX_PLACEMENT_ATTEMPTS = 1000  # random draws per obstacle before the scene counts as too small
_HILL_STD_M = 2.0  # height standard deviation of the smooth hills at roughness 1 [m]
_HILL_CORRELATION_M = 8.0  # length scale of the hills [m]
_BUMP_STD_M = 0.4  # height standard deviation of the small bumps at roughness 1 [m]
_BUMP_CORRELATION_M = 1.0  # length scale of the bumps [m]
_FOOTPRINT_CORNERS = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1], [0, 0]])  # the centre last
DEFAULT_CELL_M = 0.5  # grid spacing of random scenes [m]
MAX_GRID_POINTS = 2001  # most grid points along a side (a float64 height map of 32 MB)
MAX_ROUGHNESS = 10.0
MAX_TERRAIN_OBSTACLES = 500  # most trees, rocks or buildings each
OBSTACLE_COUNT = Interval(0, MAX_TERRAIN_OBSTACLES, integer=True)
TERRAIN_ARGUMENTS = {  # the allowed arguments of make_terrain (size_m: see _grid_points)
    "roughness": Interval(0.0, MAX_ROUGHNESS),
    "n_trees": OBSTACLE_COUNT,
    "n_rocks": OBSTACLE_COUNT,
    "n_buildings": OBSTACLE_COUNT,
}


def flat_terrain(size_m: float = 100.0, cell_m: float = 1.0, center_m=(0.0, 0.0), height_m: float = 0.0) -> Terrain:
    """Level ground at ``height_m`` over a ``size_m`` square centred on ``center_m``, no obstacles."""
    points = _grid_points(size_m, cell_m)
    center = finite_vector(center_m, 2, "center_m")
    origin = (center[0] - size_m / 2, center[1] - size_m / 2)
    return Terrain(np.full((points, points), float(height_m)), origin, cell_m)


def _grid_points(size_m: float, cell_m: float) -> int:
    """Grid points along a side; ``ParameterError`` unless ``cell_m <= size_m <= (MAX_GRID_POINTS - 1) * cell_m``."""
    if not (math.isfinite(cell_m) and cell_m > 0):
        raise ParameterError("terrain", "cell_m", "positive and finite [m]", cell_m)
    check_number("terrain", "size_m", size_m, cell_m, (MAX_GRID_POINTS - 1) * cell_m, unit=f"m (cell_m={cell_m:g} m)")
    return round(size_m / cell_m) + 1


def _unit_field(np_random: np.random.Generator, points: int, correlation_cells: float) -> np.ndarray:
    """Smooth Gaussian random field with zero mean and unit standard deviation."""
    smooth = gaussian_filter(np_random.standard_normal((points, points)), correlation_cells, mode="wrap")
    return (smooth - smooth.mean()) / smooth.std()


def make_terrain(
    np_random: np.random.Generator,
    size_m: float = 60.0,
    cell_m: float = DEFAULT_CELL_M,
    roughness: float = 0.5,
    n_trees: int = 15,
    n_rocks: int = 5,
    n_buildings: int = 2,
    center_m=(0.0, 0.0),
    clear_radius_m: float = 5.0,
    clear_path_m=None,
) -> Terrain:
    """A random ``size_m`` square scene centred on ``center_m`` [m] with trees, rocks and buildings.

    Heights: Gaussian random fields, hills (std ``_HILL_STD_M * roughness``) plus bumps (std ``_BUMP_STD_M *
    roughness**2``): 0 is level, 0.5 rolling, 1 rugged. Obstacles stand on the lowest ground under them and keep
    ``clear_radius_m`` off ``clear_path_m`` (a closed (W, 2) polyline [m], default ``center_m``); their layout
    does not depend on ``roughness``. Trees: radius 0.2-0.6 m, 4-12 m tall; rocks: 0.4-1.5 m, 0.3-1.5 m tall;
    buildings: boxes, sides 3-10 m, 3-8 m tall.

    Raises:
        ValueError: for an argument outside ``TERRAIN_ARGUMENTS`` or ``_grid_points``' range (``ParameterError``),
            a bad clear path, or obstacles that do not fit.
    """
    points = _grid_points(size_m, cell_m)
    counts = {"n_trees": n_trees, "n_rocks": n_rocks, "n_buildings": n_buildings}
    check_arguments("make_terrain", TERRAIN_ARGUMENTS, roughness=roughness, **counts)
    if not (math.isfinite(clear_radius_m) and 0 <= clear_radius_m < size_m / 2):
        raise ValueError(f"clear_radius_m must be in [0, size_m / 2 = {size_m / 2}), got {clear_radius_m!r}")
    hills = _unit_field(np_random, points, _HILL_CORRELATION_M / cell_m)
    bumps = _unit_field(np_random, points, _BUMP_CORRELATION_M / cell_m)
    heights = roughness * (_HILL_STD_M * hills + roughness * _BUMP_STD_M * bumps) + 0.0
    center = np.array(finite_vector(center_m, 2, "center_m"))
    clear_path = center[None] if clear_path_m is None else np.asarray(clear_path_m, dtype=float)
    if clear_path.ndim != 2 or clear_path.shape[1] != 2 or not np.all(np.isfinite(clear_path)):
        raise ValueError(f"clear_path_m must be a finite (W, 2) polyline [m], got {clear_path_m!r}")
    ground = Terrain(heights, tuple(center - size_m / 2), cell_m)
    route = ClosedLoop(clear_path)

    def place(count: int, footprint_radius_m: np.ndarray) -> np.ndarray:
        """Centres (count, 2) inside the scene, their footprints ``clear_radius_m`` away from the clear path."""
        half = size_m / 2 - footprint_radius_m
        centers = np.empty((count, 2))
        for index in range(count):
            for _ in range(_MAX_PLACEMENT_ATTEMPTS):
                offset = np_random.uniform(-half[index], half[index], size=2)
                clearance = clear_radius_m + footprint_radius_m[index]
                if half[index] > 0 and route.distances((center + offset)[None])[0] > clearance:
                    break
            else:
                raise ValueError(
                    f"could not place an obstacle of footprint radius {footprint_radius_m[index]:.2f} m in a "
                    f"{size_m} m scene {clear_radius_m} m clear of the clear path: enlarge size_m or shorten the path"
                )
            centers[index] = center + offset
        return centers

    def standing(half_extents_m: np.ndarray, footprint_radius_m: np.ndarray, height_range) -> tuple:
        """Centres (count, 2), bases and tops [m] of obstacles of a height drawn in ``height_range``, placed
        (``place``) and standing on the lowest ground under their footprint's corners and centre."""
        tall = np_random.uniform(*height_range, size=len(footprint_radius_m))
        centers = place(len(footprint_radius_m), footprint_radius_m)
        ground_m = ground.height_at(centers[:, None] + half_extents_m[:, None] * _FOOTPRINT_CORNERS)
        return centers, ground_m.min(axis=1), ground_m[:, -1] + tall  # the top: above the ground at the centre

    def standing_cylinders(count, radius_range, height_range, material) -> list[Cylinder]:
        radii = np_random.uniform(*radius_range, size=count)
        centers, bases, tops = standing(radii[:, None], radii, height_range)
        return [
            Cylinder(tuple(xy), float(r), float(base), float(top), material=material)
            for xy, r, base, top in zip(centers, radii, bases, tops, strict=True)
        ]

    trees = standing_cylinders(int(n_trees), (0.2, 0.6), (4.0, 12.0), "vegetation")
    rocks = standing_cylinders(int(n_rocks), (0.4, 1.5), (0.3, 1.5), "rock")
    sides = np_random.uniform(3.0, 10.0, size=(int(n_buildings), 2))
    centers, bases, tops = standing(sides / 2, np.linalg.norm(sides, axis=1) / 2, (3.0, 8.0))
    buildings = [
        Box((*(xy - half), float(base)), (*(xy + half), float(top)))
        for xy, half, base, top in zip(centers, sides / 2, bases, tops, strict=True)
    ]
    return ground.with_obstacles(cylinders=trees + rocks, boxes=buildings)
