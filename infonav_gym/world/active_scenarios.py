"""The world of ``ActiveLocalization-v0``: its goal-field scenario (its robot drives by velocity commands)."""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import kernel
from infonav_gym.config import Interval, ParameterError, check_arguments
from infonav_gym.world.scenarios import (
    FIELD_ARGUMENTS,
    MAX_FIELD_SIZE_M,
    MAX_LANDMARKS,
    CircleObstacle,
    Route,
    Scenario,
    _box_walls,
    _uniform,
)

START_MARGIN_M = 2.5  # distance of the start and the goal from the left and right walls [m]
START_CLUSTER_LANDMARKS = 2
GOAL_CLUSTER_LANDMARKS = 1
MIN_GOAL_FIELD_LANDMARKS = START_CLUSTER_LANDMARKS + GOAL_CLUSTER_LANDMARKS + 1
LIT_OFFSET_M = (7.0, 11.0)  # distance of the lit-side landmarks from the straight line start-goal [m]
MIN_GOAL_FIELD_SIZE_M = 3 * LIT_OFFSET_M[1]
OBSTACLE_ATTEMPTS_AHEAD = 4  # attempts drawn at once per obstacle, more if too few are clear (the same numbers)
GOAL_FIELD_ARGUMENTS = {  # the allowed arguments of goal_field (a size of at least 3 lit offsets)
    "n_landmarks": Interval(MIN_GOAL_FIELD_LANDMARKS, MAX_LANDMARKS, integer=True),
    "n_obstacles": FIELD_ARGUMENTS["n_obstacles"],
    "size_m": Interval(MIN_GOAL_FIELD_SIZE_M, MAX_FIELD_SIZE_M, unit="m"),
}


def goal_field(
    np_random: np.random.Generator,
    n_landmarks: int = 8,
    n_obstacles: int = 4,
    size_m: float = 40.0,
    lit_offset_m: tuple[float, float] = LIT_OFFSET_M,
) -> Scenario:
    """A square field crossed from a start on the left to a goal on the right; landmarks light only parts of it.

    Two landmarks lie ahead of the start and one before the goal, within a few metres
    of the straight line between them; the others line the middle of the crossing on
    one side only (the *lit* side, drawn at random), ``lit_offset_m`` away from the
    straight line. With a sensor range shorter than that offset, the middle of the
    straight line is dark: a robot keeps seeing landmarks there only by detouring to
    the lit side. Round obstacles stand on the dark half, clear of the straight line
    by their radius + 2 m, where they can hide the start and goal landmarks.

    The route holds the start pose (facing the goal) and the goal as its one waypoint.

    Raises:
        ParameterError: (a ``ValueError``) for an argument outside its ``GOAL_FIELD_ARGUMENTS`` interval, or a
            size below three times the largest lit offset.
        ValueError: when the obstacles do not fit.
    """
    check_arguments("goal_field", GOAL_FIELD_ARGUMENTS, n_landmarks=n_landmarks, n_obstacles=n_obstacles, size_m=size_m)
    if size_m < 3 * max(lit_offset_m):
        raise ParameterError("goal_field", "size_m", f">= {3 * max(lit_offset_m):g} m for its layout", size_m)
    n_near = START_CLUSTER_LANDMARKS + GOAL_CLUSTER_LANDMARKS  # draws: the frame's, 3 per near landmark, 2 per lit
    n_draws = 3 + 3 * n_near + 2 * (n_landmarks - n_near)
    u = np_random.random(n_draws)
    start = np.array([START_MARGIN_M, _uniform(u[0], 0.4, 0.6) * size_m])
    goal = np.array([size_m - START_MARGIN_M, _uniform(u[1], 0.4, 0.6) * size_m])
    length_m = float(np.linalg.norm(goal - start))
    frame = (start, (goal - start) / length_m, length_m, 1.0 if u[2] < 0.5 else -1.0)  # the lit side: +-1
    state, attempts = np_random.bit_generator.state, OBSTACLE_ATTEMPTS_AHEAD * max(n_obstacles, 4)
    most_attempts = 1000 * max(n_obstacles, 1)
    while True:  # the obstacles' attempts (radius, place along, offset) drawn ahead, then exactly those used taken
        layout = field_layout(u[3:], np_random.random((attempts, 3)), n_obstacles, *frame, *lit_offset_m, goal, size_m)
        np_random.bit_generator.state = state
        if layout[3] >= 0 or attempts >= most_attempts:
            break
        attempts = min(2 * attempts, most_attempts)
    landmarks, centers, radii, used = layout
    np_random.random((used if used >= 0 else attempts, 3))
    if used < 0:
        raise ValueError(f"could not place {n_obstacles} obstacles on the dark side after many attempts: too crowded")
    obstacles = [CircleObstacle((x, y), radius) for (x, y), radius in zip(centers.tolist(), radii.tolist())]
    route = Route((float(start[0]), float(start[1]), math.atan2(frame[1][1], frame[1][0])), goal[None, :])
    return Scenario(
        name="goal_field",
        bounds=(0.0, 0.0, size_m, size_m),
        routes=(route,),
        walls=_box_walls(0.0, 0.0, size_m, size_m),
        obstacles=tuple(obstacles),
        landmarks=landmarks,
    )


@kernel
def field_layout(u, attempts, n_obstacles, start, along, length_m, lit_side, lit_low_m, lit_high_m, goal, size_m):
    """``goal_field``'s landmarks (K, 2) from their draws ``u``: those near the line (side, place along, offset each;
    the first ``START_CLUSTER_LANDMARKS`` ahead of the start), then the lit ones (place, offset each); its obstacles,
    the first ``n_obstacles`` clear ``attempts`` (M, 3) (radius, place along, offset on the dark side; clear: inside
    the field, off the landmarks and the goal): centres (O, 2), radii (O,) [m]; and the attempts used, -1: too few."""
    n_near = START_CLUSTER_LANDMARKS + GOAL_CLUSTER_LANDMARKS
    n_lit = (len(u) - 3 * n_near) // 2
    landmarks = np.empty((n_near + n_lit, 2))
    for k in range(n_near + n_lit):
        if k < n_near:
            side = 1.0 if u[3 * k] < 0.5 else -1.0
            low, high = (0.06, 0.22) if k < START_CLUSTER_LANDMARKS else (0.8, 0.9)
            fraction, offset = low + (high - low) * u[3 * k + 1], side * (1.5 + (4.0 - 1.5) * u[3 * k + 2])
        else:
            draw = 3 * n_near + 2 * (k - n_near)
            fraction = 0.3 + 0.45 * ((k - n_near) + (0.2 + (0.8 - 0.2) * u[draw])) / n_lit
            offset = lit_side * (lit_low_m + (lit_high_m - lit_low_m) * u[draw + 1])
        for i in range(2):
            normal = -along[1] if i == 0 else along[0]
            value = start[i] + fraction * length_m * along[i] + offset * normal
            landmarks[k, i] = min(max(value, 1.0), size_m - 1.0)
    centers, radii, placed = np.empty((n_obstacles, 2)), np.empty(n_obstacles), 0
    for m in range(len(attempts)):
        if placed == n_obstacles:
            return landmarks, centers, radii, m
        radius, fraction = 0.7 + (1.5 - 0.7) * attempts[m, 0], 0.1 + (0.9 - 0.1) * attempts[m, 1]
        offset, clear = -lit_side * (radius + 2.0 + (8.0 - (radius + 2.0)) * attempts[m, 2]), True
        center = centers[placed]
        for i in range(2):
            center[i] = start[i] + fraction * length_m * along[i] + offset * (-along[1] if i == 0 else along[0])
            clear &= center[i] - radius > 0.5 and center[i] + radius < size_m - 0.5
        for k in range(len(landmarks)):
            dx, dy = landmarks[k, 0] - center[0], landmarks[k, 1] - center[1]
            clear &= math.sqrt(dx * dx + dy * dy) - radius > 0.5
        dx, dy = center[0] - goal[0], center[1] - goal[1]
        clear &= math.sqrt(dx * dx + dy * dy) > radius + 3.0
        radii[placed] = radius
        placed += 1 if clear else 0
    return landmarks, centers, radii, len(attempts) if placed == n_obstacles else -1
