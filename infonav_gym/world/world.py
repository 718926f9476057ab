"""The 2D physical world: a Pymunk space with a robot, static walls and obstacles, point landmarks."""

from __future__ import annotations

import math

import numpy as np
import pymunk

from infonav_gym.estimation.models import unicycle_control, wrap_angle
from infonav_gym.world.scenarios import Scenario

OBSTACLE_CATEGORY = 0b01
ROBOT_CATEGORY = 0b10
_OBSTACLES_ONLY = pymunk.ShapeFilter(mask=OBSTACLE_CATEGORY)


class World:
    """Owns the ``pymunk.Space`` (rebuilt on every ``reset``) and the robot driving in it.

    The robot is a dynamic disc whose velocity a waypoint controller sets before
    every physics step, so walls and obstacles stop it for real. Its executed
    motion is read back from Pymunk, not assumed.

    Args:
        robot_radius_m: radius of the robot's disc [m].
        max_turn_rate_rps: saturation of the heading controller [rad/s].
        heading_gain: proportional gain of the heading controller [1/s].
        waypoint_tolerance_m: a waypoint closer than this counts as reached [m].
        wall_thickness_m: thickness of wall segments [m].
        max_physics_step_s: longest Pymunk substep [s] near obstacles; an env step is split into
            equal substeps when a wall or obstacle is within reach, else taken in one step.
    """

    def __init__(
        self,
        robot_radius_m: float = 0.3,
        max_turn_rate_rps: float = 1.0,
        heading_gain: float = 2.0,
        waypoint_tolerance_m: float = 1.0,
        wall_thickness_m: float = 0.3,
        max_physics_step_s: float = 0.1,
    ):
        self.robot_radius_m = robot_radius_m
        self.max_turn_rate_rps = max_turn_rate_rps
        self.heading_gain = heading_gain
        self.waypoint_tolerance_m = waypoint_tolerance_m
        self.wall_thickness_m = wall_thickness_m
        self.max_physics_step_s = max_physics_step_s
        self.scenario: Scenario | None = None
        self.space: pymunk.Space | None = None
        self.robot: pymunk.Body | None = None
        self.waypoint_index = 0

    def reset(self, scenario: Scenario) -> None:
        """Build a fresh space for ``scenario`` and put the robot at its start pose."""
        self.scenario = scenario
        self.space = pymunk.Space()
        self.space.collision_slop = 0.01  # allowed overlap [m]
        static_shapes = [
            pymunk.Segment(self.space.static_body, start, end, self.wall_thickness_m / 2)
            for start, end in scenario.walls
        ]
        static_shapes += [
            pymunk.Circle(self.space.static_body, obstacle.radius, obstacle.center) for obstacle in scenario.obstacles
        ]
        for shape in static_shapes:
            shape.filter = pymunk.ShapeFilter(categories=OBSTACLE_CATEGORY)
        mass = 10.0
        self.robot = pymunk.Body(mass, pymunk.moment_for_circle(mass, 0, self.robot_radius_m))
        self.robot.position = scenario.start_pose[:2]
        self.robot.angle = scenario.start_pose[2]
        robot_shape = pymunk.Circle(self.robot, self.robot_radius_m)
        robot_shape.filter = pymunk.ShapeFilter(categories=ROBOT_CATEGORY)
        self.space.add(*static_shapes, self.robot, robot_shape)
        self.waypoint_index = 0

    @property
    def landmarks(self) -> np.ndarray:
        return self.scenario.landmarks

    @property
    def pose(self) -> np.ndarray:
        """True robot pose ``[x, y, heading]``."""
        return np.array(self._pose_tuple())

    def _pose_tuple(self) -> tuple[float, float, float]:
        x, y = self.robot.position
        return x, y, wrap_angle(self.robot.angle)

    @property
    def route_finished(self) -> bool:
        """True once a non-looping route's last waypoint has been reached."""
        return self.waypoint_index >= len(self.scenario.waypoints)

    def step(self, dt: float) -> np.ndarray:
        """Drive toward the current waypoint for ``dt`` seconds; return the executed ``[speed, turn_rate]``."""
        x, y, heading = self._pose_tuple()
        speed, turn_rate = self._waypoint_control(x, y, heading)
        self.robot.velocity = (speed * math.cos(heading), speed * math.sin(heading))
        self.robot.angular_velocity = turn_rate
        substeps = math.ceil(dt / self.max_physics_step_s - 1e-9) if self._obstacle_within(speed * dt) else 1
        for _ in range(substeps):
            self.space.step(dt / substeps)
        return unicycle_control((x, y, heading), self._pose_tuple(), dt)

    def _waypoint_control(self, x: float, y: float, heading: float) -> tuple[float, float]:
        waypoints = self.scenario.waypoints
        for _ in range(len(waypoints) + 1):
            if self.route_finished:
                break
            target_x, target_y = waypoints[self.waypoint_index].tolist()
            if math.hypot(target_x - x, target_y - y) > self.waypoint_tolerance_m:
                heading_error = wrap_angle(math.atan2(target_y - y, target_x - x) - heading)
                turn_rate = max(-self.max_turn_rate_rps, min(self.max_turn_rate_rps, self.heading_gain * heading_error))
                return self.scenario.speed_mps * max(math.cos(heading_error), 0.0), turn_rate
            self.waypoint_index += 1
            if self.scenario.loop_route and self.route_finished:
                self.waypoint_index = 0
        return 0.0, 0.0

    def _obstacle_within(self, distance_m: float) -> bool:
        """Whether a wall or obstacle lies within ``distance_m`` of the robot's disc (then physics substeps)."""
        x, y = self.robot.position
        reach = self.robot_radius_m + distance_m
        return bool(self.space.bb_query(pymunk.BB(x - reach, y - reach, x + reach, y + reach), _OBSTACLES_ONLY))

    def line_of_sight(self, origin, targets) -> np.ndarray:
        """For each target point (N, 2), whether the straight line from ``origin`` misses every wall and obstacle."""
        start = (float(origin[0]), float(origin[1]))
        query = self.space.segment_query_first
        return np.array(
            [query(start, (float(x), float(y)), 0.0, _OBSTACLES_ONLY) is None for x, y in np.atleast_2d(targets)],
            dtype=bool,
        )
