"""A team's sensor suites, DGPS outage schedule and speeds, parsed from the env config with clear errors."""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

from infonav_gym.config import config_keys
from infonav_gym.sensors.gps import GPSSensor

KNOWN_SENSORS = ("odometry", "gps", "laser", "vision")
RELATIVE_SENSORS = ("laser", "vision")
# Robot k of the default team has suite k % 4: two DGPS robots with lasers, one with only
# odometry and a laser, one with only odometry and a camera.
DEFAULT_SUITES = (("gps", "laser"), ("gps", "laser"), ("laser",), ("vision",))
# The Fig. 3 convoy: robot #1 keeps DGPS and carries no relative sensor, robot #2 (DGPS
# lost at 21 s) localizes through its laser, robot #3 has only odometry and a laser.
CONVOY_SUITES = (("gps",), ("gps", "laser"), ("laser",))
DEFAULT_OUTAGE = (1, 21.0, 1e9)  # robot_1 loses DGPS at t = 21 s for the rest of the episode [s]


@dataclass(frozen=True)
class RobotSuite:
    """What one robot carries besides odometry: a DGPS receiver (``gps``), its ``relative_sensor`` (``"laser"``,
    ``"vision"`` or None: it cannot observe teammates)."""

    gps: bool
    relative_sensor: str | None


def parse_suites(spec, n_robots: int, scenario: str) -> tuple[RobotSuite, ...]:
    """One ``RobotSuite`` per robot from ``robot_sensors``: None for the ``scenario``'s default team (the convoy
    has its own), else one entry per robot: sensor names or a string joining them with ``+`` (``"gps+laser"``).

    Raises:
        ValueError: a wrong number of entries, an unknown sensor (listing the known), two relative sensors on a robot.
    """
    if spec is None:
        defaults = CONVOY_SUITES if scenario == "convoy" else DEFAULT_SUITES
        spec = [defaults[robot % len(defaults)] for robot in range(n_robots)]
    if isinstance(spec, str) or not isinstance(spec, Sequence) or len(spec) != n_robots:
        raise ValueError(f"robot_sensors must list one sensor suite per robot ({n_robots}), got {spec!r}")
    return tuple(_parse_suite(entry, robot) for robot, entry in enumerate(spec))


def _parse_suite(entry, robot: int) -> RobotSuite:
    names = entry.split("+") if isinstance(entry, str) else list(entry)
    unknown = [name for name in names if name not in KNOWN_SENSORS]
    if unknown:
        raise ValueError(
            f"unknown sensor {unknown[0]!r} for robot_{robot} in robot_sensors; "
            f"known sensors: {', '.join(KNOWN_SENSORS)}"
        )
    relative = [name for name in names if name in RELATIVE_SENSORS]
    if len(relative) > 1:
        raise ValueError(f"robot_{robot} can carry one relative-pose sensor (laser or vision), got {relative}")
    return RobotSuite(gps="gps" in names, relative_sensor=relative[0] if relative else None)


def parse_outages(spec, n_robots: int) -> tuple[tuple[tuple[float, float], ...], ...]:
    """Per robot, its DGPS outage spans ``(start_s, end_s)`` from ``gps_outages`` triples ``(robot, start_s, end_s)``.

    Raises:
        ValueError: not a sequence of triples, a malformed triple, a robot out of range, not ``start_s < end_s`` (NaN).
    """
    if isinstance(spec, str) or not isinstance(spec, Sequence):
        raise ValueError(f"gps_outages must be a sequence of (robot, start_s, end_s) triples, got {spec!r}")
    spans = [[] for _ in range(n_robots)]
    for triple in spec:
        try:
            robot, start_s, end_s = triple
            robot, start_s, end_s = int(robot), float(start_s), float(end_s)
        except (TypeError, ValueError, OverflowError):
            raise ValueError(f"each gps_outages entry must be (robot, start_s, end_s), got {triple!r}") from None
        if not 0 <= robot < n_robots:
            raise ValueError(f"gps_outages names robot {robot}, but the team has robots 0..{n_robots - 1}")
        if not start_s < end_s:
            raise ValueError(f"a gps_outages span must have start_s < end_s, got {triple!r}")
        spans[robot].append((start_s, end_s))
    return tuple(tuple(robot_spans) for robot_spans in spans)


def parse_speeds(spec, defaults: Sequence[float], n_robots: int, high_mps: float) -> tuple[float, ...]:
    """Each robot's cruise speed [m/s] from ``robot_speeds_mps``: None for ``defaults[k % len(defaults)]``.

    Raises:
        ValueError: naming ``robot_speeds_mps``: not one number per robot, or a speed outside (0, ``high_mps``].
    """
    if spec is None:
        return tuple(float(defaults[robot % len(defaults)]) for robot in range(n_robots))
    if isinstance(spec, str) or not isinstance(spec, Sequence) or len(spec) != n_robots:
        raise ValueError(f"robot_speeds_mps must list one speed [m/s] per robot ({n_robots}), got {spec!r}")
    for speed in spec:
        if not (isinstance(speed, numbers.Real) and not isinstance(speed, bool) and math.isfinite(speed)):
            raise ValueError(f"robot_speeds_mps must hold numbers [m/s], got {speed!r} in {spec!r}")
        if not 0.0 < speed <= high_mps:
            raise ValueError(f"each of robot_speeds_mps must be in (0, {high_mps:g}] m/s, got {speed!r}")
    return tuple(float(speed) for speed in spec)


def gps_receivers(config: dict, suites: Sequence[RobotSuite], owner: str) -> list[GPSSensor | None]:
    """Each robot's ``GPSSensor`` (``gps_std_m``, its ``gps_outages`` spans), None for a robot without DGPS
    (``ValueError`` naming ``owner`` and the key, for bad ``gps_outages`` or ``gps_std_m``)."""
    outages = parse_outages(config["gps_outages"], len(suites))
    with config_keys(owner, {"position_std_m": "gps_std_m"}):
        return [GPSSensor(config["gps_std_m"], spans) if suite.gps else None for suite, spans in zip(suites, outages)]
