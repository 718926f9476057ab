"""Scenario builders: the static layout of a world, drawn from an explicit ``np_random``."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

CORRIDOR_LANDMARK_COUNT = 4


@dataclass(frozen=True)
class CircleObstacle:
    center: tuple[float, float]  # [m]
    radius: float  # [m]


@dataclass(frozen=True)
class Scenario:
    """Everything static about a world.

    Attributes:
        name: scenario name.
        bounds: ``(x_min, y_min, x_max, y_max)`` of the drawable area [m].
        walls: segments ``((x0, y0), (x1, y1))`` [m].
        obstacles: circular obstacles.
        landmarks: point landmark positions (L, 2) [m].
        waypoints: route the robot follows (W, 2) [m].
        start_pose: initial ``[x, y, heading]`` of the robot.
        loop_route: after the last waypoint, go back to the first (else stop there).
        speed_mps: cruise speed along the route [m/s].
    """

    name: str
    bounds: tuple[float, float, float, float]
    walls: tuple = ()
    obstacles: tuple = ()
    landmarks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    waypoints: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    loop_route: bool = False
    speed_mps: float = 1.0


def corridor(np_random: np.random.Generator, speed_mps: float = 0.5) -> Scenario:
    """The paper's Fig. 1: a straight corridor, the vehicle at its start, 4 candidate landmarks.

    Landmark #3 (index 2) is the closest and lies across the direction of travel,
    so it brings clearly more information than the others (Fig. 2). The layout is
    fixed; ``np_random`` is accepted for a uniform builder signature.
    """
    del np_random
    half_width, length = 3.0, 40.0
    walls = (
        ((-2.0, half_width), (length, half_width)),
        ((-2.0, -half_width), (length, -half_width)),
        ((-2.0, -half_width), (-2.0, half_width)),
        ((length, -half_width), (length, half_width)),
    )
    landmarks = np.array([[11.0, 2.2], [13.0, -2.2], [7.0, -2.2], [14.0, 2.2]])
    return Scenario(
        name="corridor",
        bounds=(-3.0, -4.0, length + 1.0, 4.0),
        walls=walls,
        landmarks=landmarks,
        waypoints=np.array([[length - 3.0, 0.0]]),
        start_pose=(0.0, 0.0, 0.0),
        speed_mps=speed_mps,
    )


def _distance_to_route(point: np.ndarray, route: np.ndarray) -> float:
    """Shortest distance from ``point`` to the closed polyline ``route``."""
    starts, ends = route, np.roll(route, -1, axis=0)
    direction = ends - starts
    t = np.clip(np.einsum("ij,ij->i", point - starts, direction) / np.einsum("ij,ij->i", direction, direction), 0, 1)
    return float(np.min(np.linalg.norm(starts + t[:, None] * direction - point, axis=1)))


def _rejection_sample(count: int, draw, accept, what: str, max_attempts_each: int = 1000) -> list:
    """Draw until ``count`` samples pass ``accept``; a clear error if the layout is too crowded."""
    accepted = []
    for _ in range(max_attempts_each * max(count, 1)):
        if len(accepted) == count:
            break
        sample = draw()
        if accept(sample):
            accepted.append(sample)
    if len(accepted) < count:
        raise ValueError(f"could not place {count} {what} after many attempts: the field is too crowded")
    return accepted


def field(
    np_random: np.random.Generator,
    n_landmarks: int = 8,
    n_obstacles: int = 6,
    size_m: float = 40.0,
    speed_mps: float = 1.0,
    n_waypoints: int = 6,
) -> Scenario:
    """An open square field: random landmarks and round obstacles around a random closed route.

    Obstacles keep clear of the route and landmarks stay outside obstacles, so
    the robot never collides and every landmark can be seen from somewhere.
    """
    center = np.array([size_m / 2, size_m / 2])
    angles = 2 * math.pi * (np.arange(n_waypoints) + np_random.uniform(-0.2, 0.2, n_waypoints)) / n_waypoints
    radii = size_m * np_random.uniform(0.22, 0.36, n_waypoints)
    route = center + radii[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    obstacles = _rejection_sample(
        n_obstacles,
        lambda: CircleObstacle(tuple(np_random.uniform(2.0, size_m - 2.0, 2)), float(np_random.uniform(0.5, 2.0))),
        lambda o: _distance_to_route(np.array(o.center), route) > o.radius + 2.0,
        "obstacles clear of the route",
    )
    landmarks = _rejection_sample(
        n_landmarks,
        lambda: np_random.uniform(1.0, size_m - 1.0, 2),
        lambda p: (
            _distance_to_route(p, route) > 1.0 and all(math.dist(p, o.center) > o.radius + 0.5 for o in obstacles)
        ),
        "landmarks outside obstacles",
    )
    heading = math.atan2(*(route[1] - route[0])[::-1])
    corners = ((0.0, 0.0), (size_m, 0.0), (size_m, size_m), (0.0, size_m))
    walls = tuple((corners[i], corners[(i + 1) % 4]) for i in range(4))
    return Scenario(
        name="field",
        bounds=(0.0, 0.0, size_m, size_m),
        walls=walls,
        obstacles=tuple(obstacles),
        landmarks=np.array(landmarks).reshape(-1, 2),
        waypoints=np.roll(route, -1, axis=0),
        start_pose=(float(route[0, 0]), float(route[0, 1]), heading),
        loop_route=True,
        speed_mps=speed_mps,
    )


SCENARIOS = {"corridor": corridor, "field": field}
