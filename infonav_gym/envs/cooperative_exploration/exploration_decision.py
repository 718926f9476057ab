"""What ``CooperativeExplorationVectorEnv`` sees and decides, on (N, R, ...) arrays: sight, decision, landmark gains.

An action is observation slot ``a // 5`` (0 none, ``1 + j`` landmark j, ``1 + L + j`` robot j) and motion ``a % 5``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from infonav_gym.compiled import contiguous, kernel
from infonav_gym.estimation import batched, kernels
from infonav_gym.estimation.kernels import range_bearing_of_offset
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.multi.team_decision import TeamDecision
from infonav_gym.sensors.range_bearing import noise_covariances
from infonav_gym.world.visibility import StaticGeometry, shape_arrays
from infonav_gym.world.visibility_kernels import blocked, within_coverage


class TeamSight(NamedTuple):
    """What a team's sensors (each robot's ``RelativePoseSensor`` or None) see of the landmarks: their
    range-bearing parts."""

    sensors: tuple

    def visible_landmarks(self, geometry: StaticGeometry, true_poses, landmarks) -> np.ndarray:
        """Which landmarks (N, L, 2) each robot's sensor sees from its true pose (N, R, 3), in range and field of
        view with a clear line of sight: (N, R, L) bool."""
        reach = [(-1.0, -1.0) if s is None else (s.max_range_m, 0.5 * s.range_bearing.fov_rad) for s in self.sensors]
        return landmark_sight(contiguous(true_poses), contiguous(landmarks), np.array(reach), *shape_arrays(geometry))

    @property
    def noise_stds(self) -> np.ndarray:
        """Each robot's ``RangeBearingSensor.noise_stds`` (R, 3); unit noise ``(1, 0, 1)`` without a sensor."""
        return np.array([(1.0, 0.0, 1.0) if s is None else s.range_bearing.noise_stds for s in self.sensors])

    def landmark_measurements(self, true_poses, positions, noise) -> np.ndarray:
        """Noisy range-bearing (n, R, 2) of ``positions`` (n, R, 2) seen from ``true_poses`` (n, R, 3) by each robot's
        sensor, given its standard normals ``noise`` (n, R, 2) (what ``RangeBearingSensor.measure`` draws)."""
        measured = np.zeros(noise.shape)
        for robot, sensor in enumerate(self.sensors):
            if sensor is not None:
                rb = sensor.range_bearing
                measured[:, robot] = rb.measure_with_noise(true_poses[:, robot], positions[:, robot], noise[:, robot])
        return measured


def range_bearing_noise(noise_stds, robots, ranges) -> np.ndarray:
    """``noise_covariances`` (M, 2, 2) of the sensor of each robot ``robots`` (M,) at ``ranges`` (M,) [m]
    (``noise_stds``: ``TeamSight.noise_stds``)."""
    R = np.empty((len(ranges), 2, 2))
    for robot in np.unique(robots):
        rows = robots == robot
        R[rows] = noise_covariances(np.ascontiguousarray(ranges[rows], dtype=float), *noise_stds[robot])
    return R


ExplorationDecision = NamedTuple(
    "ExplorationDecision", [(name, np.ndarray) for name in (*TeamDecision._fields, "slot_valid", "position_std")]
)
ExplorationDecision.__doc__ = """Every copy's decision at its joint EKF's prior: ``TeamDecision``'s fields (the
relative-pose candidates with the budget applied) but ``action_mask`` int8 and ``action_information_gain`` [nats]
(N, R, 5 S) of S = 1 + L + R observation slots times 5 motions; which slots each robot may choose now
``slot_valid`` (N, R, S) bool, and each robot's largest position std at the prior ``position_std`` (N, R) [m]."""


@kernel
def landmark_sight(true_poses, landmarks, reach, walls, discs, culled):
    """``TeamSight.visible_landmarks`` of each robot's range [m] and half field of view [rad] ``reach`` (R, 2)."""
    n_copies, n_robots, n_landmarks = true_poses.shape[0], true_poses.shape[1], landmarks.shape[1]
    covered = np.zeros((n_copies, n_robots, n_landmarks), dtype=np.bool_)
    for c in range(n_copies):
        for robot in range(n_robots):
            x, y, heading = true_poses[c, robot, 0], true_poses[c, robot, 1], true_poses[c, robot, 2]
            for k in range(n_landmarks):
                dx, dy = landmarks[c, k, 0] - x, landmarks[c, k, 1] - y
                covered[c, robot, k] = within_coverage(dx, dy, heading, reach[robot, 0], reach[robot, 1])
    copies, robots, seen = np.nonzero(covered)
    starts, ends = np.empty((len(copies), 2)), np.empty((len(copies), 2))
    for m in range(len(copies)):
        for i in range(2):
            starts[m, i], ends[m, i] = true_poses[copies[m], robots[m], i], landmarks[copies[m], seen[m], i]
    hit = blocked(copies, starts, ends, walls, discs, culled)
    for m in range(len(copies)):
        covered[copies[m], robots[m], seen[m]] = not hit[m]
    return covered


def landmark_gains(x, P, landmarks, noise_stds, valid) -> np.ndarray:
    """Expected MI [nats] of each robot (``TeamSight.noise_stds``) observing each landmark (N, L, 2) [m] alone at the
    prior ``x`` (N, 3R), ``P`` (N, 3R, 3R), where ``valid`` (N, R, L) bool (0 elsewhere: no action observes it):
    (N, R, L); ``ValueError`` where it is undefined."""
    gains, coincident = robot_landmark_gains(*map(contiguous, (x, P, landmarks)), noise_stds, contiguous(valid))
    if coincident or np.isnan(gains).any():
        raise ValueError(f"{batched.COINCIDENT}, or an innovation covariance is not positive definite")
    return gains


@kernel
def robot_landmark_gains(x, P, landmarks, noise_stds, valid):
    """``kernels.landmark_gain`` of each robot's range-bearing to each landmark (``range_bearing_of_offset``,
    ``noise_covariances``) on its pose block where ``valid`` (N, R, L), 0 elsewhere, and whether a landmark lies on a
    robot's estimate."""
    n_robots = x.shape[1] // POSE_DIM
    gains, coincident = np.zeros(valid.shape), False
    predicted, block = np.empty(2), np.empty((POSE_DIM, POSE_DIM))
    HP, S, columns = np.empty((2, POSE_DIM)), np.empty((2, 2)), np.empty(POSE_DIM, dtype=np.int64)
    for robot in range(n_robots):
        pose = POSE_DIM * robot
        copies, seen = np.nonzero(valid[:, robot])
        H, ranges = np.zeros((len(copies), 2, POSE_DIM)), np.empty(len(copies))
        for m in range(len(copies)):
            c, k = copies[m], seen[m]
            dx, dy = landmarks[c, k, 0] - x[c, pose], landmarks[c, k, 1] - x[c, pose + 1]
            coincident |= not range_bearing_of_offset(dx, dy, x[c, pose + 2], predicted, H[m])
            ranges[m] = predicted[0]
        covariances = noise_covariances(ranges, noise_stds[robot, 0], noise_stds[robot, 1], noise_stds[robot, 2])
        for m in range(len(copies)):
            c = copies[m]
            for i in range(POSE_DIM):  # element by element: an array into a slice compiles numba's error formatting
                for j in range(POSE_DIM):
                    block[i, j] = P[c, pose + i, pose + j]
            gains[c, robot, seen[m]] = kernels.landmark_gain(block, H[m], covariances[m], HP, S, columns)
    return gains, coincident
