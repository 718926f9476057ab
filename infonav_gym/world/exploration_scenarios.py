"""The world of ``cooperative_exploration_v0``: a square field a team explores from a base in one corner."""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.config import Interval, check_arguments
from infonav_gym.world import scenarios
from infonav_gym.world.scenarios import (
    FIELD_ARGUMENTS,
    MAX_FIELD_SIZE_M,
    MAX_ROBOTS,
    TEAM_FIELD_ARGUMENTS,
    CircleObstacle,
    Route,
    Scenario,
)

BASE_INSET_M = 4.0  # distance of the base from the two walls of its corner [m]
BASE_SPACING_M = 2.0  # distance between neighbouring robots at the base [m]
BASE_CLEARANCE_M = 6.0  # landmarks, obstacles and canopies keep this far from the base [m]
MIN_EXPLORATION_FIELD_SIZE_M = 20.0
SPARSE_LANDMARKS = 4  # the default number of landmarks: one per 400 m^2 of the default 40 m field
EXPLORATION_FIELD_ARGUMENTS = {  # the allowed arguments of exploration_field
    "n_robots": Interval(1, MAX_ROBOTS, integer=True),
    "n_obstacles": FIELD_ARGUMENTS["n_obstacles"],
    "n_canopies": TEAM_FIELD_ARGUMENTS["n_canopies"],
    "n_landmarks": FIELD_ARGUMENTS["n_landmarks"],
    "size_m": Interval(MIN_EXPLORATION_FIELD_SIZE_M, MAX_FIELD_SIZE_M, unit="m"),
}


def exploration_field(
    np_random: np.random.Generator,
    *,
    n_robots: int = 4,
    n_obstacles: int = 6,
    n_canopies: int = 3,
    n_landmarks: int = SPARSE_LANDMARKS,
    size_m: float = 40.0,
) -> Scenario:
    """A square field with round obstacles, GPS-denied canopies and sparse landmarks, explored from a base.

    The robots start side by side at a base ``BASE_INSET_M`` from the walls of a random corner, facing the centre,
    with no waypoints (velocity commands). Landmarks, canopies (radius 5-9 m) and obstacles (0.7-1.5 m) are uniform,
    ``BASE_CLEARANCE_M`` (plus radius) off the base; obstacles 1 m off landmarks. ``ValueError`` for an argument
    outside ``EXPLORATION_FIELD_ARGUMENTS`` or a team or obstacles that do not fit.
    """
    counts = {"n_robots": n_robots, "n_obstacles": n_obstacles, "n_canopies": n_canopies, "n_landmarks": n_landmarks}
    check_arguments("exploration_field", EXPLORATION_FIELD_ARGUMENTS, **counts, size_m=size_m)
    if (n_robots - 1) * BASE_SPACING_M > size_m / 2:
        raise ValueError(f"exploration_field: {n_robots} robots {BASE_SPACING_M} m apart do not fit at the base")
    corner = int(4 * np_random.random())  # 0: lower left, then counter-clockwise
    inward = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])[corner]
    base = np.where(inward > 0, 0.0, size_m) + BASE_INSET_M * inward
    across = np.array([-inward[1], inward[0]]) / math.sqrt(2.0)
    offsets = (np.arange(n_robots) - 0.5 * (n_robots - 1)) * BASE_SPACING_M
    starts = base + offsets[:, None] * across
    heading = math.atan2(inward[1], inward[0])

    def far_from_base(points: np.ndarray, margin_m) -> np.ndarray:
        return np.linalg.norm(points - base, axis=-1) > BASE_CLEARANCE_M + margin_m

    def landmark_positions(u: np.ndarray) -> np.ndarray:
        return scenarios._uniform(u, 2.0, size_m - 2.0)

    u = scenarios._uniform_until_accepted(
        np_random, n_landmarks, 2, lambda u: far_from_base(landmark_positions(u), 0.0), "landmarks off the base"
    )
    landmarks = landmark_positions(u)

    def canopy_discs(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return scenarios._uniform(u[:, :2], 0.0, size_m), scenarios._uniform(u[:, 2], 5.0, 9.0)

    u = scenarios._uniform_until_accepted(
        np_random, n_canopies, 3, lambda u: far_from_base(*canopy_discs(u)), "GPS-denied zones off the base"
    )
    canopies = [CircleObstacle((x, y), r) for (x, y), r in zip(*(part.tolist() for part in canopy_discs(u)))]

    def obstacle_discs(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        radii = scenarios._uniform(u[:, 2], 0.7, 1.5)
        room = size_m - 2 * radii[:, None] - 1.0  # the centres keep the disc 0.5 m inside the walls
        return u[:, :2] * room + radii[:, None] + 0.5, radii

    def obstacles_clear(u: np.ndarray) -> np.ndarray:
        centers, radii = obstacle_discs(u)
        gaps = np.linalg.norm(landmarks - centers[:, None], axis=-1) - radii[:, None]
        return far_from_base(centers, radii) & np.all(gaps > 1.0, axis=1)

    u = scenarios._uniform_until_accepted(np_random, n_obstacles, 3, obstacles_clear, "obstacles off base, landmarks")
    obstacles = [CircleObstacle((x, y), r) for (x, y), r in zip(*(part.tolist() for part in obstacle_discs(u)))]
    return Scenario(
        name="exploration_field",
        bounds=(0.0, 0.0, size_m, size_m),
        routes=tuple(Route((float(x), float(y), heading), np.zeros((0, 2))) for x, y in starts),
        walls=scenarios._box_walls(0.0, 0.0, size_m, size_m),
        obstacles=tuple(obstacles),
        landmarks=landmarks.reshape(-1, 2),
        gps_denied_zones=tuple(canopies),
    )
