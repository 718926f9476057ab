"""A team's relative-pose decision and info on (N, R, ...) arrays: what both team envs build theirs from.

N copies of a team of R robots; every copy has the same P (observer, target) pairs (``SensingPairs``), so the
candidates of all copies stack as (N, P, ...). A pair that is not observable now is masked out.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from infonav_gym.estimation import batched
from infonav_gym.estimation.models import relative_pose
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import gaussian_entropy_from_log_det
from infonav_gym.multi.team_sensing import NO_OBSERVATION, SensingPairs
from infonav_gym.sensors.relative_pose import noise_covariances
from infonav_gym.world.visibility import StaticGeometry, segments_clear


class TeamSightLines(NamedTuple):
    """The static shapes of N copies and the robot pairs whose line of sight the team's relative sensors need.

    Attributes:
        geometry: the copies' shapes (N copies).
        lines: the robot pairs ``(i, j)`` of the L sight lines (L, 2).
    """

    geometry: StaticGeometry
    lines: np.ndarray

    @classmethod
    def of_copies(cls, geometries: list[StaticGeometry], pairs: SensingPairs) -> TeamSightLines:
        """The sight lines of ``pairs`` in each copy's ``geometries``."""
        return cls(StaticGeometry.stack(geometries), np.array(pairs.sight_lines, dtype=int).reshape(-1, 2))

    def clear(self, true_poses: np.ndarray, copies: np.ndarray, lines: np.ndarray) -> np.ndarray:
        """Whether walls and obstacles leave sight line ``lines[m]`` of copy ``copies[m]`` clear (M,) bool, at the
        true poses (N, R, 3); only these lines are tested."""
        if not copies.size:
            return np.ones(0, dtype=bool)
        ends = self.lines[lines]
        return segments_clear(
            self.geometry, copies, true_poses[copies, ends[:, 0], :2], true_poses[copies, ends[:, 1], :2]
        )


class TeamDecision(NamedTuple):
    """Every copy's decision at its joint EKF's prior.

    Attributes:
        action_mask: int8 (N, R, R + 1): action 0 always, ``1 + j`` where robot ``j`` is observable.
        action_information_gain: expected reward of each action (N, R, R + 1) [nats], 0 where masked.
        geometry: true range, bearing and relative heading of every pair (N, P, 3).
        valid: which pairs are observable now (N, P).
        predicted: the prior's prediction of every pair's measurement (N, P, 3).
        H_observer, H_target: its Jacobians (N, P, 3, 3).
        R: its noise covariances at the predicted range (N, P, 3, 3).
        pose_log_det: ``ln det`` of each robot's pose covariance at the prior (N, R).
        pose_std: each robot's x, y, heading standard deviations at the prior (N, R, 3).
    """

    action_mask: np.ndarray
    action_information_gain: np.ndarray
    geometry: np.ndarray
    valid: np.ndarray
    predicted: np.ndarray
    H_observer: np.ndarray
    H_target: np.ndarray
    R: np.ndarray
    pose_log_det: np.ndarray
    pose_std: np.ndarray

    @classmethod
    def at_prior(cls, pairs: SensingPairs, geometry, valid, x, P, team_reward: float) -> TeamDecision:
        """The decisions of N copies at their priors ``x`` (N, 3R), ``P`` (N, 3R, 3R).

        Args:
            pairs: the team's (observer, target) pairs.
            geometry: every pair's true range, bearing and relative heading (N, P, 3) (``observable_pairs``).
            valid: which pairs are observable now (N, P).
            x, P: as above.
            team_reward: the weight of the team's MI in each robot's reward, in [0, 1].
        """
        n_copies, n_robots = x.shape[0], x.shape[1] // POSE_DIM
        n_pairs = len(pairs.observers)
        observers = np.repeat(pairs.observers[None], n_copies, axis=0)
        targets = np.repeat(pairs.targets[None], n_copies, axis=0)
        predicted, H_observer, H_target = batched.relative_pose_model(x, observers, targets, check_input=False)
        noise = np.repeat(pairs.noise[None], n_copies, axis=0).reshape(-1, 5)
        R = noise_covariances(noise, predicted[..., 0].ravel()).reshape(n_copies, n_pairs, POSE_DIM, POSE_DIM)
        mask = np.zeros((n_copies, n_robots, n_robots + 1), dtype=np.int8)
        mask[..., NO_OBSERVATION] = 1
        mask[:, pairs.observers, pairs.targets + 1] = valid
        gains = np.zeros(mask.shape)
        if n_pairs:  # every pair of every copy at once (its own P), the unobservable ones masked out after
            own, joint = batched.relative_pose_information_gains(
                P, observers, targets, H_observer, H_target, R, check_input=False
            )
            pair_gains = np.where(valid, (1.0 - team_reward) * own + team_reward * joint, 0.0)
            gains[:, pairs.observers, pairs.targets + 1] = pair_gains
        pose_log_det = batched.pose_log_dets(P, n_robots, check_input=False)
        pose_std = np.sqrt(np.diagonal(P, axis1=1, axis2=2)).reshape(n_copies, n_robots, POSE_DIM)
        return cls(mask, gains, geometry, valid, predicted, H_observer, H_target, R, pose_log_det, pose_std)


def observable_pairs(pairs: SensingPairs, sight: TeamSightLines | None, true_poses) -> tuple[np.ndarray, np.ndarray]:
    """Every pair's true range, bearing and relative heading (N, P, 3) and which are observable now (N, P) bool.

    Observable: the target lies in the observer's range and field of view, with a clear line of sight.

    Args:
        pairs: the team's (observer, target) pairs.
        sight: the copies' sight lines; None when the team has no pair.
        true_poses: every copy's true poses (N, R, 3).
    """
    n_copies, n_pairs = len(true_poses), len(pairs.observers)
    geometry = relative_pose(
        true_poses[:, pairs.observers].reshape(-1, POSE_DIM), true_poses[:, pairs.targets].reshape(-1, POSE_DIM)
    ).reshape(n_copies, n_pairs, POSE_DIM)
    valid = pairs.covered(geometry)
    if sight is not None:  # the line of sight of the covered pairs only
        copies, covered = np.nonzero(valid)
        valid[copies, covered] = sight.clear(true_poses, copies, pairs.sight_line[covered])
    return geometry, valid


class TeamStep(NamedTuple):
    """What the last reset or step did in each copy, for its info.

    Attributes:
        stepped: which copies acted (N,) bool; the others were reset and give the reset info.
        chosen: each robot's executed action (N, R), ``NO_OBSERVATION`` for a masked one and at a reset.
        invalid: whether each robot's action was masked (N, R) bool.
        own_mi, team_mi: the MI on each robot's own pose and on the joint state (N, R) [nats].
        pose_std_after_update: each robot's x, y, heading standard deviations right after the relative
            updates (N, R, 3); None for the prior's (a reset).
    """

    stepped: np.ndarray
    chosen: np.ndarray
    invalid: np.ndarray
    own_mi: np.ndarray
    team_mi: np.ndarray
    pose_std_after_update: np.ndarray | None

    @classmethod
    def of_reset(cls, n_copies: int, n_robots: int) -> TeamStep:
        """A reset of every copy: nothing stepped, no action, no MI (``pose_std_after_update`` None: the prior's)."""
        shape = (n_copies, n_robots)
        nothing = np.zeros(shape)
        return cls(
            np.zeros(n_copies, bool), np.full(shape, NO_OBSERVATION), np.zeros(shape, bool), nothing, nothing, None
        )


def team_info(decision: TeamDecision, last: TeamStep, x, true_poses, gps_available, time_s) -> dict:
    """The team env's ``infos[agent]`` of every copy and robot as arrays (N, R, ...), each with its ``_key`` mask (N,).

    ``reward_terms`` are masked out (``_own_mutual_information`` False) for the copies that were reset.

    Args:
        decision: the new decisions.
        last: what the reset or step did.
        x: the joint EKF states (N, 3R).
        true_poses: the true poses (N, R, 3).
        gps_available: which robots have a DGPS fix now (N, R).
        time_s: each copy's time (N,) [s].
    """
    terms = {"own_mutual_information": last.own_mi, "team_mutual_information": last.team_mi}
    info = {
        **team_step_info(decision, last, terms, x, true_poses, gps_available, time_s),
        "pose_std_after_update": last.pose_std_after_update.copy(),
    }
    return with_masks(info)


def team_step_info(decision, last, terms: dict, x, true_poses, gps_available, time_s) -> dict:
    """The info keys every team vector env gives, as arrays (N, R, ...) (``time_s``: (N,)), without ``_key`` masks.

    Args:
        decision: the new decisions, with ``action_mask``, ``action_information_gain`` (N, R, A),
            ``pose_log_det`` (N, R) and ``pose_std`` (N, R, 3) at the prior.
        last: what the reset or step did (``stepped`` (N,), ``chosen`` and ``invalid`` (N, R)).
        terms: each reward term (N, R) [nats], taken where ``last.stepped`` (0 and masked out elsewhere).
        x, true_poses, gps_available, time_s: as ``team_info`` takes them.
    """
    estimates = x.reshape(true_poses.shape)
    errors = true_poses - estimates
    terms = {key: np.where(last.stepped[:, None], value, 0.0) for key, value in terms.items()}
    return {
        "action_mask": decision.action_mask.copy(),
        "action_information_gain": decision.action_information_gain.copy(),
        "reward_terms": {**terms, **{f"_{key}": last.stepped.copy() for key in terms}},
        "chosen_action": last.chosen.copy(),
        "invalid_action": last.invalid.copy(),
        "gps_available": gps_available.copy(),
        "position_error_m": np.hypot(errors[..., 0], errors[..., 1]),
        "heading_error_rad": np.abs(wrap_angle(errors[..., 2])),
        "pose_entropy": gaussian_entropy_from_log_det(decision.pose_log_det, POSE_DIM),
        "pose_std": decision.pose_std.copy(),
        "true_pose": true_poses.copy(),
        "estimated_pose": estimates.copy(),
        "time_s": np.asarray(time_s, dtype=float).copy(),
    }


def with_masks(info: dict) -> dict:
    """``info`` with Gymnasium's ``_key`` mask (N,), all True, beside each key (its arrays lead with N)."""
    everyone = np.ones(len(info["action_mask"]), dtype=bool)
    return {**info, **{f"_{key}": everyone for key in info}}
