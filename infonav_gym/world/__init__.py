"""The simulated 2D world (Pymunk) and its scenarios."""

from infonav_gym.world.scenarios import SCENARIOS, CircleObstacle, Route, Scenario
from infonav_gym.world.world import World

__all__ = ["SCENARIOS", "CircleObstacle", "Route", "Scenario", "World"]
