"""What the team envs share about sensing: relative-pose pairs and their sight, DGPS fixes, the prior."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from infonav_gym.estimation.models import relative_pose
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.sensors.relative_pose import noisy_relative_poses

NO_OBSERVATION = 0  # a team env's teammate choice ``1 + j`` observes robot j; this observes no teammate


class RelativeSight(NamedTuple):
    """The relative-pose observations possible at a decision, and what their stacked update needs.

    Immutable (a named tuple: cheap to build every step).

    Attributes:
        geometry: true range, bearing and relative heading of every (observer, target) pair (P, 3).
        valid_pairs: the pairs observable now (V,), indices into the env's pair arrays.
        candidate_row: for each robot and action, its row among the valid pairs, -1 where masked (N, N + 1).
        candidates: ``(predicted (V, 3), H_observer (V, 3, 3), H_target (V, 3, 3), R (V, 3, 3))`` at
            the prior, ``None`` when no pair is observable.
        pose_log_det: ``ln det`` of each robot's pose covariance at the prior (N,).
        pose_std: each robot's x, y, heading standard deviations at the prior (N, 3).
    """

    geometry: np.ndarray
    valid_pairs: np.ndarray
    candidate_row: np.ndarray
    candidates: tuple | None
    pose_log_det: np.ndarray
    pose_std: np.ndarray


class SensingPairs(NamedTuple):
    """The (observer, target) robot pairs P of a team whose observer carries a relative-pose sensor.

    Attributes:
        observers, targets: robot indices of each pair (P,).
        noise: the observer's ``RelativePoseSensor.noise_parameters()`` per pair (P, 5).
        max_range_m: the observer's sensor range per pair (P,) [m].
        half_fov_rad: half its field of view per pair (P,) [rad].
        sight_lines: the robot pairs ``(i, j)``, ``i < j``, whose line of sight some pair needs (symmetric).
        sight_line: each pair's index into ``sight_lines`` (P,).
    """

    observers: np.ndarray
    targets: np.ndarray
    noise: np.ndarray
    max_range_m: np.ndarray
    half_fov_rad: np.ndarray
    sight_lines: list[tuple[int, int]]
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
            sight_lines=sight_lines,
            sight_line=np.array([sight_lines.index((min(i, j), max(i, j))) for i, j in pairs], dtype=int),
        )

    def covered(self, geometry: np.ndarray) -> np.ndarray:
        """Which pairs' true ``[range, bearing, ...]`` (..., P, 3) lie in the observer's range and field of view."""
        return (geometry[..., 0] <= self.max_range_m) & (np.abs(geometry[..., 1]) <= self.half_fov_rad)


class TeamSensing:
    """The sensing steps of a team env on a ``JointEKF``, a mixin of it (of a team env still written twice).

    The host has ``ekf`` (a ``JointEKF``), ``world`` (a ``World``), ``pairs`` (its ``SensingPairs``), ``gps``
    (one ``GPSSensor`` or None per robot), ``_true_poses`` (R, 3), ``_time_s`` and the generators
    ``_gps_rng`` and ``_relative_rng``.
    """

    def _observable_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The true ``[range, bearing, relative heading]`` of every pair (P, 3) and the pairs observable now (V,).

        Observable: the target lies in the observer's range and field of view, and no wall or obstacle blocks
        the line between them.
        """
        truth, pairs = self._true_poses, self.pairs
        geometry = relative_pose(truth[pairs.observers], truth[pairs.targets])
        covered = np.flatnonzero(pairs.covered(geometry))
        lines = sorted(set(pairs.sight_line[covered].tolist()))
        clear = dict(zip(lines, self.world.robots_in_sight([pairs.sight_lines[line] for line in lines])))
        return geometry, covered[[clear[line] for line in pairs.sight_line[covered].tolist()]]

    def _observe(self, chosen: np.ndarray, sight: RelativeSight) -> None:
        """Apply the chosen relative-pose observations, taken at the same time, as one stacked update.

        Args:
            chosen: each robot's teammate choice (R,): ``NO_OBSERVATION`` or ``1 + j`` to observe robot j.
            sight: the decision's ``RelativeSight`` (``candidate_row`` indexed by the teammate choice).
        """
        observers = np.flatnonzero(chosen != NO_OBSERVATION)
        targets = chosen[observers] - 1
        self._observed_pairs = list(zip(observers.tolist(), targets.tolist()))
        if observers.size == 0:
            return
        rows = sight.candidate_row[observers, chosen[observers]]
        predicted, H_observer, H_target, R = (part[rows] for part in sight.candidates)
        pairs = sight.valid_pairs[rows]
        measurements = noisy_relative_poses(sight.geometry[pairs], self.pairs.noise[pairs], self._relative_rng)
        self.ekf.relative_pose_update(
            observers, targets, measurements, predicted, H_observer, H_target, R, check_input=False
        )

    def _gps_fixes(self) -> None:
        """Fuse the DGPS fixes of the robots that have one now (none under a canopy or in an outage)."""
        denied = self.world.gps_denied(self._true_poses[:, :2])
        self._gps_available = np.array(
            [gps is not None and gps.available(self._time_s, bool(denied[k])) for k, gps in enumerate(self.gps)]
        )
        robots = np.flatnonzero(self._gps_available)
        if robots.size:
            fixes = np.array([self.gps[k].measure(self._true_poses[k, :2], self._gps_rng) for k in robots])
            covariances = np.array([self.gps[k].noise_covariance() for k in robots])
            self.ekf.gps_update(robots, fixes, covariances, check_input=False)

    def _pose_uncertainty(self) -> tuple[np.ndarray, np.ndarray]:
        """Per robot, ``ln det`` of its pose covariance (N,) and its x, y, heading standard deviations (N, 3)."""
        covariances = self.ekf.pose_covariances()
        return np.linalg.slogdet(covariances)[1], np.sqrt(np.diagonal(covariances, axis1=1, axis2=2))


def team_prior(config: dict, true_poses: np.ndarray, np_random: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The ``JointEKF`` prior: estimates drawn around the true poses (R, 3), and their covariances (R, 3, 3).

    The standard deviations are the config's ``initial_position_std_m`` and ``initial_heading_std_rad``; the
    robots start uncorrelated.
    """
    n = len(true_poses)
    pose_std = np.array([config["initial_position_std_m"]] * 2 + [config["initial_heading_std_rad"]])
    initial = true_poses + pose_std * np_random.standard_normal((n, POSE_DIM))
    return initial, np.repeat(np.diag(pose_std**2)[None], n, axis=0)


def gps_schedule(receivers) -> tuple[np.ndarray, np.ndarray]:
    """Which robots carry DGPS (R,) and each robot's outage spans (R, S, 2) [s], padded with (inf, inf).

    Args:
        receivers: one ``GPSSensor`` or None per robot.
    """
    spans = [gps.outages if gps is not None else () for gps in receivers]
    outages = np.full((len(receivers), max(map(len, spans), default=0), 2), np.inf)
    for robot, robot_spans in enumerate(spans):
        outages[robot, : len(robot_spans)] = np.reshape(robot_spans, (-1, 2))
    return np.array([gps is not None for gps in receivers]), outages


def gps_available(has_gps: np.ndarray, outages: np.ndarray, denied: np.ndarray, time_s) -> np.ndarray:
    """Which robots have a DGPS fix (N, R): they carry DGPS, are in no GPS-denied zone (``denied`` (N, R)) and in
    no outage span (``gps_schedule``) at each copy's ``time_s`` (N,) [s]."""
    time_s = np.asarray(time_s, dtype=float)[:, None, None]
    in_outage = np.any((outages[..., 0] <= time_s) & (time_s < outages[..., 1]), axis=2)
    return has_gps & ~denied & ~in_outage
