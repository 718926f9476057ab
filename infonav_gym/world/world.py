"""The 2D physical world: a Pymunk space with robots, static walls and obstacles, point landmarks."""

from __future__ import annotations

import math

import numpy as np
import pymunk

from infonav_gym.config import Interval
from infonav_gym.estimation.models import unicycle_control
from infonav_gym.geometry import wrap_angle
from infonav_gym.world.scenarios import Scenario

OBSTACLE_CATEGORY = 0b01
ROBOT_CATEGORY = 0b10
_OBSTACLES_ONLY = pymunk.ShapeFilter(mask=OBSTACLE_CATEGORY)
_ROBOT_MASS_KG = 10.0
_CLEAR_BOX_MARGIN_M = 2.0  # a robot's remembered obstacle-free box extends this far beyond its reach [m]
_EMPTY_BOX = (math.inf, math.inf, -math.inf, -math.inf)  # (left, bottom, right, top) that contains nothing
MAX_TIME_STEP_S = 60.0  # longest ``step`` [s]; near contacts it takes up to 600 Pymunk substeps
TIME_STEP_S = Interval(0.0, MAX_TIME_STEP_S, open_low=True, unit="s")  # the allowed ``step`` durations
WORLD_ARGUMENTS = {  # the allowed arguments of World
    "robot_radius_m": Interval(0.0, 10.0, open_low=True, unit="m"),
    "max_turn_rate_rps": Interval(0.0, 100.0, open_low=True, unit="rad/s"),
    "heading_gain": Interval(0.0, 1000.0, open_low=True, unit="1/s"),
    "waypoint_tolerance_m": Interval(0.0, 100.0, open_low=True, unit="m"),
    "wall_thickness_m": Interval(0.0, 10.0, open_low=True, unit="m"),
    "max_physics_step_s": Interval(1e-3, 1.0, unit="s"),  # at most 60000 substeps of a longest step
}


class World:
    """Owns the ``pymunk.Space`` (rebuilt on every ``reset``) and the robots driving in it.

    Each robot is a dynamic disc whose velocity a waypoint controller sets before
    every physics step, so walls, obstacles and the other robots stop or push it
    for real. Its executed motion is read back from Pymunk, not assumed.

    Args:
        robot_radius_m: radius of every robot's disc [m].
        max_turn_rate_rps: saturation of the heading controller [rad/s].
        heading_gain: proportional gain of the heading controller [1/s].
        waypoint_tolerance_m: a waypoint closer than this counts as reached [m].
        wall_thickness_m: thickness of wall segments [m].
        max_physics_step_s: longest Pymunk substep [s] near contacts; an env step is split into
            equal substeps when a wall, obstacle or other robot is within reach of some robot,
            else taken in one step.

    Raises:
        ParameterError: (a ``ValueError``) for an argument outside its ``WORLD_ARGUMENTS`` interval.
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
        for name, interval in WORLD_ARGUMENTS.items():
            interval.check("World", name, getattr(self, name))
        self.scenario: Scenario | None = None
        self.space: pymunk.Space | None = None
        self.robot_bodies: list[pymunk.Body] = []
        self.waypoint_indices: list[int] = []
        self._poses: list[tuple[float, float, float]] = []  # true poses as of the last reset or step
        self._waypoints: list[list[list[float]]] = []
        self._static_boxes: dict[pymunk.Shape, tuple[float, float, float, float]] = {}
        self._clear_boxes: list[tuple[float, float, float, float]] = []
        self._zone_centers = np.zeros((0, 2))
        self._zone_radii_sq = np.zeros(0)

    def reset(self, scenario: Scenario) -> None:
        """Build a fresh space for ``scenario`` and put one robot at the start of each of its routes."""
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
        self.space.add(*static_shapes)
        self.robot_bodies = []
        for route in scenario.routes:
            body = pymunk.Body(_ROBOT_MASS_KG, pymunk.moment_for_circle(_ROBOT_MASS_KG, 0, self.robot_radius_m))
            body.position = route.start_pose[:2]
            body.angle = route.start_pose[2]
            shape = pymunk.Circle(body, self.robot_radius_m)
            shape.filter = pymunk.ShapeFilter(categories=ROBOT_CATEGORY)
            self.space.add(body, shape)
            self.robot_bodies.append(body)
        self._poses = [self._read_pose(body) for body in self.robot_bodies]
        self._waypoints = [route.waypoints.tolist() for route in scenario.routes]
        self.waypoint_indices = [0] * len(scenario.routes)
        self._static_boxes = {shape: tuple(shape.bb) for shape in static_shapes}
        self._clear_boxes = [_EMPTY_BOX] * len(scenario.routes)
        zones = scenario.gps_denied_zones
        self._zone_centers = np.array([zone.center for zone in zones], dtype=float).reshape(-1, 2)
        self._zone_radii_sq = np.array([zone.radius for zone in zones], dtype=float) ** 2

    @property
    def landmarks(self) -> np.ndarray:
        return self.scenario.landmarks

    @property
    def n_robots(self) -> int:
        return len(self.robot_bodies)

    @property
    def poses(self) -> np.ndarray:
        """True poses ``[x, y, heading]`` of every robot (N, 3)."""
        return np.array(self._poses)

    @property
    def pose(self) -> np.ndarray:
        """True pose ``[x, y, heading]`` of robot 0 (the only robot of single-robot scenarios)."""
        return np.array(self._poses[0])

    @staticmethod
    def _read_pose(body: pymunk.Body) -> tuple[float, float, float]:
        x, y = body.position
        return x, y, wrap_angle(body.angle)

    def route_finished(self, robot: int = 0) -> bool:
        """True once robot ``robot``'s non-looping route has had its last waypoint reached."""
        return self.waypoint_indices[robot] >= len(self._waypoints[robot])

    def step(self, dt: float) -> np.ndarray:
        """Drive every robot toward its current waypoint for ``dt`` seconds.

        Returns:
            The executed ``[speed, turn_rate]`` of every robot (N, 2) [m/s, rad/s].

        Raises:
            ParameterError: (a ``ValueError``) unless ``dt`` is in ``TIME_STEP_S``, (0, 60] s.
        """
        if not 0.0 < dt <= MAX_TIME_STEP_S:
            TIME_STEP_S.check("World.step", "dt", dt)
        speeds = []
        for robot, (body, (x, y, heading)) in enumerate(zip(self.robot_bodies, self._poses)):
            speed, turn_rate = self._waypoint_control(robot, x, y, heading)
            body.velocity = (speed * math.cos(heading), speed * math.sin(heading))
            body.angular_velocity = turn_rate
            speeds.append(speed)
        substeps = math.ceil(dt / self.max_physics_step_s - 1e-9) if self._contact_within(speeds, dt) else 1
        for _ in range(substeps):
            self.space.step(dt / substeps)
        poses_before, self._poses = self._poses, [self._read_pose(body) for body in self.robot_bodies]
        controls = np.empty((len(speeds), 2))
        for robot, (before, after) in enumerate(zip(poses_before, self._poses)):
            controls[robot] = unicycle_control(before, after, dt)
        return controls

    def _waypoint_control(self, robot: int, x: float, y: float, heading: float) -> tuple[float, float]:
        waypoints, route = self._waypoints[robot], self.scenario.routes[robot]
        for _ in range(len(waypoints) + 1):
            if self.waypoint_indices[robot] >= len(waypoints):
                break
            target_x, target_y = waypoints[self.waypoint_indices[robot]]
            if math.hypot(target_x - x, target_y - y) > self.waypoint_tolerance_m:
                heading_error = wrap_angle(math.atan2(target_y - y, target_x - x) - heading)
                turn_rate = max(-self.max_turn_rate_rps, min(self.max_turn_rate_rps, self.heading_gain * heading_error))
                return route.speed_mps * max(math.cos(heading_error), 0.0), turn_rate
            self.waypoint_indices[robot] += 1
            if route.loop and self.waypoint_indices[robot] >= len(waypoints):
                self.waypoint_indices[robot] = 0
        return 0.0, 0.0

    def _contact_within(self, speeds: list[float], dt: float) -> bool:
        """Whether some robot may touch a wall, an obstacle or another robot within ``dt`` (then physics substeps)."""
        poses, contact_m = self._poses, 2 * self.robot_radius_m
        for i, (x_i, y_i, _) in enumerate(poses):
            for j in range(i + 1, len(poses)):
                x_j, y_j, _ = poses[j]
                reach = contact_m + (speeds[i] + speeds[j]) * dt
                if (x_j - x_i) ** 2 + (y_j - y_i) ** 2 < reach * reach:
                    return True
        radius_m = self.robot_radius_m
        return any(self._static_shape_within(robot, radius_m + speed * dt) for robot, speed in enumerate(speeds))

    def _static_shape_within(self, robot: int, reach: float) -> bool:
        """Whether a wall or obstacle's bounding box comes within ``reach`` [m] of the robot's centre.

        A box around the robot found empty is remembered, so the Pymunk query runs only
        once the robot's reach leaves it, or near walls and obstacles.
        """
        x, y, _ = self._poses[robot]
        left, bottom, right, top = x - reach, y - reach, x + reach, y + reach
        clear_left, clear_bottom, clear_right, clear_top = self._clear_boxes[robot]
        if clear_left <= left and clear_bottom <= bottom and right <= clear_right and top <= clear_top:
            return False
        margin = reach + _CLEAR_BOX_MARGIN_M
        clear_box = (x - margin, y - margin, x + margin, y + margin)
        nearby = self.space.bb_query(pymunk.BB(*clear_box), _OBSTACLES_ONLY)
        if not nearby:
            self._clear_boxes[robot] = clear_box
            return False
        boxes = (self._static_boxes[shape] for shape in nearby)
        return any(  # the overlap test of bb_query
            box_left <= right and left <= box_right and box_bottom <= top and bottom <= box_top
            for box_left, box_bottom, box_right, box_top in boxes
        )

    def line_of_sight(self, origin, targets) -> np.ndarray:
        """For each target point (N, 2), whether the straight line from ``origin`` misses every wall and obstacle.

        Robots do not block the line of sight.
        """
        start = (float(origin[0]), float(origin[1]))
        query = self.space.segment_query_first
        return np.array(
            [query(start, (float(x), float(y)), 0.0, _OBSTACLES_ONLY) is None for x, y in np.atleast_2d(targets)],
            dtype=bool,
        )

    def robots_in_sight(self, pairs) -> list[bool]:
        """For each pair ``(i, j)`` of robot indices, whether walls and obstacles leave a clear line between them."""
        query, poses = self.space.segment_query_first, self._poses
        return [query(poses[i][:2], poses[j][:2], 0.0, _OBSTACLES_ONLY) is None for i, j in pairs]

    def gps_denied(self, positions) -> np.ndarray:
        """For each position (N, 2) [m], whether it lies inside one of the scenario's GPS-denied zones."""
        positions = np.atleast_2d(np.asarray(positions, dtype=float))
        if positions.ndim != 2 or positions.shape[1] != 2:
            raise ValueError(f"positions must be an (N, 2) array of x, y [m], got shape {positions.shape}")
        offsets = positions[:, None, :] - self._zone_centers
        return np.any(np.einsum("nzi,nzi->nz", offsets, offsets) <= self._zone_radii_sq, axis=1)
