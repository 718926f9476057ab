"""The episode and step of ``infonav/ActiveLocalization-v0`` on (N, ...) arrays, and its outputs.

The env (``envs.active_localization``) starts its copies' episodes, steps them and writes their observations
and infos with these functions; the planning model (``envs.active_planning``) steps a batch of hypothetical
beliefs with the same ones (decision layout, measurement model, commands, outcome, reward terms), its unknowns
(noise, collisions, the true pose) replaced by their expectation. An action is observation slot ``a // 5``
(0: none, ``j + 1``: landmark ``j``) and motion primitive ``a % 5``, so masks and gains are (N, 1 + K, 5)
flattened to (N, 5 (1 + K)).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from infonav_gym.compiled import contiguous, kernel, stacked
from infonav_gym.envs.landmark_decision import LandmarkDecision
from infonav_gym.envs.landmark_selection import Prior
from infonav_gym.envs.observation_kernels import POSE_FEATURES, clip_into, pose_features, range_bearing_features
from infonav_gym.estimation import batched
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.geometry import wrap_angle
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.information import largest_position_std
from infonav_gym.sensors.range_bearing import RangeBearingSensor
from infonav_gym.world.active_scenarios import goal_field
from infonav_gym.world.scenarios import Scenario
from infonav_gym.world.world import start_poses

# Motion primitives: the heading to steer for, relative to the estimated bearing of the goal [rad].
PRIMITIVE_OFFSETS_RAD = (0.0, math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2)
PRIMITIVE_NAMES = ("to_goal", "veer_left", "veer_right", "sidestep_left", "sidestep_right")
N_PRIMITIVES = len(PRIMITIVE_OFFSETS_RAD)
GOAL_FEATURES = 4
LANDMARK_FEATURES = 4
OBSTACLE_FEATURES = 4
_BIG = 1e4
REWARD_TERMS = ("mutual_information", "sensing_cost", "motion_cost", "progress", "goal_bonus", "failure_penalty")


def decode_actions(actions) -> tuple[np.ndarray, np.ndarray]:
    """``(landmarks, primitives)`` of action indices (n,): the landmark observed (-1: none) and the primitive."""
    slots, primitives = np.divmod(np.asarray(actions, dtype=int), N_PRIMITIVES)
    return slots - 1, primitives


def action_layout(observable: np.ndarray, landmark_gains: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(action_mask int8, action_information_gain)`` (n, 5 (1 + K)) of copies that may observe ``observable``
    landmarks (n, K) bool, each with its expected gain (n, K) [nats]: every primitive without an observation is
    valid, and with each observable landmark; gains 0 where masked."""
    observable = contiguous(np.asarray(observable, dtype=np.bool_))
    return layout_of_actions(observable, contiguous(np.asarray(landmark_gains, dtype=float)))


@kernel
def layout_of_actions(observable, landmark_gains):
    """``action_layout`` of n copies: action ``5 (1 + k) + p`` observes landmark k with primitive p."""
    n_copies, n_landmarks = observable.shape
    mask = np.ones((n_copies, N_PRIMITIVES * (1 + n_landmarks)), dtype=np.int8)
    gains = np.zeros(mask.shape)
    for c in range(n_copies):
        for k in range(n_landmarks):
            for primitive in range(N_PRIMITIVES):
                action = N_PRIMITIVES * (1 + k) + primitive
                mask[c, action] = observable[c, k]
                if observable[c, k]:
                    gains[c, action] = landmark_gains[c, k]
    return mask, gains


class ActiveDecision(NamedTuple):
    """Every copy's decision at its EKF's prior.

    Attributes:
        sight: the landmarks' visibility and measurement model at each prior (its mask: visible, budget aside).
        action_mask: int8 (N, A), 1 = valid: every primitive without an observation, and with each visible
            landmark while budget is left.
        action_information_gain: expected MI of each action (N, A) [nats], 0 where masked.
    """

    sight: LandmarkDecision
    action_mask: np.ndarray
    action_information_gain: np.ndarray

    @classmethod
    def from_sight(cls, sight: LandmarkDecision, observations_left: np.ndarray) -> ActiveDecision:
        """The decisions of copies whose landmarks are ``sight`` and sensing budgets ``observations_left`` (N,)."""
        observable = sight.action_mask.astype(bool) & (observations_left > 0)[:, None]
        return cls(sight, *action_layout(observable, sight.action_information_gain))


def landmark_models(sensor: RangeBearingSensor, poses: np.ndarray, landmarks: np.ndarray):
    """Each landmark's range-bearing model at each estimated pose: ``(predicted (n, K, 2), H (n, K, 2, 3),
    R (n, K, 2, 2))`` for poses (n, 3) and landmarks (n, K, 2), as ``LandmarkDecision`` computes them."""
    predicted, H = batched.landmark_measurement_model(poses, landmarks, check_input=False)
    R = sensor.noise_covariance(predicted[..., 0].ravel()).reshape(*predicted.shape[:2], 2, 2)
    return predicted, H, R


def primitive_commands(config: dict, goals: np.ndarray, poses: np.ndarray, primitives) -> np.ndarray:
    """``[speed, turn rate]`` (n, 2) that each motion primitive commands from each estimated pose.

    Args:
        config: a checked ``ActiveLocalization-v0`` config.
        goals: the goal position [m], one (2,) for all poses or one per pose (n, 2).
        poses: estimated poses ``[x, y, heading]`` (n, 3).
        primitives: the primitive of each pose (n,), indices of ``PRIMITIVE_OFFSETS_RAD``.
    """
    poses = contiguous(np.asarray(poses, dtype=float))
    dt = config["time_step_s"]
    return commands_of_primitives(
        stacked(goals, (len(poses), 2)),
        poses,
        contiguous(np.asarray(primitives, dtype=np.int64)),
        config["speed_mps"],
        config["max_turn_rate_rps"] * dt,
        dt,
    )


@kernel
def commands_of_primitives(goals, poses, primitives, speed_mps, max_turn_rad, dt):
    """``primitive_commands`` of n poses (n, 3) with their goals (n, 2): steer for the goal's estimated bearing plus
    the primitive's offset, the turn clipped to ``max_turn_rad`` per step, the speed scaled by the cosine of the
    wanted turn (0 beyond a right angle)."""
    commands = np.empty((len(poses), 2))
    for i in range(len(poses)):
        goal_bearing = math.atan2(goals[i, 1] - poses[i, 1], goals[i, 0] - poses[i, 0])
        turn = wrap(goal_bearing + PRIMITIVE_OFFSETS_RAD[primitives[i]] - poses[i, 2])
        commands[i, 0] = speed_mps * max(math.cos(turn), 0.0)
        commands[i, 1] = min(max(turn, -max_turn_rad), max_turn_rad) / dt
    return commands


def distances(positions: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """The distance [m] of each position (n, 2) to its goal (n, 2) or to one goal (2,)."""
    offsets = positions - goals
    return np.hypot(offsets[:, 0], offsets[:, 1])


def step_outcome(config: dict, distance_after: np.ndarray, covariances: np.ndarray):
    """``(reached, failed)`` (n,) bool after a step: within ``goal_radius_m`` of the goal, or (not reached) the
    largest position std of ``covariances`` (n, 3, 3) above ``max_position_std_m``."""
    reached = distance_after <= config["goal_radius_m"]
    return reached, ~reached & (largest_position_std(covariances) > config["max_position_std_m"])


def reward_terms(config: dict, mutual_information, observed, driving, progress_m, reached, failed) -> dict:
    """Each of ``REWARD_TERMS`` of n steps, (n,) arrays [nats].

    Args:
        config: a checked ``ActiveLocalization-v0`` config (the costs, bonus and penalty weights).
        mutual_information: the MI of each step's update (n,) [nats], 0 without one.
        observed: which steps observed a landmark (n,) bool.
        driving: which executed a primitive (n,) bool (a no-op does not).
        progress_m: how much closer to the goal each step came [m] (n,).
        reached: which reached the goal (n,) bool.
        failed: which crossed the uncertainty bound (n,) bool.
    """
    return {
        "mutual_information": np.asarray(mutual_information, dtype=float),
        "sensing_cost": np.where(observed, -config["observation_cost_nats"], 0.0),
        "motion_cost": np.where(driving, -config["motion_cost_per_step"], 0.0),
        "progress": np.where(driving, config["progress_reward_per_m"] * progress_m, 0.0),
        "goal_bonus": np.where(reached, config["goal_bonus"], 0.0),
        "failure_penalty": np.where(failed, -config["failure_penalty"], 0.0),
    }


def total_reward(terms: dict) -> np.ndarray:
    """The reward: the sum of the terms (n,) [nats], in ``REWARD_TERMS`` order."""
    total = np.zeros_like(terms[REWARD_TERMS[0]])
    for key in REWARD_TERMS:
        total = total + terms[key]
    return total


def ranges_and_bearings(x: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Range [m] and bearing [rad] of targets (N, T, 2) from each pose (N, 3): (N, T, 2), as ``range_bearing``."""
    dx, dy = targets[..., 0] - x[:, None, 0], targets[..., 1] - x[:, None, 1]
    return np.stack([np.hypot(dx, dy), wrap_angle(np.arctan2(dy, dx) - x[:, None, 2])], axis=-1)


def start_episode(config: dict, np_random: np.random.Generator):
    """Start an episode of ``ActiveLocalization-v0``: draw its goal field and the estimator's prior from ``np_random``.

    Draws in a fixed order (the field, the sensors' generators, the initial estimate), so a sub-env gives the
    same episode for the same generator whatever the number of copies.

    Args:
        config: a checked ``ActiveLocalization-v0`` config.
        np_random: the episode's generator.

    Returns:
        ``(scenario, prior, odometry_rng, measurement_rng)``: the goal field, the estimator's ``Prior`` and the
        sensors' generators.
    """
    scenario = goal_field(np_random, config["n_candidates"], config["n_obstacles"], config["field_size_m"])
    odometry_rng, measurement_rng = np_random.spawn(2)
    pose_std = np.array([config["initial_position_std_m"]] * 2 + [config["initial_heading_std_rad"]])
    pose = np.array(start_poses(scenario)[0]) + pose_std * np_random.standard_normal(POSE_DIM)
    return scenario, Prior(pose, np.diag(pose_std**2)), odometry_rng, measurement_rng


def episode_goal(scenario: Scenario) -> np.ndarray:
    """The goal position [m] of a goal field (its route's one waypoint), a fresh (2,) array."""
    return scenario.routes[0].waypoints[0].copy()


def obstacle_discs(scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """The centres (O, 2) [m] and radii (O,) [m] of a scenario's round obstacles (the map the agent knows)."""
    centers = np.array([obstacle.center for obstacle in scenario.obstacles], dtype=float).reshape(-1, 2)
    return centers, np.array([obstacle.radius for obstacle in scenario.obstacles], dtype=float)


def observation_bounds(n_landmarks: int, n_obstacles: int) -> tuple[np.ndarray, np.ndarray]:
    """``(low, high)`` of the observation space with K landmarks and O obstacles (float32)."""
    low = [-_BIG, -_BIG, -1, -1, 0, 0, 0, -1, -100, 0] + [0, -1, -1, 0]
    high = [_BIG, _BIG, 1, 1, _BIG, _BIG, _BIG, 1, 100, 1] + [_BIG, 1, 1, 1]
    low += [0, 0, -1, -1] * n_landmarks + [0, -1, -1, 0] * n_obstacles
    high += [1, _BIG, 1, 1] * n_landmarks + [_BIG, 1, 1, _BIG] * n_obstacles
    return np.array(low, dtype=np.float32), np.array(high, dtype=np.float32)


class CopiesState(NamedTuple):
    """The state of n copies that their outputs read (rows of the env's arrays).

    Attributes:
        x: EKF states (n, 3); ``P`` their covariances (n, 3, 3).
        true_poses: true poses (n, 3).
        goals: goal positions (n, 2) [m].
        elapsed: steps since each copy's reset (n,).
        observations_left: sensing budget left (n,).
        goal_reached, failed: how the last step ended (n,) bool.
    """

    x: np.ndarray
    P: np.ndarray
    true_poses: np.ndarray
    goals: np.ndarray
    elapsed: np.ndarray
    observations_left: np.ndarray
    goal_reached: np.ndarray
    failed: np.ndarray


def observations(decision: ActiveDecision, state: CopiesState, obstacles, config: dict, space: spaces.Box):
    """The observations of n copies (n, 14 + 4K + 4O), float32, clipped to ``space`` (see ``ActiveLocalizationEnv``).

    Args:
        decision: their decisions.
        state: their state.
        obstacles: their ``(centers (n, O, 2), radii (n, O))`` [m].
        config: the env config; ``space`` the single observation space.
    """
    budget, sight = config["max_observations"], decision.sight
    left = state.observations_left / budget if budget else np.zeros(len(state.x))
    fractions = (sight.pose_entropy, state.elapsed / config["horizon"], left)
    arrays = (state.x, state.P, *fractions, state.goals, sight.action_mask, sight.predicted, *obstacles)
    return active_observations(
        *(contiguous(np.asarray(array, dtype=float)) for array in arrays),
        space.low.astype(float),
        space.high.astype(float),
    )


@kernel
def active_observations(
    x, P, pose_entropy, elapsed_fraction, left, goals, action_mask, predicted, centers, radii, low, high
):
    """``observations`` of n copies from their arrays: (n, 14 + 4K + 4O) float32, clipped to ``[low, high]``."""
    n_copies, n_landmarks = action_mask.shape
    observation = np.empty((n_copies, len(low)), dtype=np.float32)
    values = np.zeros(len(low))
    landmarks_start = POSE_FEATURES + GOAL_FEATURES
    obstacles_start = landmarks_start + LANDMARK_FEATURES * n_landmarks
    for c in range(n_copies):
        values[:] = 0.0
        pose_features(values, x[c], P[c], pose_entropy[c], elapsed_fraction[c])
        dx, dy = goals[c, 0] - x[c, 0], goals[c, 1] - x[c, 1]
        bearing = wrap(math.atan2(dy, dx) - x[c, 2])
        range_bearing_features(values[POSE_FEATURES : POSE_FEATURES + 3], math.hypot(dx, dy), bearing)
        values[POSE_FEATURES + 3] = left[c]
        for k in range(n_landmarks):
            row = landmarks_start + LANDMARK_FEATURES * k
            values[row] = action_mask[c, k]
            range_bearing_features(values[row + 1 : row + 4], predicted[c, k, 0], predicted[c, k, 1])
        for o in range(radii.shape[1]):
            row = obstacles_start + OBSTACLE_FEATURES * o
            dx, dy = centers[c, o, 0] - x[c, 0], centers[c, o, 1] - x[c, 1]
            bearing = wrap(math.atan2(dy, dx) - x[c, 2])
            range_bearing_features(values[row : row + 3], math.hypot(dx, dy), bearing)
            values[row + 3] = radii[c, o]
        clip_into(observation[c], values, low, high)
    return observation


def infos(decision: ActiveDecision, state: CopiesState, stepped, chosen, terms: dict, config: dict) -> dict:
    """The infos of n copies as arrays (n, ...), each with its ``_key`` mask.

    Args:
        decision: their new decisions.
        state: their state.
        stepped: which acted in this step (n,) bool; the others were reset and give the reset info.
        chosen: the action each took (n,), -1 for a no-op.
        terms: their reward terms, each (n,) [nats].
        config: the env config.
    """
    x, true_poses = state.x, state.true_poses
    errors = true_poses - x
    pose_entropy = decision.sight.pose_entropy
    everyone = np.ones(len(x), dtype=bool)
    stepped_terms = np.where(stepped, np.stack([terms[key] for key in REWARD_TERMS]), 0.0)  # one row per term
    terms, stepped = dict(zip(REWARD_TERMS, stepped_terms)), stepped.copy()
    info = {
        "action_mask": decision.action_mask.copy(),
        "action_information_gain": decision.action_information_gain.copy(),
        "reward_terms": {**terms, **{f"_{key}": stepped for key in terms}},
        "chosen_action": np.where(stepped, chosen, -1),
        "invalid_action": stepped & (chosen < 0),
        "pose_entropy": pose_entropy.copy(),
        "state_entropy": pose_entropy.copy(),
        "position_error_m": np.hypot(errors[:, 0], errors[:, 1]),
        "heading_error_rad": np.abs(wrap_angle(errors[:, 2])),
        "position_std_m": largest_position_std(state.P),
        "true_pose": true_poses.copy(),
        "estimated_pose": x[:, :POSE_DIM].copy(),
        "goal": state.goals.copy(),
        "distance_to_goal_m": distances(true_poses[:, :2], state.goals),
        "observations_left": state.observations_left.copy(),
        "goal_reached": state.goal_reached.copy(),
        "success": state.goal_reached.copy(),  # the evaluation harness's success flag
        "failed": state.failed.copy(),
        "time_s": state.elapsed * config["time_step_s"],
    }
    return {**info, **{f"_{key}": everyone for key in info}}
