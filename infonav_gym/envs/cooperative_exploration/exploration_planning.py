"""The planning model of ``cooperative_exploration_v0`` (what ``agents.planner.PlannerAgent`` searches), and the
helpers of one step (motion plans, scan gains, rewards) the env computes its masks, gains and rewards with.

Under the EKF's linearization a covariance after an update does not depend on the measured value, so a step's
expected reward follows from the belief alone, without sampling and without the true state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from infonav_gym.envs.cooperative_exploration.exploration_decision import TeamSight, landmark_gains, range_bearing_noise
from infonav_gym.estimation import batched
from infonav_gym.estimation.state import POSE_DIM, BeliefBatch, block_diagonal
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import largest_position_std, mutual_information_from_log_dets
from infonav_gym.multi.team_decision import observable_pairs
from infonav_gym.sensors.relative_pose import noise_covariances
from infonav_gym.world.clearance import clear_moves

MOTION_NAMES = ("stay", "east", "north", "west", "south")
MOTION_HEADINGS_RAD = np.array([0.0, 0.0, math.pi / 2, math.pi, -math.pi / 2])  # "stay" does not drive
STAY = 0
N_MOTIONS = len(MOTION_NAMES)
NOOP_ACTION = 0  # stay and observe nothing: slot 0, motion STAY
MOTION_DIRECTIONS = np.stack([np.cos(MOTION_HEADINGS_RAD), np.sin(MOTION_HEADINGS_RAD)], axis=-1)  # (5, 2)


def motion_plan(motions, headings, speeds_mps) -> tuple[np.ndarray, np.ndarray]:
    """Each robot's turn [rad] on the spot, from its *estimated* heading at the decision to the motion's compass
    heading, and its speed [m/s] in the drive phase after it (``stay``: neither); the arguments broadcast together."""
    drives = motions != STAY
    turns = np.where(drives, wrap_angle(MOTION_HEADINGS_RAD[motions] - headings), 0.0)
    return turns, np.where(drives, speeds_mps, 0.0)


def motion_phases(turns, speeds, config: dict) -> tuple:
    """A step's turn phase, then its drive phase: ``(duration [s], unicycle controls (..., 2))`` of each, of the
    ``turns`` [rad] on the spot and the drives at ``speeds`` [m/s] (``turn_time_s``, ``time_step_s``)."""
    turn_s = config["turn_time_s"]
    return (
        (turn_s, np.stack([np.zeros_like(turns), turns / turn_s], axis=-1)),
        (config["time_step_s"] - turn_s, np.stack([speeds, np.zeros_like(speeds)], axis=-1)),
    )


def clear_motions(geometry, poses, headings, speeds_mps, drive_s: float, robot_radius_m: float) -> np.ndarray:
    """Which motions each robot may take (N, R, 5): after its turn (planned at the estimated ``headings``), its drive
    from ``poses`` (N, R, 3) for ``drive_s`` [s] at its speed (R,) [m/s] keeps ``world.clearance.clear_moves``'
    ``CLEARANCE_M`` from ``geometry`` and wherever a teammate's motions take it. From the true poses (the env's
    masks) no contact ever pushes a robot unseen by its odometry; from the estimates it is the belief's guess."""
    turns, speeds = motion_plan(np.arange(N_MOTIONS), headings[..., None], speeds_mps[:, None])
    headings, reach = poses[..., 2:3] + turns, drive_s * speeds
    displacements = reach[..., None] * np.stack([np.cos(headings), np.sin(headings)], axis=-1)
    return clear_moves(geometry, poses[..., :2], displacements, robot_radius_m)


def scan_gains(map_model, variances, positions, position_std, speeds_mps, drive_s: float) -> np.ndarray:
    """Map information [nats] each robot's scan would bring alone after each motion (..., R, 5), 0 for ``stay``:
    from where the motion takes its estimated position (..., R, 2) in ``drive_s`` [s] at its speed (R,) [m/s], with
    the scan noise of its position std (..., R) [m], on the map's cell variances (..., G)."""
    drives = np.flatnonzero(np.arange(N_MOTIONS) != STAY)
    ends = positions[..., None, :] + drive_s * speeds_mps[:, None, None] * MOTION_DIRECTIONS[drives]  # (..., R, 4, 2)
    noise = np.broadcast_to(map_model.scan_noise_variances(position_std)[..., None], ends.shape[:-1])
    variances = np.asarray(variances)
    n_scans = ends.shape[-3] * len(drives)
    flat_gains = map_model.scan_gains(
        variances.reshape(-1, variances.shape[-1]), ends.reshape(-1, n_scans, 2), noise.reshape(-1, n_scans)
    )
    gains = np.zeros((*ends.shape[:-2], N_MOTIONS))
    gains[..., drives] = flat_gains.reshape(ends.shape[:-1])
    return gains


def action_table(team_reward: float, slot_valid, observation_gain, motion_clear, scan) -> tuple:
    """``(action_mask int8, action_information_gain [nats])`` (..., 5 S) of each (observation slot, motion): valid
    where both are (``slot_valid`` (..., S), ``motion_clear`` (..., 5)); ``(1 - team_reward)`` times the observation's
    gain (..., S) plus ``team_reward`` times the scan's (..., 5), 0 where masked."""
    mask = slot_valid[..., None] & motion_clear[..., None, :]
    gains = np.where(mask, (1.0 - team_reward) * observation_gain[..., None] + team_reward * scan[..., None, :], 0.0)
    return mask.reshape(*mask.shape[:-2], -1).astype(np.int8), gains.reshape(*mask.shape[:-2], -1)


def reward_terms(config: dict, own, map_information, observed, driving, lost) -> dict[str, np.ndarray]:
    """Every robot's reward terms (..., R) (see the env) from its own pose MI ``own`` (..., R) [nats], the team's
    ``map_information`` (...) [nats], whether it ``observed`` and drove (``driving``) (..., R), and whether a robot
    of the team is ``lost`` (...)."""
    zeros = np.zeros(np.shape(own))  # the team's numbers (...) repeated for each robot (..., R)
    return {
        "own_pose_information": own,
        "team_map_information": zeros + np.asarray(map_information, dtype=float)[..., None],
        "sensing_cost": -config["observation_cost_nats"] * np.asarray(observed),
        "motion_cost": -config["motion_cost_per_step"] * np.asarray(driving),
        "lost_penalty": zeros + np.where(lost, -config["lost_penalty"], 0.0)[..., None],
    }


def total_reward(team_reward: float, terms: dict) -> np.ndarray:
    """The rewards (..., R) of the terms of ``reward_terms``."""
    costs = terms["sensing_cost"] + terms["motion_cost"] + terms["lost_penalty"]
    return (1.0 - team_reward) * terms["own_pose_information"] + team_reward * terms["team_map_information"] + costs


@dataclass(frozen=True)
class TeamBelief(BeliefBatch):
    """The team's estimator state at a decision, batched over ``B`` hypothetical futures (estimates only): the
    joint ``x`` (B, 3R) and ``covariance``, the map's cell variances (B, G) [m^2], each robot's budget left (B, R),
    the ``steps`` since the env's decision and whether the episode has ended (B,); judged from the estimates, which
    landmarks each robot would see (B, R, L), which ``SensingPairs`` are observable (B, P) and which motions are
    clear of contacts (B, R, 5)."""

    x: np.ndarray
    covariance: np.ndarray
    map_variances: np.ndarray
    observations_left: np.ndarray
    steps: np.ndarray
    done: np.ndarray
    landmark_visible: np.ndarray
    pair_visible: np.ndarray
    motion_clear: np.ndarray


class ExplorationPlanningModel:
    """The planning model of one copy of ``CooperativeExplorationVectorEnv`` (``env.planning_model(copy)``); it reads
    the copy's episode and estimator state (``env.state``) when called, so one model serves a whole run."""

    n_primitives = N_MOTIONS
    idle_primitive = STAY  # the motion that stands still

    def __init__(self, env, copy: int = 0):
        self._env, self._copy = env, copy
        self._parts = parts = env.parts
        self._sight = TeamSight(tuple(parts.relative_sensors))
        self._pair_index = env.env_scenario.pair_index  # robot, teammate choice -> its pair, -1 for none
        self._gps_noise = np.array([np.eye(2) if gps is None else gps.noise_covariance() for gps in parts.gps])
        self._odometry_covariances = env.env_scenario.odometry_covariances
        self._drive_s = self.config["time_step_s"] - self.config["turn_time_s"]  # the drive phase of a step [s]
        self._tiled: tuple = (None, {})  # the copy's static geometry and its tiled copies by count

    @property
    def config(self) -> dict:
        return self._env.config

    @property
    def max_position_std_m(self) -> float:
        """The bound on a robot's largest position standard deviation [m] (config ``max_position_std_m``)."""
        return self.config["max_position_std_m"]

    @property
    def step_index(self) -> int:
        """The index of the current decision: steps since the copy's reset."""
        return int(self._env.state.elapsed[self._copy])

    @staticmethod
    def position_std(covariances: np.ndarray) -> np.ndarray:
        """Each robot's largest position standard deviation (B, R) [m] in joint covariances (B, 3R, 3R)."""
        robots = np.arange(np.shape(covariances)[1] // POSE_DIM)
        blocks = batched.pose_blocks(covariances)[:, robots, robots]
        return largest_position_std(blocks.reshape(-1, POSE_DIM, POSE_DIM)).reshape(blocks.shape[:2])

    def belief(self) -> TeamBelief:
        """The team's estimator state at the copy's current decision, as a batch of one (``RuntimeError`` before the
        env's first ``reset()``)."""
        env, copy = self._env, self._copy
        if env.decision is None:
            raise RuntimeError(f"{env.owner_name}: call reset() before the planning model's belief()")
        state = env.state
        done = state.lost[copy].any() or state.success[copy] or state.elapsed[copy] >= env.max_cycles
        arrays = (state.x, state.P, state.map_variances, state.observations_left)
        return self._belief(*(array[None, copy].copy() for array in arrays), np.zeros(1, dtype=int), np.array([done]))

    def plan_decision(self, belief: TeamBelief, robot: int) -> tuple[np.ndarray, np.ndarray]:
        """Robot ``robot``'s ``(action_mask (B, A), action_information_gain (B, A))`` at each belief, as ``infos``
        give them but judged from the estimates; a finished belief has only action 0 valid, with gain 0."""
        parts, pairs, n_landmarks, B = self._parts, self._parts.pairs, self.config["n_landmarks"], len(belief)
        poses = belief.x.reshape(B, -1, POSE_DIM)
        n_slots = 1 + n_landmarks + poses.shape[1]
        observable = (belief.observations_left[:, robot] > 0) & ~belief.done
        slot_valid = np.tile(np.arange(n_slots) == 0, (B, 1))  # slot 0, observe nothing, is always valid
        slot_valid[:, 1 : 1 + n_landmarks] = belief.landmark_visible[:, robot] & observable[:, None]
        observation_gain = np.zeros((B, n_slots))
        if n_landmarks and parts.relative_sensors[robot] is not None:
            landmarks = np.broadcast_to(self._landmarks(), (B, n_landmarks, 2))
            noise_stds, visible = self._sight.noise_stds, belief.landmark_visible
            gains = landmark_gains(belief.x, belief.covariance, landmarks, noise_stds, visible)
            observation_gain[:, 1 : 1 + n_landmarks] = gains[:, robot]
        own_pairs = np.flatnonzero(pairs.observers == robot)
        if own_pairs.size:
            slots = 1 + n_landmarks + pairs.targets[own_pairs]
            slot_valid[:, slots] = belief.pair_visible[:, own_pairs] & observable[:, None]
            chosen = np.broadcast_to(own_pairs, (B, own_pairs.size))
            observers, targets = pairs.observers[chosen], pairs.targets[chosen]
            predicted, H_observer, H_target = batched.relative_pose_model(
                belief.x, observers, targets, check_input=False
            )
            R = self._pair_noise(chosen, predicted[..., 0])
            observation_gain[:, slots] = batched.relative_pose_information_gains(
                belief.covariance, observers, targets, H_observer, H_target, R, check_input=False
            )[0]
        own = slice(robot, robot + 1)
        position_std, speeds = self.position_std(belief.covariance)[:, own], parts.speeds_mps[own]
        scan = scan_gains(parts.map_model, belief.map_variances, poses[:, own, :2], position_std, speeds, self._drive_s)
        clear = belief.motion_clear[:, robot].copy()
        clear[belief.done] = np.arange(N_MOTIONS) == STAY  # and only slot 0 is valid: stay, observe nothing
        return action_table(self.config["team_reward"], slot_valid, observation_gain, clear, scan[:, 0])

    def plan_step(self, belief: TeamBelief, actions) -> tuple[TeamBelief, np.ndarray]:
        """Predict one step of every belief under the team's actions (B, R): ``(next beliefs, rewards (B, R))``, the
        env's transition with the unknowns at their expectation: observations fused with the measurement as predicted
        (exact MI), motions commanded from the estimate, DGPS fixes and scans at the estimated positions. What the
        belief does not allow is dropped (an observation out of sight or budget; a motion not clear: stay); a
        finished belief stays put and earns 0."""
        cfg, map_model = self.config, self._parts.map_model
        B, n_robots, n_landmarks = len(belief), len(self._parts.gps), cfg["n_landmarks"]
        live = ~belief.done
        slots, motions = np.divmod(np.asarray(actions, dtype=int).reshape(B, n_robots), N_MOTIONS)
        budget = (belief.observations_left > 0) & live[:, None]
        copies, robots = np.arange(B)[:, None], np.arange(n_robots)
        landmarks = np.clip(slots - 1, 0, max(n_landmarks - 1, 0))
        sees_landmark = (slots >= 1) & (slots <= n_landmarks) & budget
        if n_landmarks:
            sees_landmark &= belief.landmark_visible[copies, robots, landmarks]
        pairs = self._pair_index[robots, np.clip(slots - n_landmarks, 1, n_robots)]
        sees_teammate = (slots > n_landmarks) & budget & (pairs >= 0)
        sees_teammate &= belief.pair_visible[copies, np.maximum(pairs, 0)]
        driving = (motions != STAY) & live[:, None] & belief.motion_clear[copies, robots, motions]
        observed = sees_landmark | sees_teammate
        P = self._expected_observations(belief, sees_landmark, landmarks, sees_teammate, pairs)
        log_dets = [batched.pose_log_dets(M, n_robots, check_input=False) for M in (belief.covariance, P)]
        own = mutual_information_from_log_dets(*log_dets)
        x, P = self._expected_motion(belief.x, P, motions, driving)
        positions = x.reshape(B, n_robots, POSE_DIM)[..., :2]
        elapsed = self.step_index
        time_s = elapsed * cfg["time_step_s"] + (belief.steps + 1) * cfg["time_step_s"]
        env = self._env
        has_fix = env.env_scenario.gps_available(env.state, np.full(B, self._copy), positions, time_s) & live[:, None]
        if has_fix.any():
            x, P = batched.gps_update(x, P, positions, self._gps_noise, has_fix, check_input=False)
        position_std = self.position_std(P)
        noise = map_model.scan_noise_variances(position_std)
        map_variances, map_information = map_model.fused(belief.map_variances, positions, noise, driving)
        lost = (position_std > cfg["max_position_std_m"]).any(axis=1) & live
        success = (map_model.coverage(map_variances) >= cfg["coverage_target"]) & ~lost & live
        out_of_time = elapsed + belief.steps + 1 >= cfg["max_cycles"]
        rewards = total_reward(cfg["team_reward"], reward_terms(cfg, own, map_information, observed, driving, lost))
        following = self._belief(
            np.where(live[:, None], x, belief.x),
            np.where(live[:, None, None], P, belief.covariance),
            np.where(live[:, None], map_variances, belief.map_variances),
            belief.observations_left - observed,
            belief.steps + live,
            belief.done | lost | success | out_of_time,
        )
        return following, np.where(live[:, None], rewards, 0.0)

    def _belief(self, x, covariance, map_variances, observations_left, steps, done) -> TeamBelief:
        """A ``TeamBelief`` with what each robot would see judged from the estimates ``x`` (B, 3R)."""
        B, n_landmarks = len(x), self.config["n_landmarks"]
        poses = x.reshape(B, -1, POSE_DIM)
        landmarks = np.broadcast_to(self._landmarks(), (B, n_landmarks, 2))
        geometry, radius_m = self._tiled_geometry(B), self._env.state.worlds.robot_radius_m
        landmark_visible = self._sight.visible_landmarks(geometry, poses, landmarks)
        pair_visible = observable_pairs(self._parts.pairs, geometry, poses)[1]
        motion_clear = clear_motions(geometry, poses, poses[..., 2], self._parts.speeds_mps, self._drive_s, radius_m)
        return TeamBelief(
            x, covariance, map_variances, observations_left, steps, done, landmark_visible, pair_visible, motion_clear
        )

    def _landmarks(self) -> np.ndarray:
        """The landmarks of the copy's episode (L, 2) [m]."""
        return self._env.scenario(self._copy).landmarks

    def _tiled_geometry(self, n_copies: int):
        """The copy's static shapes as ``n_copies`` copies (``StaticGeometry.tiled``), kept for the episode."""
        geometry = self._env.state.geometries[self._copy]
        if self._tiled[0] is not geometry:
            self._tiled = (geometry, {})
        if n_copies not in self._tiled[1]:
            self._tiled[1][n_copies] = geometry.tiled(n_copies)
        return self._tiled[1][n_copies]

    def _pair_noise(self, pairs: np.ndarray, ranges: np.ndarray) -> np.ndarray:
        """Noise covariances (..., 3, 3) of the relative poses of ``pairs`` (``SensingPairs`` rows) at ``ranges``."""
        noise = self._parts.pairs.noise[pairs].reshape(-1, 5)
        return noise_covariances(noise, ranges.ravel()).reshape(*np.shape(pairs), 3, 3)

    def _expected_observations(self, belief, sees_landmark, landmarks, sees_teammate, pairs) -> np.ndarray:
        """The joint covariance (B, 3R, 3R) after every robot's observation of the step, as one stacked update at
        the estimates: robot r's fills rows ``3r .. 3r + 2`` of the Jacobian (a landmark's leaves the third zero)."""
        B, n = belief.covariance.shape[:2]
        n_robots = n // POSE_DIM
        H = np.zeros((B, n_robots, POSE_DIM, n_robots, POSE_DIM))  # (copy, robot's rows, pose block, its columns)
        R = np.broadcast_to(np.eye(POSE_DIM), (B, n_robots, POSE_DIM, POSE_DIM)).copy()
        poses = belief.x.reshape(B, n_robots, POSE_DIM)
        copies, robots = np.nonzero(sees_landmark)
        if copies.size:
            seen = self._landmarks()[landmarks[copies, robots]][:, None]
            predicted, H_pose = batched.landmark_measurement_model(poses[copies, robots], seen, check_input=False)
            H[copies, robots, :2, robots] = H_pose[:, 0]
            R[copies, robots, :2, :2] = range_bearing_noise(self._sight.noise_stds, robots, predicted[:, 0, 0])
        copies, robots = np.nonzero(sees_teammate)
        if copies.size:
            chosen = pairs[copies, robots]
            targets = self._parts.pairs.targets[chosen]
            predicted, H_observer, H_target = batched.relative_pose_model(
                belief.x[copies], robots[:, None], targets[:, None], check_input=False
            )
            H[copies, robots, :, robots], H[copies, robots, :, targets] = H_observer[:, 0], H_target[:, 0]
            R[copies, robots] = self._pair_noise(chosen, predicted[:, 0, 0])
        observing = np.flatnonzero((sees_landmark | sees_teammate).any(axis=1))
        P = belief.covariance.copy()
        if observing.size:
            stacked_R = np.array([block_diagonal(blocks) for blocks in R[observing]])
            P[observing] = batched.posterior_covariance(
                P[observing], H[observing].reshape(observing.size, n, n), stacked_R, check_input=False
            )
        return P

    def _expected_motion(self, x, P, motions, driving) -> tuple[np.ndarray, np.ndarray]:
        """The prediction ``(x, P)`` of the step's commanded turns and drives (the ``driving`` robots' motions)."""
        turns, speeds = motion_plan(motions[..., None], x[:, 2::POSE_DIM, None], self._parts.speeds_mps[:, None])
        turns, speeds = np.where(driving, turns[..., 0], 0.0), np.where(driving, speeds[..., 0], 0.0)
        for phase_s, controls in motion_phases(turns, speeds, self.config):
            x, P = batched.predict_team(x, P, controls, phase_s, self._odometry_covariances, check_input=False)
        return x, P
