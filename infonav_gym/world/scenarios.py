"""Scenario builders: the static layout of a world, drawn from an explicit ``np_random``."""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from infonav_gym.compiled import kernel
from infonav_gym.config import Interval, ParameterError, check_arguments
from infonav_gym.geometry import ClosedLoop, loop_distance

CORRIDOR_LANDMARK_COUNT = 4
MAX_SPEED_MPS = 50.0  # fastest cruise speed of a route [m/s]
MIN_FIELD_SIZE_M = 10.0  # smallest side of a square field [m]
MAX_FIELD_SIZE_M = 1000.0  # largest side of a square field [m]
MAX_LANDMARKS = 100  # most landmarks of a field
MAX_OBSTACLES = 100  # most round obstacles of a field
MAX_CANOPIES = 20  # most GPS-denied zones of a team field
MAX_ROBOTS = 32  # largest team
MAX_WAYPOINTS = 100  # most vertices of a random closed route
DEFAULT_WAYPOINTS = 6  # vertices of a random closed route unless a builder is told otherwise
MAX_ATTEMPTS_EACH = 1000  # draws per wanted sample of a random layout before it counts as too crowded
SPEED_MPS = Interval(0.0, MAX_SPEED_MPS, open_low=True, unit="m/s")  # a route's cruise speed
WAYPOINT_COUNT = Interval(3, MAX_WAYPOINTS, integer=True)  # vertices of a random closed route
CORRIDOR_ARGUMENTS = {"speed_mps": SPEED_MPS}  # the allowed arguments of each builder
FIELD_ARGUMENTS = {
    "n_landmarks": Interval(0, MAX_LANDMARKS, integer=True),
    "n_obstacles": Interval(0, MAX_OBSTACLES, integer=True),
    "size_m": Interval(MIN_FIELD_SIZE_M, MAX_FIELD_SIZE_M, unit="m"),
    "speed_mps": SPEED_MPS,
    "n_waypoints": WAYPOINT_COUNT,
}
TEAM_FIELD_ARGUMENTS = {
    **{name: FIELD_ARGUMENTS[name] for name in ("n_obstacles", "size_m", "speed_mps", "n_waypoints")},
    "n_robots": Interval(1, MAX_ROBOTS, integer=True),  # and no more than fit: team_route_bands
    "n_canopies": Interval(0, MAX_CANOPIES, integer=True),
}
CONVOY_ARGUMENTS = {"n_robots": Interval(2, MAX_ROBOTS, integer=True), "speed_mps": SPEED_MPS}


@dataclass(frozen=True)
class CircleObstacle:
    center: tuple[float, float]  # [m]
    radius: float  # [m]


@dataclass(frozen=True)
class Route:
    """One robot's route: start ``[x, y, heading]`` [m, m, rad], waypoints driven to in turn (W, 2) [m] (none:
    parked), whether to loop back to the first, cruise speed [m/s]."""

    start_pose: tuple[float, float, float]
    waypoints: np.ndarray
    loop: bool = False
    speed_mps: float = 1.0

    def __post_init__(self):
        waypoints = np.array(self.waypoints, dtype=float)
        if waypoints.size == 0:
            waypoints = np.zeros((0, 2))
        if waypoints.ndim != 2 or waypoints.shape[1] != 2 or not np.isfinite(waypoints).all():
            raise ValueError(f"route waypoints must be a finite (W, 2) array [m], got shape {waypoints.shape}")
        SPEED_MPS.check("route", "speed_mps", self.speed_mps)
        waypoints.flags.writeable = False
        object.__setattr__(self, "waypoints", waypoints)


@dataclass(frozen=True)
class Scenario:
    """Everything static about a world: drawable ``bounds`` ``(x_min, y_min, x_max, y_max)`` [m], one route per
    robot (at least one), wall segments ``((x0, y0), (x1, y1))`` [m], circular obstacles, landmarks (L, 2) [m]
    and GPS-denied circles (not physical: robots drive through them)."""

    name: str
    bounds: tuple[float, float, float, float]
    routes: tuple[Route, ...]
    walls: tuple = ()
    obstacles: tuple = ()
    landmarks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    gps_denied_zones: tuple[CircleObstacle, ...] = ()

    def __post_init__(self):
        if not self.routes:
            raise ValueError(f"scenario {self.name!r} needs at least one route (one per robot), got none")


def corridor(np_random: np.random.Generator, speed_mps: float = 0.5) -> Scenario:
    """The paper's Fig. 1: a straight corridor, 4 landmarks; #3 (index 2), closest and across the direction of
    travel, brings clearly the most information (Fig. 2). Fixed: ``np_random`` is unused."""
    del np_random
    check_arguments("corridor", CORRIDOR_ARGUMENTS, speed_mps=speed_mps)
    half_width, length = 3.0, 40.0
    walls = (
        ((-2.0, half_width), (length, half_width)),
        ((-2.0, -half_width), (length, -half_width)),
        ((-2.0, -half_width), (-2.0, half_width)),
        ((length, -half_width), (length, half_width)),
    )
    return Scenario(
        name="corridor",
        bounds=(-3.0, -4.0, length + 1.0, 4.0),
        walls=walls,
        routes=(Route((0.0, 0.0, 0.0), np.array([[length - 3.0, 0.0]]), speed_mps=speed_mps),),
        landmarks=np.array([[11.0, 2.2], [13.0, -2.2], [7.0, -2.2], [14.0, 2.2]]),
    )


def _placed(samples, count: int, what: str):
    """The ``samples`` of a random layout, or ``ValueError`` when fewer than ``count`` were placed (too crowded)."""
    if len(samples) < count:
        raise ValueError(f"could not place {count} {what} after many attempts: the field is too crowded")
    return samples


def _uniform_until_accepted(np_random, count: int, width: int, accept, what: str):
    """The first ``count`` rows of ``width`` uniform [0, 1) numbers that pass the batched test ``accept``: drawn
    ahead in batches, the generator rewound to end right after the last attempt (as one draw per attempt)."""
    accepted, attempts_left, batch = [], MAX_ATTEMPTS_EACH * max(count, 1), max(4 * count, 16)
    while len(accepted) < count and attempts_left > 0:
        state, size = np_random.bit_generator.state, min(batch, attempts_left)
        rows = np_random.random((size, width))
        passed = np.flatnonzero(accept(rows))[: count - len(accepted)]
        if len(accepted) + len(passed) == count:
            np_random.bit_generator.state = state
            np_random.random((passed[-1] + 1, width))  # consume exactly the attempts made
        accepted.extend(rows[passed])
        attempts_left -= size
    return _placed(np.array(accepted).reshape(-1, width), count, what)


def _uniform(u: np.ndarray, low, high) -> np.ndarray:
    """``Generator.uniform(low, high)`` of drawn uniform [0, 1) numbers ``u``."""
    return low + (high - low) * u


def _polygon(center: np.ndarray, angles: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """The (W, 2) vertices at polar ``angles`` [rad] and ``radii`` [m] around ``center``."""
    return center + radii[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def _next_vertices(polygon: np.ndarray) -> np.ndarray:
    """Each vertex's successor around the closed ``polygon``: ``np.roll(polygon, -1, axis=0)`` without its overhead."""
    return np.concatenate((polygon[1:], polygon[:1]))


def _points_along(polygon: np.ndarray, per_edge: int = 8) -> np.ndarray:
    """Points spaced evenly along each edge of the closed ``polygon`` (W * per_edge, 2)."""
    fractions = np.arange(per_edge)[:, None, None] / per_edge
    return (polygon + fractions * (_next_vertices(polygon) - polygon)).reshape(-1, 2)


def _closed_route(polygon: np.ndarray, speed_mps: float) -> Route:
    """A looping route around ``polygon``, starting at its first vertex and heading for the second."""
    (x0, y0), (x1, y1) = polygon[:2].tolist()
    return Route((x0, y0, math.atan2(y1 - y0, x1 - x0)), _next_vertices(polygon), loop=True, speed_mps=speed_mps)


def _box_walls(x_min: float, y_min: float, x_max: float, y_max: float) -> tuple:
    """The four walls around the rectangle ``[x_min, x_max] x [y_min, y_max]``."""
    corners = ((x_min, y_min), (x_max, y_min), (x_max, y_max), (x_min, y_max))
    return tuple((corners[i], corners[(i + 1) % 4]) for i in range(4))


def _placed_obstacles(rows: np.ndarray, count: int) -> tuple:
    """The obstacle of each row ``[x, y, radius]`` [m], or ``ValueError`` when fewer than ``count`` were placed."""
    rows = _placed(rows, count, "obstacles clear of the routes")
    return tuple(CircleObstacle((x, y), radius) for x, y, radius in rows.tolist())


@kernel
def obstacles_clear_of(np_random, count, size_m, starts, directions):
    """Up to ``count`` round obstacles (n, 3) in the square field, each its radius + 2 m clear of the route edges."""
    return discs_clear_of(np_random, count, 2.0, size_m - 2.0, (0.5, 2.0), starts, directions, 2.0, np.empty((0, 3)))


@kernel
def discs_clear_of(np_random, count, low_m, high_m, radii_m, starts, directions, route_gap_m, discs):
    """Up to ``count`` discs ``[x, y, radius]`` (n, 3) [m], centre uniform in ``[low_m, high_m)`` squared, radius in
    ``radii_m`` (``(0.0, 0.0)``: points, none drawn), each > ``route_gap_m`` beyond its radius from the route edges
    and 0.5 m beyond each of ``discs`` (D, 3); one row of draws per attempt, ``MAX_ATTEMPTS_EACH`` per disc."""
    placed_discs, placed = np.empty((count, 3)), 0
    for _ in range(MAX_ATTEMPTS_EACH * max(count, 1)):
        if placed == count:
            break
        x, y = low_m + (high_m - low_m) * np_random.random(2)
        radius = radii_m[0] + (radii_m[1] - radii_m[0]) * np_random.random() if radii_m[1] > 0.0 else 0.0
        clear = loop_distance(x, y, starts, directions) > radius + route_gap_m
        for d in range(len(discs)):
            clear &= math.hypot(x - discs[d, 0], y - discs[d, 1]) > discs[d, 2] + 0.5
        if clear:
            placed_discs[placed, 0], placed_discs[placed, 1], placed_discs[placed, 2] = x, y, radius
            placed += 1
    return placed_discs[:placed]


@kernel
def field_discs(np_random, n_landmarks, n_obstacles, size_m, starts, directions):
    """``field``'s obstacles ``[x, y, radius]`` (n, 3), then landmarks (m, 2) [m], clear of the route edges ``starts +
    t directions``; no landmark is drawn after obstacles that do not fit."""
    obstacles = obstacles_clear_of(np_random, n_obstacles, size_m, starts, directions)
    count = n_landmarks if len(obstacles) == n_obstacles else 0
    points = discs_clear_of(np_random, count, 1.0, size_m - 1.0, (0.0, 0.0), starts, directions, 1.0, obstacles)
    return obstacles, np.ascontiguousarray(points[:, :2])


def field(
    np_random: np.random.Generator,
    n_landmarks: int = 8,
    n_obstacles: int = 6,
    size_m: float = 40.0,
    speed_mps: float = 1.0,
    n_waypoints: int = DEFAULT_WAYPOINTS,
) -> Scenario:
    """An open square field: random landmarks, and round obstacles clear of a random closed route (``field_discs``).
    ``ValueError`` for an argument outside ``FIELD_ARGUMENTS`` (``ParameterError``) or obstacles that do not fit."""
    arguments = {"n_landmarks": n_landmarks, "n_obstacles": n_obstacles, "size_m": size_m, "speed_mps": speed_mps}
    check_arguments("field", FIELD_ARGUMENTS, **arguments, n_waypoints=n_waypoints)
    center = np.array([size_m / 2, size_m / 2])
    angles = 2 * math.pi * (np.arange(n_waypoints) + np_random.uniform(-0.2, 0.2, n_waypoints)) / n_waypoints
    route = _polygon(center, angles, size_m * np_random.uniform(0.22, 0.36, n_waypoints))
    loop = ClosedLoop(route)
    obstacles, landmarks = field_discs(np_random, n_landmarks, n_obstacles, float(size_m), loop.starts, loop.directions)
    return Scenario(
        name="field",
        bounds=(0.0, 0.0, size_m, size_m),
        routes=(_closed_route(route, speed_mps),),
        walls=_box_walls(0.0, 0.0, size_m, size_m),
        obstacles=_placed_obstacles(obstacles, n_obstacles),
        landmarks=_placed(landmarks, n_landmarks, "landmarks outside obstacles"),  # (L, 2), after the obstacles
    )


TEAM_ROUTE_GAP_M = 2.0  # least distance between two robots' routes [m]
MAX_CANOPY_COVER = 0.5  # largest fraction of a route's length one GPS-denied zone may cover
_TEAM_ANGLE_JITTER = 0.1  # jitter of a waypoint's polar angle, as a fraction of the sector between waypoints


def _radial_bands(
    n_bands: int, inner_m: float, outer_m: float, gap_m: float, sector_rad: float, max_width_m: float
) -> list[tuple[float, float]]:
    """Vertex radius ranges [m], innermost first, of closed polygons ``gap_m`` apart between ``inner_m`` and
    ``outer_m``, each up to ``max_width_m`` wide; ``ValueError`` when they do not fit.

    Edges spanning at most ``sector_rad`` stay beyond ``cos(sector_rad / 2)`` times the smallest vertex radius.
    """
    sag = math.cos(sector_rad / 2)

    def bands(width_m: float) -> list[tuple[float, float]]:
        stacked, high = [], outer_m
        for _ in range(n_bands):
            stacked.append((high - width_m, high))
            high = (high - width_m) * sag - gap_m
        return stacked[::-1]

    def clearance(width_m: float) -> float:
        return bands(width_m)[0][0] * sag - inner_m

    if clearance(0.0) < 0.0:
        raise ValueError(
            f"cannot fit {n_bands} routes {gap_m} m apart between {inner_m:.1f} m and {outer_m:.1f} m "
            "from the field centre: use fewer robots, a larger size_m or more n_waypoints"
        )
    width_m = min(max_width_m, clearance(0.0) / (clearance(0.0) - clearance(1.0)))  # clearance is affine in width
    return bands(width_m)


def _canopies_on(polygons: list, count: int, np_random: np.random.Generator) -> list:
    """``count`` GPS-denied zones (radius 4-8 m) on the routes, each covering at most ``MAX_CANOPY_COVER`` of any
    route and no route's start."""

    def draw() -> CircleObstacle:
        polygon = polygons[np_random.integers(len(polygons))]
        edge = np_random.integers(len(polygon))
        point = polygon[edge] + np_random.uniform() * (polygon[(edge + 1) % len(polygon)] - polygon[edge])
        return CircleObstacle((float(point[0]), float(point[1])), float(np_random.uniform(4.0, 8.0)))

    def accept(zone: CircleObstacle) -> bool:
        starts_open = all(math.dist(polygon[0], zone.center) >= zone.radius for polygon in polygons)
        covered = np.mean(np.linalg.norm(route_points - zone.center, axis=-1) < zone.radius, axis=1)
        return starts_open and bool(np.all(covered <= MAX_CANOPY_COVER))

    route_points = np.array([_points_along(polygon) for polygon in polygons])  # (R, P, 2): routes of equal size
    accepted = []
    for _ in range(MAX_ATTEMPTS_EACH * max(count, 1)):  # draw until ``count`` zones pass ``accept``
        if len(accepted) == count:
            break
        if accept(zone := draw()):
            accepted.append(zone)
    what = f"GPS-denied zones off the route starts covering at most {MAX_CANOPY_COVER:.0%} of any route"
    return _placed(accepted, count, what)


def team_route_bands(n_robots: int, size_m: float, n_waypoints: int) -> list[tuple[float, float]]:
    """The radial bands of ``team_field``'s routes (deterministic), or ``ParameterError`` when they do not fit."""
    try:
        return _radial_bands(
            n_robots,
            inner_m=2.0,  # the innermost route keeps its waypoints >= ~2 m apart
            outer_m=size_m / 2 - 2.5,
            gap_m=TEAM_ROUTE_GAP_M,
            sector_rad=2 * math.pi * (1 + 2 * _TEAM_ANGLE_JITTER) / n_waypoints,
            max_width_m=0.15 * size_m,
        )
    except ValueError as error:
        raise ParameterError("team_field", "n_robots", f"a team whose routes fit ({error})", n_robots) from None


def team_field(
    np_random: np.random.Generator,
    n_robots: int = 4,
    n_obstacles: int = 6,
    n_canopies: int = 2,
    size_m: float = 40.0,
    speed_mps: float = 1.0,
    n_waypoints: int = DEFAULT_WAYPOINTS,
) -> Scenario:
    """An open square field for a team, no landmarks: each robot loops its own route in a radial band
    ``TEAM_ROUTE_GAP_M`` from the next; obstacles clear of the routes; GPS-denied zones on them (``_canopies_on``).

    Raises:
        ValueError: for an argument outside ``TEAM_FIELD_ARGUMENTS`` or a team that does not fit
            (``ParameterError``), or obstacles or canopies that do not fit.
    """
    counts = {"n_robots": n_robots, "n_obstacles": n_obstacles, "n_canopies": n_canopies, "n_waypoints": n_waypoints}
    check_arguments("team_field", TEAM_FIELD_ARGUMENTS, **counts, size_m=size_m, speed_mps=speed_mps)
    bands = team_route_bands(n_robots, size_m, n_waypoints)
    center = np.array([size_m / 2, size_m / 2])
    first_angle = np_random.uniform(0.0, 2 * math.pi)
    polygons = []
    for robot, (low_m, high_m) in enumerate(bands):
        jitter = np_random.uniform(-_TEAM_ANGLE_JITTER, _TEAM_ANGLE_JITTER, n_waypoints)
        angles = first_angle + 2 * math.pi * (robot / n_robots + (np.arange(n_waypoints) + jitter) / n_waypoints)
        polygons.append(_polygon(center, angles, np_random.uniform(low_m, high_m, n_waypoints)))
    routes = ClosedLoop(*polygons)
    obstacles = obstacles_clear_of(np_random, n_obstacles, float(size_m), routes.starts, routes.directions)
    return Scenario(
        name="team_field",
        bounds=(0.0, 0.0, size_m, size_m),
        routes=tuple(_closed_route(polygon, speed_mps) for polygon in polygons),
        walls=_box_walls(0.0, 0.0, size_m, size_m),
        obstacles=_placed_obstacles(obstacles, n_obstacles),
        gps_denied_zones=tuple(_canopies_on(polygons, n_canopies, np_random)),  # drawn after the obstacles
    )


CONVOY_LANE_SPACING_M = 6.0
CONVOY_LENGTH_M = 62.0
# Openings [m along x] in the hedge between lanes h and h + 1 (the first after Fig. 3's DGPS loss at 21 s)
CONVOY_OPENINGS = (((30.0, 33.0), (42.0, 45.0), (54.0, 57.0)), ((12.0, 15.0), (42.0, 45.0)))


def _hedge(y: float, openings, x_start: float, x_end: float) -> tuple:
    """Wall segments along ``y`` from ``x_start`` to ``x_end`` with gaps at the ``openings`` (x ranges)."""
    edges = [x_start, *(x for opening in openings for x in opening), x_end]
    return tuple(((edges[k], y), (edges[k + 1], y)) for k in range(0, len(edges), 2))


def convoy(np_random: np.random.Generator, n_robots: int = 3, speed_mps: float = 1.0) -> Scenario:
    """The paper's Fig. 3: robot ``k`` drives lane ``y = -6 k`` from ``x = 0`` to 62; hedges between lanes block
    sight but at ``CONVOY_OPENINGS``, so relative observations come in bursts. Fixed: ``np_random`` is unused."""
    del np_random
    check_arguments("convoy", CONVOY_ARGUMENTS, n_robots=n_robots, speed_mps=speed_mps)
    lanes = [-CONVOY_LANE_SPACING_M * k for k in range(n_robots)]
    half = CONVOY_LANE_SPACING_M / 2
    x_min, x_max, y_min, y_max = -3.0, CONVOY_LENGTH_M + 3.0, lanes[-1] - half, half
    walls = _box_walls(x_min, y_min, x_max, y_max)
    for hedge in range(n_robots - 1):
        walls += _hedge(lanes[hedge] - half, CONVOY_OPENINGS[min(hedge, len(CONVOY_OPENINGS) - 1)], x_min, x_max)
    routes = tuple(Route((0.0, y, 0.0), np.array([[CONVOY_LENGTH_M, y]]), speed_mps=speed_mps) for y in lanes)
    return Scenario(name="convoy", bounds=(x_min - 1, y_min - 1, x_max + 1, y_max + 1), routes=routes, walls=walls)


ScenarioBuilder = Callable[..., Scenario]  # builder(np_random, **parameters) -> Scenario

# The registry: every scenario by name (``register_scenario`` adds to it); TEAM_SCENARIOS: those for teams.
SCENARIOS: dict[str, ScenarioBuilder] = {
    "corridor": corridor,
    "field": field,
    "team_field": team_field,
    "convoy": convoy,
}
TEAM_SCENARIOS: set[str] = {"team_field", "convoy"}


def register_scenario(name: str, builder: ScenarioBuilder, *, team: bool = False) -> None:
    """Make ``builder(np_random, **parameters) -> Scenario`` the scenario ``name`` (``team``: for the team envs), in
    a module every process imports (``SubprocVecEnv`` workers start fresh); ``ValueError`` for a bad name/builder."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"a scenario name must be a non-empty string, got {name!r}")
    if name in SCENARIOS:
        raise ValueError(f"scenario {name!r} is already registered (registered: {', '.join(sorted(SCENARIOS))})")
    if not callable(builder):
        raise ValueError(f"the builder of scenario {name!r} must be callable, got {builder!r}")
    SCENARIOS[name] = builder
    if team:
        TEAM_SCENARIOS.add(name)


def scenario_names(team: bool) -> tuple[str, ...]:
    """The registered scenarios for teams (``team=True``) or for a single robot, sorted."""
    return tuple(sorted(name for name in SCENARIOS if (name in TEAM_SCENARIOS) == team))


def build_scenario(name: str, np_random: np.random.Generator, **parameters) -> Scenario:
    """Build the scenario ``name`` with the ``parameters`` its builder names; ``ValueError`` for an unknown name or
    a builder that returns no ``Scenario``."""
    if name not in SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; registered: {', '.join(sorted(SCENARIOS))}")
    builder = SCENARIOS[name]
    named = _named_parameters(builder)
    if named is not None:
        parameters = {key: value for key, value in parameters.items() if key in named}
    scenario = builder(np_random, **parameters)
    if not isinstance(scenario, Scenario):
        raise ValueError(f"the builder of scenario {name!r} returned a {type(scenario).__name__}, not a Scenario")
    return scenario


@functools.cache
def _named_parameters(builder: ScenarioBuilder) -> frozenset[str] | None:
    """The parameter names ``builder`` takes, None when it takes any keyword (``**kwargs``)."""
    signature = inspect.signature(builder).parameters.values()
    if any(parameter.kind is inspect.Parameter.VAR_KEYWORD for parameter in signature):
        return None
    return frozenset(parameter.name for parameter in signature)


def scenario_from_config(
    config: dict,
    np_random: np.random.Generator,
    parameter_keys: dict[str, str],
    owner: str,
    n_routes: int,
    max_landmarks: int | None = None,
) -> Scenario:
    """Build ``config["scenario"]`` for the env ``owner`` (``parameter_keys``: builder parameter -> config key);
    ``ValueError`` as ``build_scenario``'s, or unless it has ``n_routes`` routes and at most ``max_landmarks``."""
    parameters = {name: config[key] for name, key in parameter_keys.items()}
    scenario = build_scenario(config["scenario"], np_random, **parameters)
    routes, landmarks = len(scenario.routes), len(scenario.landmarks)
    if routes != n_routes or (max_landmarks is not None and landmarks > max_landmarks):
        most = "" if max_landmarks is None else f" and at most {max_landmarks} landmarks"
        raise ValueError(
            f"scenario {config['scenario']!r} has {routes} route(s) and {landmarks} landmarks: "
            f"{owner} needs {n_routes} route(s){most}"
        )
    return scenario
