"""What the team envs share about sensing: relative-pose pairs, DGPS schedules and fixes, the prior."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from infonav_gym.compiled import kernel
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.world.world_batch import start_poses

NO_OBSERVATION = 0  # a team env's teammate choice ``1 + j`` observes robot j; this observes no teammate


class SensingPairs(NamedTuple):
    """The (observer, target) robot pairs P of a team whose observer carries a relative-pose sensor: their robots,
    the observer's ``noise_parameters()`` (P, 5), range [m] and half field of view [rad]; the robot pairs ``(i, j)``,
    ``i < j``, whose line of sight some pair needs (L, 2) and each pair's index into them (P,)."""

    observers: np.ndarray
    targets: np.ndarray
    noise: np.ndarray
    max_range_m: np.ndarray
    half_fov_rad: np.ndarray
    sight_lines: np.ndarray
    sight_line: np.ndarray

    @classmethod
    def of_team(cls, relative_sensors) -> SensingPairs:
        """The pairs of a team whose robot ``k`` carries ``relative_sensors[k]`` (a ``RelativePoseSensor`` or None)."""
        n = len(relative_sensors)
        pairs = [(i, j) for i in range(n) for j in range(n) if i != j and relative_sensors[i] is not None]
        sight_lines = sorted({(min(i, j), max(i, j)) for i, j in pairs})
        return cls(
            observers=np.array([i for i, _ in pairs], dtype=int),
            targets=np.array([j for _, j in pairs], dtype=int),
            noise=np.array([relative_sensors[i].noise_parameters() for i, _ in pairs]).reshape(-1, 5),
            max_range_m=np.array([relative_sensors[i].max_range_m for i, _ in pairs]),
            half_fov_rad=np.array([0.5 * relative_sensors[i].range_bearing.fov_rad for i, _ in pairs]),
            sight_lines=np.array(sight_lines, dtype=int).reshape(-1, 2),
            sight_line=np.array([sight_lines.index((min(i, j), max(i, j))) for i, j in pairs], dtype=int),
        )


def team_episode(config: dict, scenario, np_random: np.random.Generator, n_streams: int) -> tuple:
    """An episode of ``scenario`` (drawn from ``np_random``): ``(scenario, poses (R, 3), covariances (R, 3, 3),
    *generators)``, the ``n_streams`` sensor generators spawned, then the ``JointEKF`` prior: estimates drawn around
    the route starts with ``initial_position_std_m`` and ``initial_heading_std_rad``, uncorrelated."""
    generators = np_random.spawn(n_streams)
    true_poses = np.array(start_poses(scenario))
    pose_std = np.array([config["initial_position_std_m"]] * 2 + [config["initial_heading_std_rad"]])
    initial = true_poses + pose_std * np_random.standard_normal((len(true_poses), POSE_DIM))
    return scenario, initial, np.repeat(np.diag(pose_std**2)[None], len(true_poses), axis=0), *generators


def gps_schedule(receivers) -> tuple[np.ndarray, np.ndarray]:
    """Which robots carry DGPS (R,) and each robot's outage spans (R, S, 2) [s], padded with (inf, inf), of their
    ``receivers`` (a ``GPSSensor`` or None each)."""
    spans = [gps.outages if gps is not None else () for gps in receivers]
    outages = np.full((len(receivers), max(map(len, spans), default=0), 2), np.inf)
    for robot, robot_spans in enumerate(spans):
        outages[robot, : len(robot_spans)] = np.reshape(robot_spans, (-1, 2))
    return np.array([gps is not None for gps in receivers]), outages


@kernel
def gps_available(copies, positions, centers, radii_sq, has_gps, outages, time_s):
    """Which robots at ``positions`` (n, R, 2) [m] of ``copies`` (n,) have a DGPS fix at ``time_s`` (n,) [s]: they
    carry DGPS (``has_gps``), are in no outage span (``outages``: ``gps_schedule``) and in no GPS-denied zone of their
    copy (discs of ``centers`` (N, Z, 2) [m] and squared radii ``radii_sq`` (N, Z) [m^2], -1 for padding): (n, R)."""
    n_copies, n_robots = positions.shape[0], positions.shape[1]
    available = np.zeros((n_copies, n_robots), dtype=np.bool_)
    for k in range(n_copies):
        c, now = copies[k], time_s[k]
        for robot in range(n_robots):
            fix = has_gps[robot]
            for span in range(outages.shape[1]):
                fix &= not outages[robot, span, 0] <= now < outages[robot, span, 1]
            for zone in range(radii_sq.shape[1]):
                dx, dy = positions[k, robot, 0] - centers[c, zone, 0], positions[k, robot, 1] - centers[c, zone, 1]
                fix &= not dx**2 + dy**2 <= radii_sq[c, zone]
            available[k, robot] = fix
    return available
