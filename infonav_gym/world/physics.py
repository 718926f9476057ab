"""The physics of record: a scenario's walls, obstacles and robot discs in a Pymunk space, and the world's arguments.

``WorldBatch`` moves robots by compiled free motion when nothing is within reach; a step that may touch something is
taken here, by Pymunk's solver, and so is every line-of-sight query the tests check the compiled visibility against.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk

from infonav_gym.config import Interval
from infonav_gym.geometry import wrap_angle
from infonav_gym.world.scenarios import Scenario

OBSTACLE_CATEGORY = 0b01
ROBOT_CATEGORY = 0b10
_OBSTACLES_ONLY = pymunk.ShapeFilter(mask=OBSTACLE_CATEGORY)
_ROBOT_MASS_KG = 10.0
MAX_TIME_STEP_S = 60.0  # longest ``step`` [s]; near contacts it takes up to 600 Pymunk substeps
TIME_STEP_S = Interval(0.0, MAX_TIME_STEP_S, open_low=True, unit="s")  # the allowed ``step`` durations
WORLD_ARGUMENTS = {  # the allowed arguments of World and WorldBatch
    "robot_radius_m": Interval(0.0, 10.0, open_low=True, unit="m"),  # every robot's disc
    "max_turn_rate_rps": Interval(0.0, 100.0, open_low=True, unit="rad/s"),  # the heading controller's saturation
    "heading_gain": Interval(0.0, 1000.0, open_low=True, unit="1/s"),  # and its proportional gain
    "waypoint_tolerance_m": Interval(0.0, 100.0, open_low=True, unit="m"),  # a waypoint this close is reached
    "wall_thickness_m": Interval(0.0, 10.0, open_low=True, unit="m"),
    "max_physics_step_s": Interval(1e-3, 1.0, unit="s"),  # longest Pymunk substep of a contact step
}


class ContactSpace:
    """One copy's scenario in a Pymunk space: static walls and round obstacles, a dynamic disc per route (robot);
    arguments as ``WORLD_ARGUMENTS``."""

    def __init__(self, scenario: Scenario, robot_radius_m: float, wall_thickness_m: float, max_physics_step_s: float):
        self.max_physics_step_s = max_physics_step_s
        self.space = pymunk.Space()
        self.space.collision_slop = 0.01  # allowed overlap [m]
        static_body = self.space.static_body
        static_shapes = [pymunk.Segment(static_body, start, end, wall_thickness_m / 2) for start, end in scenario.walls]
        static_shapes += [pymunk.Circle(static_body, o.radius, o.center) for o in scenario.obstacles]
        for shape in static_shapes:
            shape.filter = pymunk.ShapeFilter(categories=OBSTACLE_CATEGORY)
        self.space.add(*static_shapes)
        self._robot_bodies = []
        for _ in scenario.routes:
            body = pymunk.Body(_ROBOT_MASS_KG, pymunk.moment_for_circle(_ROBOT_MASS_KG, 0, robot_radius_m))
            shape = pymunk.Circle(body, robot_radius_m)
            shape.filter = pymunk.ShapeFilter(categories=ROBOT_CATEGORY)
            self.space.add(body, shape)
            self._robot_bodies.append(body)

    def drive(self, poses: np.ndarray, controls: np.ndarray, dt: float) -> np.ndarray:
        """The robots' poses (R, 3) after ``dt`` in Pymunk substeps, from ``poses`` (R, 3) driving ``[speed,
        turn_rate]`` (R, 2): walls, obstacles and the other robots stop or push them for real."""
        for body, (x, y, heading), (speed, turn_rate) in zip(self._robot_bodies, poses.tolist(), controls.tolist()):
            body.position = x, y
            body.angle = heading
            body.velocity = (speed * math.cos(heading), speed * math.sin(heading))
            body.angular_velocity = turn_rate
        substeps = math.ceil(dt / self.max_physics_step_s - 1e-9)
        for _ in range(substeps):
            self.space.step(dt / substeps)
        return np.array([(*body.position, wrap_angle(body.angle)) for body in self._robot_bodies])

    def end_contacts(self) -> None:
        """A free step ends a run of ``drive`` steps: Pymunk forgets the run's warm-start contacts, so every run starts
        as in a fresh space and an idle copy's space may be dropped and rebuilt with the same numbers."""
        for body in self._robot_bodies:
            self.space.remove(body, *body.shapes)
        for body in self._robot_bodies:
            self.space.add(body, *body.shapes)

    def line_of_sight(self, origin, targets) -> np.ndarray:
        """Per target point (N, 2), whether the line from ``origin`` misses all walls and obstacles (not robots)."""
        start = (float(origin[0]), float(origin[1]))
        query = self.space.segment_query_first
        return np.array(
            [query(start, (float(x), float(y)), 0.0, _OBSTACLES_ONLY) is None for x, y in np.atleast_2d(targets)],
            dtype=bool,
        )


def static_boxes(scenario: Scenario, wall_thickness_m: float) -> np.ndarray:
    """Bounding boxes ``(left, bottom, right, top)`` of the scenario's walls, then obstacles (S, 4) [m], as Pymunk's
    (what ``StaticGeometry``'s boxes hold, without building one: a reset of many copies calls this per copy)."""
    half = wall_thickness_m / 2
    boxes = [
        (min(a[0], b[0]) - half, min(a[1], b[1]) - half, max(a[0], b[0]) + half, max(a[1], b[1]) + half)
        for a, b in scenario.walls
    ]
    boxes += [
        (o.center[0] - o.radius, o.center[1] - o.radius, o.center[0] + o.radius, o.center[1] + o.radius)
        for o in scenario.obstacles
    ]
    return np.array(boxes, dtype=float).reshape(-1, 4)
