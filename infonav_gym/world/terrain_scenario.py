"""A vehicle's loop through a 2.5D terrain: the ``Terrain`` the sensors see and the ``Scenario`` Pymunk drives.

Trees and rocks are round obstacles of the 2D world, buildings four walls: what blocks the vehicle is what the
sensors see.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from infonav_gym.config import Interval, check_arguments, check_config_arguments
from infonav_gym.world.scenarios import (
    DEFAULT_WAYPOINTS,
    SPEED_MPS,
    WAYPOINT_COUNT,
    CircleObstacle,
    Scenario,
    _box_walls,
    _closed_route,
    _polygon,
)
from infonav_gym.world.terrain import Terrain
from infonav_gym.world.terrain_generation import DEFAULT_CELL_M, MAX_GRID_POINTS, TERRAIN_ARGUMENTS, make_terrain

ROUTE_CLEARANCE_M = 3.0  # obstacles keep this far from the route [m]
SCENE_CONFIG = {  # env config keys of a terrain_loop scene, with their defaults
    "scene_size_m": 60.0,  # side of the square scene [m]
    "roughness": 0.7,  # ground roughness, see make_terrain
    "n_trees": 25,
    "n_rocks": 8,
    "n_buildings": 3,
}
TERRAIN_LOOP_ARGUMENTS = {  # the allowed arguments of terrain_loop
    **TERRAIN_ARGUMENTS,
    "size_m": Interval(DEFAULT_CELL_M, (MAX_GRID_POINTS - 1) * DEFAULT_CELL_M, unit="m"),
    "speed_mps": SPEED_MPS,
    "n_waypoints": WAYPOINT_COUNT,
}


@dataclass(frozen=True)
class TerrainScenario:
    """The 2D scenario (route, obstacles, walls) and the 2.5D terrain of one scene."""

    scenario: Scenario
    terrain: Terrain


def with_terrain_obstacles(scenario: Scenario, terrain: Terrain) -> Scenario:
    """``scenario`` plus ``terrain``'s obstacles: each cylinder a disc, each box four walls."""
    walls = []
    for box in terrain.boxes:
        (x_min, y_min, _), (x_max, y_max, _) = box.min_corner_m, box.max_corner_m
        walls.extend(_box_walls(x_min, y_min, x_max, y_max))
    discs = tuple(CircleObstacle(cylinder.center_m, cylinder.radius_m) for cylinder in terrain.cylinders)
    return replace(scenario, walls=scenario.walls + tuple(walls), obstacles=scenario.obstacles + discs)


def terrain_loop(
    np_random: np.random.Generator,
    size_m: float = 60.0,
    roughness: float = 0.7,
    n_trees: int = 25,
    n_rocks: int = 8,
    n_buildings: int = 3,
    speed_mps: float = 2.0,
    n_waypoints: int = DEFAULT_WAYPOINTS,
) -> TerrainScenario:
    """A random scene (``make_terrain``) and a closed route through it, a jittered polygon at 22-36 % of ``size_m``
    that obstacles keep clear of; ``ParameterError`` outside ``TERRAIN_LOOP_ARGUMENTS``."""
    counts = {"n_trees": n_trees, "n_rocks": n_rocks, "n_buildings": n_buildings, "n_waypoints": n_waypoints}
    check_arguments("terrain_loop", TERRAIN_LOOP_ARGUMENTS, size_m=size_m, roughness=roughness, **counts)
    check_arguments("terrain_loop", TERRAIN_LOOP_ARGUMENTS, speed_mps=speed_mps)
    center = np.zeros(2)
    sectors = np.arange(n_waypoints) + np_random.uniform(-0.2, 0.2, n_waypoints)
    route = _polygon(center, 2 * math.pi * sectors / n_waypoints, size_m * np_random.uniform(0.22, 0.36, n_waypoints))
    terrain = make_terrain(
        np_random,
        size_m=size_m,
        roughness=roughness,
        n_trees=n_trees,
        n_rocks=n_rocks,
        n_buildings=n_buildings,
        center_m=center,
        clear_radius_m=ROUTE_CLEARANCE_M,
        clear_path_m=route,
    )
    drive = Scenario(name="terrain_loop", bounds=terrain.bounds_m, routes=(_closed_route(route, speed_mps),))
    return TerrainScenario(with_terrain_obstacles(drive, terrain), terrain)


_LOOP_CONFIG_KEYS = {  # the env config key of each terrain_loop argument: its own name but for size_m
    "size_m": "scene_size_m",
    **{argument: argument for argument in ("roughness", "n_trees", "n_rocks", "n_buildings", "speed_mps")},
}


def check_scene_config(config: dict, owner: str) -> None:
    """``ValueError`` naming the key unless an env config's ``SCENE_CONFIG`` keys and ``speed_mps`` are valid."""
    check_config_arguments(config, owner, "terrain_loop", TERRAIN_LOOP_ARGUMENTS, _LOOP_CONFIG_KEYS)


def terrain_loop_from_config(np_random: np.random.Generator, config: dict) -> TerrainScenario:
    """``terrain_loop`` with an env config's ``SCENE_CONFIG`` keys and its ``speed_mps``."""
    return terrain_loop(np_random, **{argument: config[key] for argument, key in _LOOP_CONFIG_KEYS.items()})
