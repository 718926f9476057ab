"""An a-priori map of a terrain scene, as a real prior map is: coarser, noisy, features misplaced, missing and extra.

The map is a ``Terrain`` in the world's frame (a georeferencing error would move the vehicle's estimate and its truth
on the map alike) and the points of its surfaces with their normals and the feature each lies on, sampled every
``cell_m``: the ground grid, each cylinder's side and each box's walls and roof. What registration to the map matches
scans against (``map_registration``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from infonav_gym.config import Interval, check_arguments
from infonav_gym.registration.kdtree import KdTree
from infonav_gym.world.terrain import Box, Cylinder, Terrain

PRIOR_MAP_ARGUMENTS = {  # the allowed fields of MapErrors
    "cell_m": Interval(0.1, 10.0, unit="m"),
    "height_std_m": Interval(0.0, 10.0, unit="m"),
    "feature_offset_std_m": Interval(0.0, 10.0, unit="m"),
    "missing_fraction": Interval(0.0, 1.0),
    "extra_features": Interval(0, 500, integer=True),
}
EXTRA_RADIUS_M = (0.3, 1.0)  # radius of a feature the map has and the scene has not [m]
EXTRA_HEIGHT_M = (1.0, 5.0)  # its height [m]


@dataclass(frozen=True, eq=False)
class PriorMap:
    """The map: its ``terrain`` and its surface points (M, 3), unit normals (M, 3), the feature each lies on (M,)
    (an index into ``terrain.cylinders + terrain.boxes``; -1: the ground) and their k-d ``tree``."""

    terrain: Terrain
    points: np.ndarray
    normals: np.ndarray
    features: np.ndarray
    tree: KdTree


@dataclass(frozen=True)
class MapErrors:
    """How a map differs from its terrain: heights every ``cell_m`` [m] with Gaussian errors of std ``height_std_m``
    [m]; each feature (obstacle) moved by a Gaussian offset of std ``feature_offset_std_m`` [m] along x and y, or
    left out with probability ``missing_fraction``; ``extra_features`` cylinders that are not there (radius
    ``EXTRA_RADIUS_M``, height ``EXTRA_HEIGHT_M``). ``ParameterError`` outside ``PRIOR_MAP_ARGUMENTS``."""

    cell_m: float = 1.0
    height_std_m: float = 0.05
    feature_offset_std_m: float = 0.2
    missing_fraction: float = 0.1
    extra_features: int = 3

    def __post_init__(self):
        check_arguments("MapErrors", PRIOR_MAP_ARGUMENTS, **asdict(self))


def prior_map(terrain: Terrain, np_random: np.random.Generator, errors: MapErrors = MapErrors()) -> PriorMap:
    """The map of ``terrain`` with ``errors``, drawn from ``np_random``."""
    cell_m, height_std_m = errors.cell_m, errors.height_std_m
    missing_fraction, extra_features = errors.missing_fraction, errors.extra_features
    feature_offset_std_m = errors.feature_offset_std_m
    x_min, y_min, x_max, y_max = terrain.bounds_m
    columns, rows = int((x_max - x_min) // cell_m) + 1, int((y_max - y_min) // cell_m) + 1
    grid = np.stack(np.meshgrid(x_min + cell_m * np.arange(columns), y_min + cell_m * np.arange(rows)), axis=-1)
    heights = terrain.height_at(grid) + height_std_m * np_random.standard_normal((rows, columns))
    obstacles = terrain.cylinders + terrain.boxes
    kept = np_random.random(len(obstacles)) >= missing_fraction
    offsets = feature_offset_std_m * np_random.standard_normal((len(obstacles), 2))
    moved = [_shifted(obstacle, offset) for obstacle, offset, keep in zip(obstacles, offsets, kept) if keep]
    cylinders = [obstacle for obstacle in moved if isinstance(obstacle, Cylinder)]
    boxes = [obstacle for obstacle in moved if isinstance(obstacle, Box)]
    ground = Terrain(heights, (x_min, y_min), cell_m)
    centers = np_random.uniform([x_min, y_min], [x_max, y_max], size=(extra_features, 2))
    radii = np_random.uniform(*EXTRA_RADIUS_M, size=extra_features)
    tall = np_random.uniform(*EXTRA_HEIGHT_M, size=extra_features)
    bases = ground.height_at(centers) if extra_features else np.zeros(0)
    extras = [
        Cylinder(tuple(xy), float(r), float(base), float(base + h), material="rock")
        for xy, r, base, h in zip(centers, radii, bases, tall, strict=True)
    ]
    map_terrain = ground.with_obstacles(cylinders=cylinders + extras, boxes=boxes)
    points, normals, features = surface_samples(map_terrain)
    return PriorMap(map_terrain, points, normals, features, KdTree(points))


def _shifted(obstacle, offset: np.ndarray):
    """``obstacle`` (a ``Cylinder`` or ``Box``) moved by ``offset`` (2,) [m]."""
    if isinstance(obstacle, Cylinder):
        center = np.asarray(obstacle.center_m) + offset
        return Cylinder(tuple(center), obstacle.radius_m, obstacle.bottom_m, obstacle.top_m, obstacle.material)
    shift = np.append(offset, 0.0)
    low, high = np.asarray(obstacle.min_corner_m) + shift, np.asarray(obstacle.max_corner_m) + shift
    return Box(tuple(low), tuple(high), obstacle.material)


def surface_samples(terrain: Terrain) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (M, 3), outward unit normals (M, 3) and features (M,) (``PriorMap``'s) of ``terrain``'s surfaces about
    every ``cell_m``: the ground at its grid points (normals from the grid's slopes), each cylinder's side and each
    box's four walls and roof."""
    cell = terrain.cell_m
    heights = terrain.heights_m
    rows, columns = heights.shape
    slope_y, slope_x = np.gradient(heights, cell)
    x0, y0 = terrain.origin_m
    xs, ys = np.meshgrid(x0 + cell * np.arange(columns), y0 + cell * np.arange(rows))
    up = _unit(np.stack([-slope_x, -slope_y, np.ones_like(xs)], axis=-1).reshape(-1, 3))
    parts = [(np.stack([xs, ys, heights], axis=-1).reshape(-1, 3), up)]
    for cylinder in terrain.cylinders:
        around = max(6, math.ceil(2 * math.pi * cylinder.radius_m / cell))
        angle = 2 * math.pi * np.arange(around) / around
        z = _steps(cylinder.bottom_m, cylinder.top_m, cell)
        normal = np.stack([np.cos(angle), np.sin(angle), np.zeros(around)], axis=-1)
        side = np.asarray(cylinder.center_m) + cylinder.radius_m * normal[:, :2]
        points = np.concatenate([np.repeat(side, len(z), axis=0), np.tile(z, around)[:, None]], axis=1)
        parts.append((points, np.repeat(normal, len(z), axis=0)))
    for box in terrain.boxes:
        faces = list(_box_faces(box, cell))
        parts.append(tuple(np.concatenate([face[i] for face in faces]) for i in range(2)))
    features = np.concatenate([np.full(len(part[0]), index - 1) for index, part in enumerate(parts)])
    return np.concatenate([part[0] for part in parts]), np.concatenate([part[1] for part in parts]), features


def _unit(vectors: np.ndarray) -> np.ndarray:
    return vectors / np.linalg.norm(vectors, axis=-1, keepdims=True)


def _steps(low: float, high: float, cell: float) -> np.ndarray:
    """Sample positions every about ``cell`` strictly inside ``(low, high)``, at least one."""
    count = max(1, round((high - low) / cell))
    return low + (np.arange(count) + 0.5) * (high - low) / count


def _box_faces(box: Box, cell: float):
    """(points, normals) of each wall and the roof of ``box``, every about ``cell``."""
    low, high = np.asarray(box.min_corner_m), np.asarray(box.max_corner_m)
    for axis in range(3):
        others = [a for a in range(3) if a != axis]
        u, v = np.meshgrid(_steps(low[others[0]], high[others[0]], cell), _steps(low[others[1]], high[others[1]], cell))
        for side, sign in ((low, -1.0), (high, 1.0)):
            if axis == 2 and sign < 0:
                continue  # the floor stands on the ground
            points = np.empty((u.size, 3))
            points[:, others[0]], points[:, others[1]], points[:, axis] = u.ravel(), v.ravel(), side[axis]
            normals = np.zeros((u.size, 3))
            normals[:, axis] = sign
            yield points, normals
