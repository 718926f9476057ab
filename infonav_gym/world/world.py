"""The 2D physical world of one scenario: ``WorldBatch``'s N = 1 view, with Pymunk as its physics of record."""

from __future__ import annotations

import numpy as np
import pymunk

from infonav_gym.world.scenarios import Scenario
from infonav_gym.world.world_batch import WorldBatch

_ONLY_COPY = np.zeros(1, dtype=int)


class World:
    """The robots of a scenario driving in a Pymunk world of walls and round obstacles.

    Each robot is a dynamic disc driven by a waypoint controller. A step in which no wall, obstacle or other robot
    comes within reach of any robot is free motion, integrated as Pymunk integrates a free body; any other step is
    Pymunk's, so walls, obstacles and the other robots stop or push them for real, and the executed motion is read
    back, not assumed. It is one copy of a ``WorldBatch``, which holds the arrays and the rules.

    Args:
        **world_args: ``robot_radius_m``, ``max_turn_rate_rps``, ``heading_gain``, ``waypoint_tolerance_m``,
            ``wall_thickness_m``, ``max_physics_step_s`` (``WorldBatch``'s, with its defaults).

    Raises:
        ParameterError: (a ``ValueError``) for an argument outside its ``WORLD_ARGUMENTS`` interval.
    """

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
        """Drive every robot toward its current waypoint for ``dt`` seconds.

        Returns:
            The executed ``[speed, turn_rate]`` of every robot (R, 2) [m/s, rad/s].

        Raises:
            ParameterError: (a ``ValueError``) unless ``dt`` is in ``TIME_STEP_S``, (0, 60] s.
        """
        return self._batch.step(dt, _ONLY_COPY)[0]

    def line_of_sight(self, origin, targets) -> np.ndarray:
        """For each target point (N, 2), whether the straight line from ``origin`` misses every wall and obstacle.

        Robots do not block the line of sight.
        """
        return self._batch.contact_space(0).line_of_sight(origin, targets)
