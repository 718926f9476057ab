"""The episode and step of ``infonav/ActiveLocalization-v0`` on (N, ...) arrays, and its outputs.

The scenario (``scenario.py``) starts its copies' episodes, steps them and writes their observations
and infos with these functions; the planning model (``planning.py``) steps a batch of hypothetical
beliefs with the same ones (decision layout, measurement model, commands, outcome, reward terms), its unknowns
(noise, collisions, the true pose) replaced by their expectation. An action is observation slot ``a // 5``
(0: none, ``j + 1``: landmark ``j``) and motion primitive ``a % 5``, so masks and gains are (N, 1 + K, 5)
flattened to (N, 5 (1 + K)).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from infonav_gym.compiled import contiguous, kernel, stacked
from infonav_gym.envs.observation_kernels import BIG, POSE_FEATURES, clip_into, pose_features, range_bearing_features
from infonav_gym.estimation import batched
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.information import position_std_kernel as position_std
from infonav_gym.sensors.range_bearing import RangeBearingSensor
from infonav_gym.world.active_scenarios import GoalFieldLayouts, goal_field_layouts, goal_field_scenarios
from infonav_gym.world.scenarios import Scenario
from infonav_gym.world.visibility import StaticGeometry
from infonav_gym.world.world_batch import start_poses

# Motion primitives: the heading to steer for, relative to the estimated bearing of the goal [rad].
PRIMITIVE_OFFSETS_RAD = (0.0, math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2)
PRIMITIVE_NAMES = ("to_goal", "veer_left", "veer_right", "sidestep_left", "sidestep_right")
N_PRIMITIVES = len(PRIMITIVE_OFFSETS_RAD)
GOAL_FEATURES = 4
LANDMARK_FEATURES = 4
OBSTACLE_FEATURES = 4
REWARD_TERMS = ("mutual_information", "sensing_cost", "motion_cost", "progress", "goal_bonus", "failure_penalty")
REWARD_WEIGHT_KEYS = (
    "observation_cost_nats",
    "motion_cost_per_step",
    "progress_reward_per_m",
    "goal_bonus",
    "failure_penalty",
)


def decode_actions(actions) -> tuple[np.ndarray, np.ndarray]:
    """``(landmarks, primitives)`` of action indices (n,): the landmark observed (-1: none) and the primitive."""
    slots, primitives = np.divmod(np.asarray(actions, dtype=int), N_PRIMITIVES)
    return slots - 1, primitives


@kernel
def layout_of_actions(observable, landmark_gains):
    """``(action_mask int8, action_information_gain)`` (n, 5 (1 + K)) of copies that may observe ``observable``
    landmarks (n, K) bool, each with its expected gain (n, K) [nats]: action ``5 (1 + k) + p`` observes landmark k
    with primitive p, and every primitive without an observation is valid; gains 0 where masked."""
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


def landmark_models(sensor: RangeBearingSensor, poses: np.ndarray, landmarks: np.ndarray):
    """Each landmark's range-bearing model at each estimated pose: ``(predicted (n, K, 2), H (n, K, 2, 3),
    R (n, K, 2, 2))`` for poses (n, 3) and landmarks (n, K, 2), as ``LandmarkDecision`` computes them."""
    predicted, H = batched.landmark_measurement_model(poses, landmarks, check_input=False)
    R = sensor.noise_covariance(predicted[..., 0].ravel()).reshape(*predicted.shape[:2], 2, 2)
    return predicted, H, R


def primitive_commands(config: dict, goals: np.ndarray, poses: np.ndarray, primitives) -> np.ndarray:
    """``[speed, turn rate]`` (n, 2) that each pose's primitive (n,) (-1: stand still) commands from the estimated
    ``poses`` (n, 3) towards ``goals`` [m], one (2,) for all or one per pose (n, 2)."""
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
    commands = np.zeros((len(poses), 2))
    for i in range(len(poses)):
        if primitives[i] < 0:
            continue
        goal_bearing = math.atan2(goals[i, 1] - poses[i, 1], goals[i, 0] - poses[i, 0])
        turn = wrap(goal_bearing + PRIMITIVE_OFFSETS_RAD[primitives[i]] - poses[i, 2])
        commands[i, 0] = speed_mps * max(math.cos(turn), 0.0)
        commands[i, 1] = min(max(turn, -max_turn_rad), max_turn_rad) / dt
    return commands


def step_rewards(config: dict, before, after, goals, covariances, mutual_information, observed, driving, scored):
    """``(terms (6, n) [nats] in REWARD_TERMS order, totals (n,), reached (n,), failed (n,))`` of n steps: progress
    from the positions ``before`` to ``after`` [m] (n, 2) towards ``goals``; the EKF ``covariances`` after them, the
    MI of each update (n,) [nats], which ``observed``, were ``driving`` and are ``scored`` (may reach the goal, within
    ``goal_radius_m``, or fail: not reached and the largest position std above ``max_position_std_m``)."""
    return rewards_of_steps(
        *(contiguous(np.asarray(array, dtype=float)) for array in (before, after, goals, covariances)),
        contiguous(np.asarray(mutual_information, dtype=float)),
        *(contiguous(np.asarray(array, dtype=np.bool_)) for array in (observed, driving, scored)),
        np.array([config[key] for key in (*REWARD_WEIGHT_KEYS, "goal_radius_m", "max_position_std_m")], dtype=float),
    )


@kernel
def rewards_of_steps(before, after, goals, covariances, mutual_information, observed, driving, scored, weights):
    """``step_rewards`` of n steps; ``weights``: the config's five reward weights, goal radius and failure bound."""
    n = len(before)
    terms, totals = np.zeros((len(REWARD_TERMS), n)), np.zeros(n)
    reached, failed = np.zeros(n, dtype=np.bool_), np.zeros(n, dtype=np.bool_)
    for c in range(n):
        distance_after = math.hypot(after[c, 0] - goals[c, 0], after[c, 1] - goals[c, 1])
        if scored[c]:
            reached[c] = distance_after <= weights[5]
            std = position_std(covariances[c, 0, 0], covariances[c, 0, 1], covariances[c, 1, 1])
            failed[c] = not reached[c] and std > weights[6]
        terms[0, c] = mutual_information[c]
        terms[1, c] = -weights[0] if observed[c] else 0.0
        if driving[c]:
            progress = math.hypot(before[c, 0] - goals[c, 0], before[c, 1] - goals[c, 1]) - distance_after
            terms[2, c], terms[3, c] = -weights[1], weights[2] * progress
        terms[4, c] = weights[3] if reached[c] else 0.0
        terms[5, c] = -weights[4] if failed[c] else 0.0
        for term in range(len(REWARD_TERMS)):
            totals[c] += terms[term, c]
    return terms, totals, reached, failed


class EpisodeStarts(NamedTuple):
    """The starts of n episodes (``start_episodes``): goal fields, their arrays stacked, the initial pose estimates
    (n, 3) and their covariance (3, 3), the same for all, and each episode's sensors' generators (odometry,
    measurement)."""

    scenarios: list[Scenario]
    layouts: GoalFieldLayouts
    poses: np.ndarray
    pose_covariance: np.ndarray
    sensor_generators: list[list[np.random.Generator]]


def start_episodes(config: dict, generators: list[np.random.Generator]) -> EpisodeStarts:
    """Each generator's episode: its goal field, then its sensors' generators, then its initial estimate (in that
    order, so a sub-env's episode does not depend on the number of copies); the fields laid out in one batch."""
    layouts = goal_field_layouts(generators, config["n_candidates"], config["n_obstacles"], config["field_size_m"])
    scenarios = goal_field_scenarios(layouts)
    sensor_generators = [np_random.spawn(2) for np_random in generators]
    pose_std = np.array([config["initial_position_std_m"]] * 2 + [config["initial_heading_std_rad"]])
    normals = np.array([np_random.standard_normal(POSE_DIM) for np_random in generators])
    poses = np.array([start_poses(scenario)[0] for scenario in scenarios]) + pose_std * normals
    return EpisodeStarts(scenarios, layouts, poses, np.diag(pose_std**2), sensor_generators)


def field_geometry(walls, wall_thickness_m: float, centers: np.ndarray, radii: np.ndarray) -> StaticGeometry:
    """``StaticGeometry.from_scenario`` of n goal fields, stacked: their common ``walls`` of ``wall_thickness_m`` [m],
    then their round obstacles, centres (n, O, 2) and radii (n, O) [m]."""
    walls, n = np.array(walls, dtype=float), len(radii)
    wall_shape, (starts, ends) = (n, len(walls)), (np.repeat(walls[None, :, end], n, axis=0) for end in (0, 1))
    walls = (starts, ends, np.full(wall_shape, wall_thickness_m / 2), np.ones(wall_shape, dtype=bool))
    arrays = (*walls, centers, radii, np.ones(radii.shape, dtype=bool))
    for array in arrays:
        array.flags.writeable = False  # as every StaticGeometry's
    return StaticGeometry(*arrays)


def observation_bounds(n_landmarks: int, n_obstacles: int) -> tuple[list, list]:
    """``(low, high)`` of the observation features after the pose's, with K landmarks and O obstacles."""
    low = [0, -1, -1, 0] + [0, 0, -1, -1] * n_landmarks + [0, -1, -1, 0] * n_obstacles
    high = [BIG, 1, 1, 1] + [1, BIG, 1, 1] * n_landmarks + [BIG, 1, 1, BIG] * n_obstacles
    return low, high


@kernel
def outputs_of_copies(
    visible, gains, predicted, entropy, x, P, truth, goals, elapsed, left, centers, radii, horizon, budget, low, high
):
    """``(action_mask, action_information_gain, observations, info values)`` of n copies from their landmarks'
    ``LandmarkDecision`` fields: the action layout (every primitive without an observation, and with each ``visible``
    landmark while budget is left), the observations (n, 14 + 4K + 4O) clipped to ``[low, high]`` (the space's bounds
    as float64), and the position error [m], heading error [rad], largest position std [m] and true distance to the
    goal [m] (n, 4)."""
    n_copies, n_landmarks = visible.shape
    observable = np.empty((n_copies, n_landmarks), dtype=np.bool_)
    observation = np.empty((n_copies, len(low)), dtype=np.float32)
    values, info = np.zeros(len(low)), np.empty((n_copies, 4))
    landmarks_start = POSE_FEATURES + GOAL_FEATURES
    obstacles_start = landmarks_start + LANDMARK_FEATURES * n_landmarks
    for c in range(n_copies):
        values[:] = 0.0
        pose_features(values, x[c], P[c], entropy[c], elapsed[c] / horizon)
        dx, dy = goals[c, 0] - x[c, 0], goals[c, 1] - x[c, 1]
        bearing = wrap(math.atan2(dy, dx) - x[c, 2])
        range_bearing_features(values[POSE_FEATURES : POSE_FEATURES + 3], math.hypot(dx, dy), bearing)
        values[POSE_FEATURES + 3] = left[c] / budget if budget else 0.0
        for k in range(n_landmarks):
            observable[c, k] = visible[c, k] != 0 and left[c] > 0
            row = landmarks_start + LANDMARK_FEATURES * k
            values[row] = visible[c, k]
            range_bearing_features(values[row + 1 : row + 4], predicted[c, k, 0], predicted[c, k, 1])
        for o in range(radii.shape[1]):
            row = obstacles_start + OBSTACLE_FEATURES * o
            dx, dy = centers[c, o, 0] - x[c, 0], centers[c, o, 1] - x[c, 1]
            bearing = wrap(math.atan2(dy, dx) - x[c, 2])
            range_bearing_features(values[row : row + 3], math.hypot(dx, dy), bearing)
            values[row + 3] = radii[c, o]
        clip_into(observation[c], values, low, high)
        info[c, 0] = math.hypot(truth[c, 0] - x[c, 0], truth[c, 1] - x[c, 1])
        info[c, 1] = abs(wrap(truth[c, 2] - x[c, 2]))
        info[c, 2] = position_std(P[c, 0, 0], P[c, 0, 1], P[c, 1, 1])
        info[c, 3] = math.hypot(truth[c, 0] - goals[c, 0], truth[c, 1] - goals[c, 1])
    return (*layout_of_actions(observable, gains), observation, info)
