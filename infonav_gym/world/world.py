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
    """The robots of a scenario driving in a Pymunk world of walls and round obstacles.

    Each robot is a dynamic disc driven by a waypoint controller. Its pose is kept here; a step in which no wall,
    obstacle or other robot comes within reach of any robot is free motion, integrated as Pymunk integrates a free
    body (position += velocity x dt, angle += angular velocity x dt). Any other step is Pymunk's: the robots' discs
    are put at their poses with their velocities and the space is stepped in substeps, so walls, obstacles and the
    other robots stop or push them for real; the executed motion is read back, not assumed. The space is built at
    the first contact step or line-of-sight query after a ``reset``.

    Args:
        robot_radius_m: radius of every robot's disc [m].
        max_turn_rate_rps: saturation of the heading controller [rad/s].
        heading_gain: proportional gain of the heading controller [1/s].
        waypoint_tolerance_m: a waypoint closer than this counts as reached [m].
        wall_thickness_m: thickness of wall segments [m].
        max_physics_step_s: longest Pymunk substep [s] of a contact step, split into equal substeps.

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
        self._space: pymunk.Space | None = None
        self._robot_bodies: list[pymunk.Body] = []
        self._in_contact = False  # the last step was a Pymunk contact step
        self.waypoint_indices: list[int] = []
        self._poses: list[tuple[float, float, float]] = []  # true poses as of the last reset or step
        self._waypoints: list[list[list[float]]] = []
        self._static_boxes: list[tuple[float, float, float, float]] = []
        self._clear_boxes: list[tuple[float, float, float, float]] = []
        self._zone_centers = np.zeros((0, 2))
        self._zone_radii_sq = np.zeros(0)

    def reset(self, scenario: Scenario) -> None:
        """Put one robot at the start of each of ``scenario``'s routes (a fresh space is built when first needed)."""
        self.scenario = scenario
        self._space, self._robot_bodies, self._in_contact = None, [], False
        self._poses = start_poses(scenario)
        self._waypoints = [route.waypoints.tolist() for route in scenario.routes]
        self.waypoint_indices = [0] * len(scenario.routes)
        self._static_boxes = [tuple(box) for box in static_boxes(scenario, self.wall_thickness_m).tolist()]
        self._clear_boxes = [_EMPTY_BOX] * len(scenario.routes)
        zones = scenario.gps_denied_zones
        self._zone_centers = np.array([zone.center for zone in zones], dtype=float).reshape(-1, 2)
        self._zone_radii_sq = np.array([zone.radius for zone in zones], dtype=float) ** 2

    @property
    def space(self) -> pymunk.Space:
        """The Pymunk space of the scenario's walls, obstacles and robot discs (built on first use)."""
        if self._space is None:
            self._space, self._robot_bodies = self._build_space()
        return self._space

    def _build_space(self) -> tuple[pymunk.Space, list[pymunk.Body]]:
        space = pymunk.Space()
        space.collision_slop = 0.01  # allowed overlap [m]
        scenario = self.scenario
        static_shapes = [
            pymunk.Segment(space.static_body, start, end, self.wall_thickness_m / 2) for start, end in scenario.walls
        ]
        static_shapes += [
            pymunk.Circle(space.static_body, obstacle.radius, obstacle.center) for obstacle in scenario.obstacles
        ]
        for shape in static_shapes:
            shape.filter = pymunk.ShapeFilter(categories=OBSTACLE_CATEGORY)
        space.add(*static_shapes)
        bodies = []
        for _ in scenario.routes:
            body = pymunk.Body(_ROBOT_MASS_KG, pymunk.moment_for_circle(_ROBOT_MASS_KG, 0, self.robot_radius_m))
            shape = pymunk.Circle(body, self.robot_radius_m)
            shape.filter = pymunk.ShapeFilter(categories=ROBOT_CATEGORY)
            space.add(body, shape)
            bodies.append(body)
        return space, bodies

    @property
    def landmarks(self) -> np.ndarray:
        return self.scenario.landmarks

    @property
    def n_robots(self) -> int:
        return len(self._poses)

    @property
    def poses(self) -> np.ndarray:
        """True poses ``[x, y, heading]`` of every robot (N, 3)."""
        return np.array(self._poses)

    @property
    def pose(self) -> np.ndarray:
        """True pose ``[x, y, heading]`` of robot 0 (the only robot of single-robot scenarios)."""
        return np.array(self._poses[0])

    def step(self, dt: float) -> np.ndarray:
        """Drive every robot toward its current waypoint for ``dt`` seconds.

        Returns:
            The executed ``[speed, turn_rate]`` of every robot (N, 2) [m/s, rad/s].

        Raises:
            ParameterError: (a ``ValueError``) unless ``dt`` is in ``TIME_STEP_S``, (0, 60] s.
        """
        if not 0.0 < dt <= MAX_TIME_STEP_S:
            TIME_STEP_S.check("World.step", "dt", dt)
        controls = [self._waypoint_control(robot, *pose) for robot, pose in enumerate(self._poses)]
        poses_before = self._poses
        if self._contact_within([speed for speed, _ in controls], dt):
            self.drive_in_contact(controls, dt)
        else:
            self.end_contacts()
            self._poses = [
                (
                    x + speed * math.cos(heading) * dt,
                    y + speed * math.sin(heading) * dt,
                    wrap_angle(heading + turn * dt),
                )
                for (x, y, heading), (speed, turn) in zip(poses_before, controls)
            ]
        executed = np.empty((len(controls), 2))
        for robot, (before, after) in enumerate(zip(poses_before, self._poses)):
            executed[robot] = unicycle_control(before, after, dt)
        return executed

    def drive_in_contact(self, controls, dt: float) -> None:
        """Step the Pymunk space for ``dt`` in substeps with each robot driving its ``[speed, turn_rate]`` (R, 2)."""
        space = self.space
        for body, (x, y, heading), (speed, turn_rate) in zip(self._robot_bodies, self._poses, controls):
            body.position = x, y
            body.angle = heading
            body.velocity = (speed * math.cos(heading), speed * math.sin(heading))
            body.angular_velocity = turn_rate
        substeps = math.ceil(dt / self.max_physics_step_s - 1e-9)
        for _ in range(substeps):
            space.step(dt / substeps)
        self._poses = [(*body.position, wrap_angle(body.angle)) for body in self._robot_bodies]
        self._in_contact = True

    def end_contacts(self) -> None:
        """A free step ends a run of contact steps: Pymunk forgets the run's contacts (the robots leave and re-enter).

        Pymunk remembers recent contacts to warm-start its solver; forgetting them when a run ends makes every run
        start as in a fresh space, whatever came before, so a batched world may drop an idle copy's space to save
        its memory (a few hundred kB) and build it again for the next run, with the same numbers.
        """
        if not self._in_contact:
            return
        self._in_contact = False
        for body in self._robot_bodies:
            self._space.remove(body, *body.shapes)
        for body in self._robot_bodies:
            self._space.add(body, *body.shapes)

    def drop_space(self) -> None:
        """Free the Pymunk space (built again when next needed): only between runs of contact steps."""
        self._space, self._robot_bodies, self._in_contact = None, [], False

    def set_poses(self, poses) -> None:
        """Put the robots at ``poses`` (R, 3) [m, m, rad] (a batched world stepping this one's free motion)."""
        self._poses = [tuple(pose) for pose in np.asarray(poses, dtype=float).tolist()]

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
        """Whether some robot may touch a wall, an obstacle or another robot within ``dt`` (then Pymunk steps)."""
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

        A box around the robot found empty is remembered, so the boxes are searched only
        once the robot's reach leaves it, or near walls and obstacles.
        """
        x, y, _ = self._poses[robot]
        left, bottom, right, top = x - reach, y - reach, x + reach, y + reach
        clear_left, clear_bottom, clear_right, clear_top = self._clear_boxes[robot]
        if clear_left <= left and clear_bottom <= bottom and right <= clear_right and top <= clear_top:
            return False
        if any(_overlap(box, (left, bottom, right, top)) for box in self._static_boxes):
            return True
        margin = reach + _CLEAR_BOX_MARGIN_M
        clear_box = (x - margin, y - margin, x + margin, y + margin)
        if not any(_overlap(box, clear_box) for box in self._static_boxes):
            self._clear_boxes[robot] = clear_box
        return False

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

    def gps_denied(self, positions) -> np.ndarray:
        """For each position (N, 2) [m], whether it lies inside one of the scenario's GPS-denied zones."""
        positions = np.atleast_2d(np.asarray(positions, dtype=float))
        if positions.ndim != 2 or positions.shape[1] != 2:
            raise ValueError(f"positions must be an (N, 2) array of x, y [m], got shape {positions.shape}")
        offsets = positions[:, None, :] - self._zone_centers
        return np.any(np.einsum("nzi,nzi->nz", offsets, offsets) <= self._zone_radii_sq, axis=1)


def start_poses(scenario: Scenario) -> list[tuple[float, float, float]]:
    """Each robot's pose ``(x, y, heading)`` at the start of its route, heading wrapped to [-pi, pi)."""
    return [(*route.start_pose[:2], wrap_angle(route.start_pose[2])) for route in scenario.routes]


def static_boxes(scenario: Scenario, wall_thickness_m: float) -> np.ndarray:
    """Bounding boxes ``(left, bottom, right, top)`` of the scenario's walls, then obstacles (S, 4) [m], as Pymunk's."""
    boxes = [
        (
            min(a[0], b[0]) - wall_thickness_m / 2,
            min(a[1], b[1]) - wall_thickness_m / 2,
            max(a[0], b[0]) + wall_thickness_m / 2,
            max(a[1], b[1]) + wall_thickness_m / 2,
        )
        for a, b in scenario.walls
    ]
    boxes += [
        (o.center[0] - o.radius, o.center[1] - o.radius, o.center[0] + o.radius, o.center[1] + o.radius)
        for o in scenario.obstacles
    ]
    return np.array(boxes, dtype=float).reshape(-1, 4)


def _overlap(box, other) -> bool:
    """Whether two boxes ``(left, bottom, right, top)`` overlap or touch (the test of Pymunk's ``bb_query``)."""
    return box[0] <= other[2] and other[0] <= box[2] and box[1] <= other[3] and other[1] <= box[3]
