"""Compiled robot motion of ``WorldBatch``, one robot of one copy at a time.

Poses are ``[x, y, heading]`` [m, m, rad], controls ``[speed, turn_rate]`` [m/s, rad/s]; arrays carry the copies
first and the robots second. Free motion is integrated as Pymunk integrates a free body (``free_substeps``: the
operations of Chipmunk's integration, in its order), so a step taken here gives Pymunk's numbers.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import kernel
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.world.clearance_kernels import teammate_conflicts
from infonav_gym.world.visibility_kernels import blocked


@kernel
def waypoint_controls(copies, poses, index, n_waypoints, loops, waypoints, route_speeds, tolerance_m, gain, max_turn):
    """The waypoint controls (n, R, 2) of the robots (poses (n, R, 3)) of ``copies`` (n,); advances ``index`` (N, R).

    Heading error times ``gain`` saturated at ``max_turn``, the route's speed times the error's cosine (none facing
    away); a waypoint within ``tolerance_m`` is passed (a looping route restarts, an open one ends: a stop).
    """
    n_rows, n_robots = poses.shape[0], poses.shape[1]
    last = waypoints.shape[2] - 1
    controls = np.zeros((n_rows, n_robots, 2))
    for row in range(n_rows):
        copy = copies[row]
        for robot in range(n_robots):
            current, count = index[copy, robot], n_waypoints[copy, robot]
            x, y, heading = poses[row, robot, 0], poses[row, robot, 1], poses[row, robot, 2]
            for attempt in range(last + 2):
                if attempt > count or current >= count:  # past the end, or looped all round: stop
                    break
                target = waypoints[copy, robot, min(current, last)]
                offset_x, offset_y = target[0] - x, target[1] - y
                if math.hypot(offset_x, offset_y) > tolerance_m:
                    heading_error = wrap(math.atan2(offset_y, offset_x) - heading)
                    controls[row, robot, 1] = min(max(gain * heading_error, -max_turn), max_turn)
                    controls[row, robot, 0] = route_speeds[copy, robot] * max(math.cos(heading_error), 0.0)
                    break
                current += 1
                if loops[copy, robot] and current >= count:
                    current = 0
            index[copy, robot] = current
    return controls


def unicycle_moves(poses, controls, dt):
    """Each robot driven straight along its heading for ``dt`` [s], heading turned at its rate: (n, R, 3)."""
    return free_substeps(poses, controls, dt, 1)


@kernel
def executed_controls(before, after, dt):
    """The ``[speed, turn_rate]`` that took each robot from ``before`` to ``after`` in ``dt`` [s]: (n, R, 2)."""
    controls = np.empty((before.shape[0], before.shape[1], 2))
    for row in range(before.shape[0]):
        for robot in range(before.shape[1]):
            heading = before[row, robot, 2]
            dx, dy = after[row, robot, 0] - before[row, robot, 0], after[row, robot, 1] - before[row, robot, 1]
            controls[row, robot, 0] = (dx * math.cos(heading) + dy * math.sin(heading)) / dt
            controls[row, robot, 1] = wrap(after[row, robot, 2] - heading) / dt
    return controls


@kernel
def free_substeps(poses, controls, dt, substeps):
    """The poses (n, R, 3) after ``substeps`` of Chipmunk's free-body integration over ``dt`` [s] (no contact)."""
    step_s = dt / substeps
    after = np.empty_like(poses)
    for row in range(poses.shape[0]):
        for robot in range(poses.shape[1]):
            x, y, angle = poses[row, robot, 0], poses[row, robot, 1], poses[row, robot, 2]
            speed, turn_rate = controls[row, robot, 0], controls[row, robot, 1]
            velocity_x, velocity_y = speed * math.cos(angle), speed * math.sin(angle)
            for _ in range(substeps):
                x, y, angle = x + velocity_x * step_s, y + velocity_y * step_s, angle + turn_rate * step_s
            after[row, robot, 0], after[row, robot, 1], after[row, robot, 2] = x, y, wrap(angle)
    return after


@kernel
def contact_within(copies, poses, controls, dt, boxes, radius_m):
    """Which of ``copies`` have a static box and which two robots (n,) within reach ``radius_m + speed * dt``."""
    n_rows, n_robots = poses.shape[0], poses.shape[1]
    near_static, near_robots = np.zeros(n_rows, dtype=np.bool_), np.zeros(n_rows, dtype=np.bool_)
    for row in range(n_rows):
        copy = copies[row]
        for robot in range(n_robots):
            reach = radius_m + controls[row, robot, 0] * dt
            x, y = poses[row, robot, 0], poses[row, robot, 1]
            low_x, low_y, high_x, high_y = x - reach, y - reach, x + reach, y + reach
            for shape in range(boxes.shape[1]):
                box = boxes[copy, shape]
                if box[0] <= high_x and low_x <= box[2] and box[1] <= high_y and low_y <= box[3]:
                    near_static[row] = True
                    break
            for other in range(robot + 1, n_robots):
                offset_x = poses[row, other, 0] - x
                offset_y = poses[row, other, 1] - y
                pair_reach = 2 * radius_m + (controls[row, robot, 0] + controls[row, other, 0]) * dt
                if offset_x**2 + offset_y**2 < pair_reach * pair_reach:
                    near_robots[row] = True
    return near_static, near_robots


@kernel
def contact_free(copies, poses, controls, dt, robots_contact_m, near_static, walls, discs, culled):
    """Which of ``copies`` (n,) keep clear of contact in ``dt`` [s], each robot straight along its heading (as in a
    contact-free Pymunk step): two robots stay ``robots_contact_m`` [m] apart, and in the copies ``near_static`` (n,)
    its line misses ``walls``, ``discs`` (``visibility.shape_arrays`` of the shapes grown by a robot's reach)."""
    n_rows, n_robots = poses.shape[0], poses.shape[1]
    starts, ends = np.empty((n_rows * n_robots, 2)), np.empty((n_rows * n_robots, 2))
    displacements = np.empty((n_rows, n_robots, 1, 2))
    for line in range(n_rows * n_robots):  # every robot's line, the copies not near_static's unused
        row, robot = line // n_robots, line % n_robots
        reach, heading = controls[row, robot, 0] * dt, poses[row, robot, 2]
        displacements[row, robot, 0, 0] = reach * math.cos(heading)
        displacements[row, robot, 0, 1] = reach * math.sin(heading)
        for i in range(2):
            starts[line, i] = poses[row, robot, i]
            ends[line, i] = starts[line, i] + displacements[row, robot, 0, i]
    conflicts = teammate_conflicts(starts.reshape(n_rows, n_robots, 2), displacements, robots_contact_m)
    hits = blocked(np.repeat(copies, n_robots), starts, ends, walls, discs, culled)
    free = np.ones(n_rows, dtype=np.bool_)
    for line in range(n_rows * n_robots):
        row, robot = line // n_robots, line % n_robots
        free[row] &= not (near_static[row] and hits[line])
        for other in range(n_robots):
            free[row] &= not conflicts[row, robot, 0, other, 0]
    return free
