"""The world of ``ActiveLocalization-v0``: its goal-field scenario (its robot drives by velocity commands)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from infonav_gym.compiled import inline, kernel
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
    """A square field crossed from a start on the left to a goal on the right (the route's one waypoint).

    Two landmarks lie ahead of the start and one before the goal, near the straight line; the others line the
    middle on one random (lit) side, ``lit_offset_m`` off the line: with a shorter sensor range a robot sees them
    only by detouring. Round obstacles stand on the dark half, clear of the line by their radius + 2 m.

    Raises:
        ValueError: for an argument outside ``GOAL_FIELD_ARGUMENTS`` or a size below three lit offsets
            (``ParameterError``), or obstacles that do not fit.
    """
    return goal_field_scenarios(goal_field_layouts([np_random], n_landmarks, n_obstacles, size_m, lit_offset_m))[0]


class GoalFieldLayouts(NamedTuple):
    """The layouts of n goal fields (``goal_field``'s), stacked: starts, goals (n, 2), headings toward the goals
    (n,) [rad], landmarks (n, K, 2), obstacle centres (n, O, 2) and radii (n, O) [m]."""

    size_m: float
    starts: np.ndarray
    headings: np.ndarray
    goals: np.ndarray
    landmarks: np.ndarray
    obstacle_centers: np.ndarray
    obstacle_radii: np.ndarray


def goal_field_layouts(
    generators: list[np.random.Generator],
    n_landmarks: int = 8,
    n_obstacles: int = 4,
    size_m: float = 40.0,
    lit_offset_m: tuple[float, float] = LIT_OFFSET_M,
) -> GoalFieldLayouts:
    """``goal_field``'s layout from each of ``generators`` (the same draws), checked once, in one kernel call."""
    check_arguments("goal_field", GOAL_FIELD_ARGUMENTS, n_landmarks=n_landmarks, n_obstacles=n_obstacles, size_m=size_m)
    if size_m < 3 * max(lit_offset_m):
        raise ParameterError("goal_field", "size_m", f">= {3 * max(lit_offset_m):g} m for its layout", size_m)
    n_near = START_CLUSTER_LANDMARKS + GOAL_CLUSTER_LANDMARKS  # draws: the frame's, 3 per near landmark, 2 per lit
    u = np.array([np_random.random(3 + 3 * n_near + 2 * (n_landmarks - n_near)) for np_random in generators])
    ends = np.empty((len(u), 2, 2))  # each field's start and goal [m]
    ends[:, :, 0] = START_MARGIN_M, size_m - START_MARGIN_M
    ends[:, :, 1] = _uniform(u[:, :2], 0.4, 0.6) * size_m
    offsets = ends[:, 1] - ends[:, 0]
    lengths_m = np.array([float(np.linalg.norm(offset)) for offset in offsets])  # each the norm of a single field
    frames = (ends, offsets / lengths_m[:, None], lengths_m, np.where(u[:, 2] < 0.5, 1.0, -1.0))  # lit side: +-1
    layouts = drawn_layouts(generators, u[:, 3:], n_obstacles, frames, lit_offset_m, size_m)
    headings = np.array([math.atan2(y, x) for x, y in frames[1].tolist()])
    return GoalFieldLayouts(size_m, ends[:, 0], headings, ends[:, 1], *layouts)


def goal_field_scenarios(layouts: GoalFieldLayouts) -> list[Scenario]:
    """The ``Scenario`` of each goal field of ``layouts``: its route from the start (facing the goal) to the goal."""
    size_m = layouts.size_m
    walls = _box_walls(0.0, 0.0, size_m, size_m)
    fields = zip(
        layouts.starts.tolist(),
        layouts.headings.tolist(),
        layouts.goals,
        layouts.landmarks,
        layouts.obstacle_centers.tolist(),
        layouts.obstacle_radii.tolist(),
    )
    return [
        Scenario(
            name="goal_field",
            bounds=(0.0, 0.0, size_m, size_m),
            routes=(Route((*start, heading), goal[None, :]),),
            walls=walls,
            obstacles=tuple(CircleObstacle((x, y), radius) for (x, y), radius in zip(centers, radii)),
            landmarks=landmarks,
        )
        for start, heading, goal, landmarks, centers, radii in fields
    ]


def drawn_layouts(generators, u, n_obstacles: int, frames: tuple, lit_offset_m, size_m: float, attempts: int = 0):
    """``field_layouts`` of each generator's field: ``attempts`` obstacle draws ahead (0: ``OBSTACLE_ATTEMPTS_AHEAD``
    per obstacle), the generator rewound to take exactly those used; twice as many again where too few
    (``ValueError`` past 1000 per obstacle). ``(landmarks (n, K, 2), centres (n, O, 2), radii (n, O))`` [m]."""
    attempts, most_attempts = attempts or OBSTACLE_ATTEMPTS_AHEAD * max(n_obstacles, 4), 1000 * max(n_obstacles, 1)
    states = [np_random.bit_generator.state for np_random in generators]
    drawn = np.array([np_random.random((attempts, 3)) for np_random in generators])
    *layouts, used = field_layouts(u, drawn, n_obstacles, *frames, *lit_offset_m, size_m)
    for np_random, state, count in zip(generators, states, used.tolist()):
        np_random.bit_generator.state = state
        np_random.random((max(count, 0), 3))  # the attempts used; none where too few: drawn again, more
    short = np.flatnonzero(used < 0)
    if short.size and attempts >= most_attempts:
        raise ValueError(f"could not place {n_obstacles} obstacles on the dark side after many attempts: too crowded")
    if short.size:
        retried = [generators[field] for field in short.tolist()], u[short], n_obstacles
        frames = tuple(part[short] for part in frames)
        again = min(2 * attempts, most_attempts)
        for array, part in zip(layouts, drawn_layouts(*retried, frames, lit_offset_m, size_m, again)):
            array[short] = part
    return layouts


@kernel
def field_layouts(u, attempts, n_obstacles, ends, alongs, lengths_m, lit_sides, lit_low_m, lit_high_m, size_m):
    """The layouts of n goal fields from their landmarks' draws ``u`` (n, D) and obstacle ``attempts`` (n, M, 3),
    their frames (``ends``: start and goal (n, 2, 2), the unit vectors ``alongs`` from one to the other (n, 2), their
    distances ``lengths_m`` (n,), ``lit_sides`` (n,) +-1): landmarks (n, K, 2) (``place_landmarks``), obstacle
    centres (n, O, 2) and radii (n, O) [m] (``place_obstacles``), and the attempts each used (n,), -1: too few."""
    n_fields, n_near = len(u), START_CLUSTER_LANDMARKS + GOAL_CLUSTER_LANDMARKS
    landmarks = np.empty((n_fields, n_near + (u.shape[1] - 3 * n_near) // 2, 2))
    centers, radii = np.empty((n_fields, n_obstacles, 2)), np.empty((n_fields, n_obstacles))
    used = np.empty(n_fields, dtype=np.int64)
    for f in range(n_fields):
        frame = (ends[f, 0], alongs[f], lengths_m[f], lit_sides[f])
        place_landmarks(landmarks[f], u[f], *frame, lit_low_m, lit_high_m, size_m)
        used[f] = place_obstacles(centers[f], radii[f], attempts[f], landmarks[f], *frame, ends[f, 1], size_m)
    return landmarks, centers, radii, used


@inline
def place_landmarks(landmarks, u, start, along, length_m, lit_side, lit_low_m, lit_high_m, size_m):
    """One field's landmarks into ``landmarks`` (K, 2) from their draws ``u``: those near the line (side, place along,
    offset each; the first ``START_CLUSTER_LANDMARKS`` ahead of the start), then the lit ones (place, offset each)."""
    n_near = START_CLUSTER_LANDMARKS + GOAL_CLUSTER_LANDMARKS
    n_lit = len(landmarks) - n_near
    for k in range(len(landmarks)):
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


@inline
def place_obstacles(centers, radii, attempts, landmarks, start, along, length_m, lit_side, goal, size_m):
    """One field's obstacles into ``centers`` (O, 2) and ``radii`` (O,): the first O clear ``attempts`` (M, 3)
    (radius, place along, offset on the dark side; clear: inside the field, off the ``landmarks`` and the goal);
    the attempts used, -1: too few."""
    n_obstacles, placed = len(radii), 0
    for m in range(len(attempts)):
        if placed == n_obstacles:
            return m
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
    return len(attempts) if placed == n_obstacles else -1
