"""``WorldBatch``: N copies of a world of robots driving among walls and obstacles, stepped at once on stacked arrays.

A step with nothing within reach of a copy's robots is free motion, integrated as Pymunk integrates a free body
(compiled: ``motion_kernels``); otherwise the copy steps in its own Pymunk space (``physics.ContactSpace``), unless
the straight paths keep ``CONTACT_GAP_M`` off everything outside a run of contact steps (Pymunk would find no
contact: its substeps run here, the same numbers). So every copy moves as Pymunk moves it
(``tests/test_pymunk_oracle.py``). ``World`` is its N = 1 view.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.geometry import wrap_angle
from infonav_gym.world.motion_kernels import (
    contact_free,
    contact_within,
    executed_controls,
    free_substeps,
    unicycle_moves,
    waypoint_controls,
)
from infonav_gym.world.physics import MAX_TIME_STEP_S, TIME_STEP_S, WORLD_ARGUMENTS, ContactSpace, static_boxes
from infonav_gym.world.scenarios import Scenario
from infonav_gym.world.visibility import StaticGeometry, shape_arrays

_EMPTY_BOX = (np.inf, np.inf, -np.inf, -np.inf)  # a padding box that overlaps nothing
CONTACT_GAP_M = 1e-3  # paths this far beyond touching anything take Pymunk's contact-free substeps here [m]
MAX_IDLE_SPACES = 64  # Pymunk spaces kept for copies between runs of contact steps (a few hundred kB each)


class WorldBatch:
    """N >= 1 copies of a world, each with R robots: ``poses`` (N, R, 3) ``[x, y, heading]``; ``static_geometry``
    (the copies' ``StaticGeometry``, when the owner keeps it, else None: built here). Arguments: ``WORLD_ARGUMENTS``
    (``ParameterError`` outside them)."""

    def __init__(
        self,
        n_copies: int,
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
        self._spaces: list[ContactSpace | None] = [None] * n_copies  # built when a copy first needs Pymunk
        self._scenarios: list[Scenario | None] = [None] * n_copies
        self.static_geometry: StaticGeometry | None = None
        self._grown: StaticGeometry | None = None  # every copy's static shapes, grown for the contact test
        self._grown_stale = np.ones(n_copies, dtype=bool)  # copies reset since: rebuilt when a free step needs them
        self._in_contact = np.zeros(n_copies, dtype=bool)  # the copy's last step was a contact step
        self._has_space = np.zeros(n_copies, dtype=bool)  # the copy holds a Pymunk space (``_spaces[copy]``)
        self._waypoints = np.zeros((n_copies, 0, 0, 2))
        self._resize_robots(0)  # the robots' arrays, sized at the first reset
        self._boxes = np.full((n_copies, 0, 4), _EMPTY_BOX)

    @property
    def n_copies(self) -> int:
        return len(self._spaces)

    def scenario(self, copy: int) -> Scenario:
        """The scenario copy ``copy`` was last reset to."""
        return self._scenarios[copy]

    def reset_copy(self, copy: int, scenario: Scenario) -> None:
        """Put copy ``copy``'s robots at the starts of ``scenario``'s routes (``ValueError`` unless R of them)."""
        routes = scenario.routes
        if (copy == 0 or self.poses.shape[1] == 0) and len(routes) != self.poses.shape[1]:
            self._resize_robots(len(routes))
        if len(routes) != self.poses.shape[1]:
            raise ValueError(
                f"WorldBatch copy {copy}: scenario {scenario.name!r} has {len(routes)} robots, the other copies "
                f"{self.poses.shape[1]}; every copy needs the same number"
            )
        self._scenarios[copy], self._spaces[copy], self._has_space[copy] = scenario, None, False
        self._grown_stale[copy], self._in_contact[copy] = True, False
        self.poses[copy] = start_poses(scenario)
        self._waypoints = _widened(self._waypoints, max(len(route.waypoints) for route in routes), (0.0, 0.0))
        for robot, route in enumerate(routes):
            self._waypoints[copy, robot, : len(route.waypoints)] = route.waypoints
        self._n_waypoints[copy] = [len(route.waypoints) for route in routes]
        self._waypoint_index[copy] = 0
        self._route_speeds[copy] = [route.speed_mps for route in routes]
        self._loops[copy] = [route.loop for route in routes]
        boxes = static_boxes(scenario, self.wall_thickness_m)
        self._boxes = _widened(self._boxes, len(boxes), _EMPTY_BOX)
        self._boxes[copy] = _EMPTY_BOX
        self._boxes[copy, : len(boxes)] = boxes

    def _resize_robots(self, n_robots: int) -> None:
        n = self.n_copies
        self.poses = np.zeros((n, n_robots, 3))
        self._waypoints = np.zeros((n, n_robots, self._waypoints.shape[2], 2))
        self._n_waypoints = np.zeros((n, n_robots), dtype=int)
        self._waypoint_index = np.zeros((n, n_robots), dtype=int)
        self._route_speeds = np.zeros((n, n_robots))
        self._loops = np.zeros((n, n_robots), dtype=bool)

    def step(self, dt: float, copies: np.ndarray, commands: np.ndarray | None = None) -> np.ndarray:
        """Drive the robots of ``copies`` (n,) ascending for ``dt`` seconds (``TIME_STEP_S``) by ``commands`` (n, R, 2)
        ``[speed, turn_rate]``, or None: their waypoint controllers. Returns the executed (n, R, 2) [m/s, rad/s]."""
        if not 0.0 < dt <= MAX_TIME_STEP_S:
            TIME_STEP_S.check("World.step", "dt", dt)
        rows = slice(None) if len(copies) == self.n_copies else copies  # all copies: views, no fancy-index copies
        before = self.poses[rows]
        controls = self._waypoint_controls(copies, before) if commands is None else np.asarray(commands, dtype=float)
        after = unicycle_moves(before, controls, dt)
        near_static, near_robots = contact_within(copies, before, controls, dt, self._boxes, self.robot_radius_m)
        was_in_contact = self._in_contact[rows]
        if np.count_nonzero(near_static) or np.count_nonzero(near_robots) or np.count_nonzero(was_in_contact):
            contact = near_static | near_robots
            self._contact_steps(copies, before, controls, after, contact, near_static, was_in_contact.copy(), dt)
        executed = executed_controls(before, after, dt)  # before ``poses`` changes: ``before`` may be its view
        self.poses[rows] = after
        return executed

    def _contact_steps(self, copies, before, controls, after, contact, near_static, was_in_contact, dt) -> None:
        """``step`` of the ``copies`` that may touch something (``contact`` (n,)) or did in their last step: those the
        contact-free test clears take Pymunk's substeps here, the others a step in their own Pymunk space (``after``
        (n, R, 3) updated in place)."""
        free = np.flatnonzero(contact & ~was_in_contact)
        if free.size:  # in the static shapes grown by a robot's radius and CONTACT_GAP_M
            shapes = shape_arrays(self._grown_geometry(copies[free]))
            moves = (before[free], controls[free], dt, 2 * self.robot_radius_m + CONTACT_GAP_M, near_static[free])
            free = free[contact_free(copies[free], *moves, *shapes)]
            substeps = math.ceil(dt / self.max_physics_step_s - 1e-9)  # as ContactSpace.drive
            after[free] = free_substeps(before[free], controls[free], dt, substeps)  # Chipmunk's free-body integration
            contact[free] = False
        for copy in copies[was_in_contact & ~contact].tolist():  # their runs of contact steps end
            self._spaces[copy].end_contacts()
            if np.count_nonzero(self._has_space & ~self._in_contact) > MAX_IDLE_SPACES:
                self._spaces[copy], self._has_space[copy] = None, False  # built again, alike, at its next contact step
        self._in_contact[copies] = contact
        for row in np.flatnonzero(contact).tolist():
            after[row] = self.contact_space(int(copies[row])).drive(before[row], controls[row], dt)

    def contact_space(self, copy: int) -> ContactSpace:
        """Copy ``copy``'s Pymunk space as of its scenario (built when first asked for after ``reset_copy``)."""
        if self._spaces[copy] is None:
            arguments = self.robot_radius_m, self.wall_thickness_m, self.max_physics_step_s
            self._spaces[copy], self._has_space[copy] = ContactSpace(self._scenarios[copy], *arguments), True
        return self._spaces[copy]

    def _waypoint_controls(self, copies: np.ndarray, poses: np.ndarray) -> np.ndarray:
        """The waypoint controls ``[speed, turn_rate]`` (n, R, 2) of ``copies``; advances their waypoints."""
        routes = self._waypoint_index, self._n_waypoints, self._loops, self._waypoints, self._route_speeds
        return waypoint_controls(
            copies, poses, *routes, self.waypoint_tolerance_m, self.heading_gain, self.max_turn_rate_rps
        )

    def waypoint_indices(self, copy: int) -> list[int]:
        """The waypoint each robot of copy ``copy`` drives to next (its route's length once an open route ends)."""
        return self._waypoint_index[copy].tolist()

    def _grown_geometry(self, copies: np.ndarray) -> StaticGeometry:
        """The walls and obstacles of all N copies grown by ``robot_radius_m + CONTACT_GAP_M``, those of ``copies``
        (n,) as of their scenarios (each copy's built once per scenario, when a free step first needs it, unless
        given as ``static_geometry``)."""
        if self.static_geometry is not None:
            return self.static_geometry.grown(self.robot_radius_m + CONTACT_GAP_M)  # kept by the geometry
        stale = copies[self._grown_stale[copies]]
        if stale.size:
            fresh = StaticGeometry.from_scenarios([self._scenarios[copy] for copy in stale], self.wall_thickness_m)
            fresh = fresh.grown(self.robot_radius_m + CONTACT_GAP_M)
            self._grown = (fresh.tiled(self.n_copies) if self._grown is None else self._grown).with_copies(stale, fresh)
            self._grown_stale[stale] = False
        return self._grown


def _widened(array: np.ndarray, size: int, fill: tuple) -> np.ndarray:
    """``array`` (..., C, K) filled up with rows ``fill`` (K,) to ``size`` rows along its next to last axis."""
    if size <= array.shape[-2]:
        return array
    rows = np.broadcast_to(fill, (*array.shape[:-2], size - array.shape[-2], array.shape[-1]))
    return np.concatenate([array, rows], axis=-2)


def start_poses(scenario: Scenario) -> list[tuple[float, float, float]]:
    """Each robot's pose ``(x, y, heading)`` at the start of its route, heading wrapped to [-pi, pi)."""
    return [(*route.start_pose[:2], wrap_angle(route.start_pose[2])) for route in scenario.routes]
