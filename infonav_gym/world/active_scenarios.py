"""The world of ``ActiveLocalization-v0``: its goal-field scenario and a World driven by velocity commands."""

from __future__ import annotations

import math

import numpy as np

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
    _uniform_until_accepted,
)
from infonav_gym.world.world import World

START_MARGIN_M = 2.5  # distance of the start and the goal from the left and right walls [m]
START_CLUSTER_LANDMARKS = 2
GOAL_CLUSTER_LANDMARKS = 1
MIN_GOAL_FIELD_LANDMARKS = START_CLUSTER_LANDMARKS + GOAL_CLUSTER_LANDMARKS + 1
LIT_OFFSET_M = (7.0, 11.0)  # distance of the lit-side landmarks from the straight line start-goal [m]
MIN_GOAL_FIELD_SIZE_M = 3 * LIT_OFFSET_M[1]
GOAL_FIELD_ARGUMENTS = {  # the allowed arguments of goal_field (a size of at least 3 lit offsets)
    "n_landmarks": Interval(MIN_GOAL_FIELD_LANDMARKS, MAX_LANDMARKS, integer=True),
    "n_obstacles": FIELD_ARGUMENTS["n_obstacles"],
    "size_m": Interval(MIN_GOAL_FIELD_SIZE_M, MAX_FIELD_SIZE_M, unit="m"),
}


class CommandedWorld(World):
    """A ``World`` whose robots follow velocity commands instead of waypoints.

    ``command(speeds, turn_rates)`` sets what each robot drives during the next
    ``step``; Pymunk still executes it (obstacles stop or deflect the robot) and
    ``step`` returns the executed motion, as for ``World``.
    """

    def reset(self, scenario: Scenario) -> None:
        super().reset(scenario)
        self._commands = [(0.0, 0.0)] * self.n_robots

    def command(self, speed_mps: float, turn_rate_rps: float, robot: int = 0) -> None:
        """Drive robot ``robot`` at ``speed_mps`` [m/s] and ``turn_rate_rps`` [rad/s] until the next command."""
        self._commands[robot] = (float(speed_mps), float(turn_rate_rps))

    def _waypoint_control(self, robot: int, x: float, y: float, heading: float) -> tuple[float, float]:
        return self._commands[robot]


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
    start = np.array([START_MARGIN_M, np_random.uniform(0.4, 0.6) * size_m])
    goal = np.array([size_m - START_MARGIN_M, np_random.uniform(0.4, 0.6) * size_m])
    along = (goal - start) / np.linalg.norm(goal - start)
    normal = np.array([-along[1], along[0]])
    length_m = float(np.linalg.norm(goal - start))
    lit_side = 1.0 if np_random.random() < 0.5 else -1.0

    def near_line(fraction_low: float, fraction_high: float, offset_low: float, offset_high: float) -> np.ndarray:
        side = 1.0 if np_random.random() < 0.5 else -1.0
        fraction = np_random.uniform(fraction_low, fraction_high)
        return start + fraction * length_m * along + side * np_random.uniform(offset_low, offset_high) * normal

    landmarks = [near_line(0.06, 0.22, 1.5, 4.0) for _ in range(START_CLUSTER_LANDMARKS)]
    landmarks += [near_line(0.8, 0.9, 1.5, 4.0) for _ in range(GOAL_CLUSTER_LANDMARKS)]
    n_lit = n_landmarks - len(landmarks)
    for k in range(n_lit):
        fraction = 0.3 + 0.45 * (k + np_random.uniform(0.2, 0.8)) / n_lit
        offset = lit_side * np_random.uniform(*lit_offset_m)
        landmarks.append(start + fraction * length_m * along + offset * normal)
    landmarks = np.clip(np.array(landmarks), 1.0, size_m - 1.0)

    def obstacle_discs(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres (M, 2) and radii (M,) of the obstacles drawn as ``u`` (M, 3): radius, place along, offset."""
        radii = _uniform(u[:, 0], 0.7, 1.5)
        fractions, offsets = _uniform(u[:, 1], 0.1, 0.9), -lit_side * _uniform(u[:, 2], radii + 2.0, 8.0)
        return start + fractions[:, None] * length_m * along + offsets[:, None] * normal, radii

    def clear(u: np.ndarray) -> np.ndarray:
        centers, radii = obstacle_discs(u)
        inside = np.all(centers - radii[:, None] > 0.5, axis=1) & np.all(
            centers + radii[:, None] < size_m - 0.5, axis=1
        )
        gaps = np.linalg.norm(landmarks - centers[:, None], axis=-1) - radii[:, None]
        return inside & np.all(gaps > 0.5, axis=1) & (np.linalg.norm(centers - goal, axis=1) > radii + 3.0)

    u = _uniform_until_accepted(np_random, n_obstacles, 3, clear, "obstacles on the dark side")
    centers, radii = obstacle_discs(u)
    obstacles = [CircleObstacle((x, y), radius) for (x, y), radius in zip(centers.tolist(), radii.tolist())]
    heading = math.atan2(along[1], along[0])
    route = Route((float(start[0]), float(start[1]), heading), goal[None, :])
    return Scenario(
        name="goal_field",
        bounds=(0.0, 0.0, size_m, size_m),
        routes=(route,),
        walls=_box_walls(0.0, 0.0, size_m, size_m),
        obstacles=tuple(obstacles),
        landmarks=landmarks,
    )
