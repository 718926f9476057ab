"""The simulated 2D world (Pymunk) and its scenarios."""

from infonav_gym.world.scenarios import (
    SCENARIOS,
    CircleObstacle,
    Route,
    Scenario,
    build_scenario,
    register_scenario,
    scenario_names,
)
from infonav_gym.world.terrain import MATERIALS, Box, Cylinder, RayHits, Terrain
from infonav_gym.world.terrain_generation import flat_terrain, make_terrain
from infonav_gym.world.visibility import StaticGeometry
from infonav_gym.world.world import World

__all__ = [
    "MATERIALS",
    "SCENARIOS",
    "Box",
    "CircleObstacle",
    "Cylinder",
    "RayHits",
    "Route",
    "Scenario",
    "StaticGeometry",
    "Terrain",
    "World",
    "build_scenario",
    "flat_terrain",
    "make_terrain",
    "register_scenario",
    "scenario_names",
]
