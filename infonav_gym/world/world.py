"""The 2D physical world of one scenario: ``WorldBatch``'s N = 1 view, with Pymunk as its physics of record."""

from __future__ import annotations

import numpy as np
import pymunk

from infonav_gym.world.scenarios import Scenario
from infonav_gym.world.world_batch import WorldBatch

_ONLY_COPY = np.zeros(1, dtype=int)


class World:
    """The robots of a scenario, discs driven by waypoint controllers in a Pymunk world of walls and obstacles: one
    copy of a ``WorldBatch`` (``world_args``: ``WORLD_ARGUMENTS``; ``ParameterError`` outside them)."""

    def __init__(self, **world_args):
        self._batch = WorldBatch(1, **world_args)
        self.robot_radius_m = self._batch.robot_radius_m
        self.wall_thickness_m = self._batch.wall_thickness_m
        self.waypoint_tolerance_m = self._batch.waypoint_tolerance_m

    def reset(self, scenario: Scenario) -> None:
        """Put one robot at the start of each of ``scenario``'s routes (a fresh space is built when first needed)."""
        self._batch.reset_copy(0, scenario)

    @property
    def scenario(self) -> Scenario | None:
        return self._batch.scenario(0)

    @property
    def space(self) -> pymunk.Space:
        """The Pymunk space of the scenario's walls, obstacles and robot discs (built on first use)."""
        return self._batch.contact_space(0).space

    @property
    def landmarks(self) -> np.ndarray:
        return self.scenario.landmarks

    @property
    def n_robots(self) -> int:
        return self._batch.poses.shape[1]

    @property
    def poses(self) -> np.ndarray:
        """True poses ``[x, y, heading]`` of every robot (R, 3)."""
        return self._batch.poses[0].copy()

    @property
    def pose(self) -> np.ndarray:
        """True pose ``[x, y, heading]`` of robot 0 (the only robot of single-robot scenarios)."""
        return self._batch.poses[0, 0].copy()

    @property
    def waypoint_indices(self) -> list[int]:
        """The waypoint each robot drives to next (its route's length once an open route has ended)."""
        return self._batch.waypoint_indices(0)

    def step(self, dt: float) -> np.ndarray:
        """Drive every robot toward its waypoint for ``dt`` [s]; the executed ``[speed, turn_rate]`` (R, 2)."""
        return self._batch.step(dt, _ONLY_COPY)[0]

    def line_of_sight(self, origin, targets) -> np.ndarray:
        """Per target point (N, 2), whether the line from ``origin`` misses all walls and obstacles (not robots)."""
        return self._batch.contact_space(0).line_of_sight(origin, targets)
