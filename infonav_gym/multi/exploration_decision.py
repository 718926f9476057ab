"""What ``CooperativeExplorationVectorEnv`` sees, decides and reports, on (N, R, ...) arrays: sight, decision, info.

N copies of a team of R robots, each copy with L landmarks (N, L, 2) and a map of G cells (N, G). An action is
observation slot ``a // 5`` (0 none, ``1 + j`` landmark j, ``1 + L + j`` robot j) and motion ``a % 5``, so masks
and gains are (N, R, 1 + L + R, 5) flattened to (N, R, 5 (1 + L + R)).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from infonav_gym.envs.active_transition import ranges_and_bearings
from infonav_gym.estimation import batched
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.multi.team_decision import (
    TeamDecision,
    team_step_info,
    with_masks,
)
from infonav_gym.world.visibility import StaticGeometry, segments_clear

EXPLORATION_INFO_KEYS = frozenset(
    {"gps_available", "pose_std", "position_std_m", "pose_entropy", "position_error_m", "heading_error_rad"}
    | {"estimated_pose", "observations_left", "coverage", "lost", "failed", "success"}
)


class TeamSight(NamedTuple):
    """What a team's sensors see of the landmarks.

    Attributes:
        sensors: each robot's ``RelativePoseSensor`` or None (R,); its range-bearing part sees landmarks.
    """

    sensors: tuple

    def visible_landmarks(self, geometry: StaticGeometry, true_poses, landmarks) -> np.ndarray:
        """Which landmarks (N, L, 2) each robot's sensor sees from its true pose (N, R, 3): (N, R, L) bool.

        In the range-bearing sensor's range and field of view, with a clear line of sight.
        """
        n_copies, n_robots = true_poses.shape[:2]
        seen = ranges_and_bearings(true_poses.reshape(-1, POSE_DIM), np.repeat(landmarks, n_robots, axis=0))
        seen = seen.reshape(n_copies, n_robots, -1, 2)
        covered = np.zeros(seen.shape[:3], dtype=bool)
        for robot, sensor in enumerate(self.sensors):
            if sensor is not None:
                in_range = sensor.range_bearing.in_coverage(seen[:, robot].reshape(-1, 2))
                covered[:, robot] = in_range.reshape(n_copies, -1)
        copy, robot, landmark = np.nonzero(covered)
        covered[copy, robot, landmark] = segments_clear(
            geometry, copy, true_poses[copy, robot, :2], landmarks[copy, landmark]
        )
        return covered

    def landmark_noise(self, predicted) -> np.ndarray:
        """Each robot's range-bearing noise (..., R, K, 2, 2) at its predicted measurements (..., R, K, 2).

        The identity for a robot without a sensor (it observes nothing).
        """
        R = np.broadcast_to(np.eye(2), (*predicted.shape, 2)).copy()
        for robot, sensor in enumerate(self.sensors):
            if sensor is not None:
                ranges = predicted[..., robot, :, 0]
                noise = sensor.range_bearing.noise_covariance(ranges.ravel())
                R[..., robot, :, :, :] = noise.reshape(*ranges.shape, 2, 2)
        return R

    def landmark_measurements(self, true_poses, positions, noise) -> np.ndarray:
        """Noisy range-bearing (n, R, 2) of ``positions`` (n, R, 2) seen from ``true_poses`` (n, R, 3) by each robot's
        sensor, given its standard normals ``noise`` (n, R, 2) (what ``RangeBearingSensor.measure`` draws)."""
        measured = np.zeros(noise.shape)
        for robot, sensor in enumerate(self.sensors):
            if sensor is not None:
                rb = sensor.range_bearing
                measured[:, robot] = rb.measure_with_noise(true_poses[:, robot], positions[:, robot], noise[:, robot])
        return measured


class ExplorationDecision(NamedTuple):
    """Every copy's decision at its joint EKF's prior.

    Attributes:
        action_mask: int8 (N, R, 5 S), S = 1 + L + R observation slots times 5 motions.
        action_information_gain: immediate expected information of each action (N, R, 5 S) [nats], 0 where masked.
        team: the relative-pose candidates (``TeamDecision`` with the budget applied; its gains are own-pose MI).
        slot_valid: which observation slots each robot may choose now (N, R, S) bool.
        position_std: each robot's largest position standard deviation at the prior (N, R) [m].
    """

    action_mask: np.ndarray
    action_information_gain: np.ndarray
    team: TeamDecision
    slot_valid: np.ndarray
    position_std: np.ndarray


def landmark_gains(x, P, landmarks, noise_of) -> np.ndarray:
    """Expected MI [nats] of each robot observing each landmark alone at the prior (N, R, L).

    Args:
        x, P: the joint EKF states (N, 3R) and covariances (N, 3R, 3R).
        landmarks: each copy's landmarks (N, L, 2) [m].
        noise_of: ``TeamSight.landmark_noise``.
    """
    n_copies, n_robots = len(x), x.shape[1] // POSE_DIM
    poses = x.reshape(-1, POSE_DIM)
    predicted, H = batched.landmark_measurement_model(poses, np.repeat(landmarks, n_robots, axis=0), check_input=False)
    R = noise_of(predicted.reshape(n_copies, n_robots, -1, 2)).reshape(len(poses), -1, 2, 2)
    own = batched.pose_blocks(P)[:, np.arange(n_robots), np.arange(n_robots)].reshape(-1, POSE_DIM, POSE_DIM)
    return batched.landmark_information_gains(own, H, R, check_input=False).reshape(n_copies, n_robots, -1)


class ExplorationStep(NamedTuple):
    """What the last reset or step did in each copy, for its info.

    Attributes:
        stepped: which copies acted (N,) bool; the others were reset and give the reset info.
        chosen: each robot's executed action (N, R), the no-op (0) for a masked one and at a reset.
        invalid: whether each robot's action was masked (N, R) bool.
        terms: each reward term (``REWARD_TERMS``) of each robot (N, R) [nats].
    """

    stepped: np.ndarray
    chosen: np.ndarray
    invalid: np.ndarray
    terms: dict

    @classmethod
    def nothing(cls, n_copies: int, n_robots: int, terms) -> ExplorationStep:
        """No copy stepped: no action, every term 0."""
        shape = (n_copies, n_robots)
        nothing = {key: np.zeros(shape) for key in terms}
        return cls(np.zeros(n_copies, bool), np.zeros(shape, int), np.zeros(shape, bool), nothing)

    def restarted(self, copies: np.ndarray) -> ExplorationStep:
        """This record with the (N,) bool ``copies`` reset since: no action, no reward, not stepped."""
        rows = copies[:, None]
        return ExplorationStep(
            self.stepped & ~copies,
            np.where(rows, 0, self.chosen),
            self.invalid & ~rows,
            {key: np.where(rows, 0.0, value) for key, value in self.terms.items()},
        )


def exploration_info(decision: ExplorationDecision, last: ExplorationStep, state: dict) -> dict:
    """Every copy's and robot's ``infos[agent]`` (see ``CooperativeExplorationEnv``) as arrays (N, R, ...) with
    ``_key`` masks (N,).

    The team's keys ``time_s``, ``coverage``, ``failed`` and ``success`` are (N,); ``reward_terms`` are masked out
    (``_own_pose_information`` False, ...) for the copies that were reset.

    Args:
        decision: the new decisions.
        last: what the reset or step did.
        state: the copies' ``x`` (N, 3R), ``true_poses`` (N, R, 3), ``gps_available``, ``observations_left`` and
            ``lost`` (N, R), ``coverage``, ``success`` and ``time_s`` (N,).
    """
    prior = decision.team._replace(
        action_mask=decision.action_mask, action_information_gain=decision.action_information_gain
    )
    info = team_step_info(
        prior, last, last.terms, state["x"], state["true_poses"], state["gps_available"], state["time_s"]
    )
    return with_masks(
        {
            **info,
            "position_std_m": decision.position_std.copy(),
            "observations_left": state["observations_left"].copy(),
            "coverage": state["coverage"].copy(),
            "lost": state["lost"].copy(),
            "failed": state["lost"].any(axis=1),
            "success": state["success"].copy(),
        }
    )
