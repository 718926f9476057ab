"""``infonav/LandmarkSelection-v0``: choose which landmark to observe (the paper's Section III), as a scenario."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from infonav_gym.compiled import kernel
from infonav_gym.config import Interval, check_choice, check_config, check_config_arguments
from infonav_gym.envs.base import shared_config
from infonav_gym.envs.landmark_decision import LandmarkDecision, checked_fields, decision_arguments, landmark_decisions
from infonav_gym.envs.metrics import LOCALIZATION_METRICS
from infonav_gym.envs.observation_kernels import BIG, POSE_FEATURES, clip_into, pose_features, range_bearing_features
from infonav_gym.envs.one_robot import OneRobotDriver, OneRobotScenario, OneRobotState
from infonav_gym.envs.single_view import SingleEnvView
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.envs.vector_infos import decision_info
from infonav_gym.estimation.state import INITIAL_POSE_STD, POSE_DIM, Prior
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.information import gaussian_entropy_kernel
from infonav_gym.scene import SceneFrame
from infonav_gym.sensors.odometry import odometry_sensor_from_config
from infonav_gym.sensors.range_bearing import range_bearing_sensor_from_config
from infonav_gym.world.physics import TIME_STEP_S
from infonav_gym.world.scenarios import (
    CORRIDOR_LANDMARK_COUNT,
    FIELD_ARGUMENTS,
    MAX_LANDMARKS,
    scenario_from_config,
    scenario_names,
)
from infonav_gym.world.visibility import StaticGeometry
from infonav_gym.world.world_batch import start_poses

SCENARIO_KEYS = {  # scenario builder parameter: the config key that gives it
    "speed_mps": "speed_mps",
    "n_landmarks": "n_candidates",
    "n_obstacles": "n_obstacles",
    "size_m": "field_size_m",
}
CANDIDATE_FEATURES = 5
# the info keys ``landmark_outputs`` computes, in its order
INFO_NUMBERS = ("pose_entropy", "state_entropy", "position_error_m", "heading_error_rad", "time_s")
INFO_NUMBERS += ("true_pose", "estimated_pose")
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "n_candidates": Interval(1, MAX_LANDMARKS, integer=True),
    "time_step_s": TIME_STEP_S,
    "landmark_prior_std_m": Interval(1e-4, 100.0, unit="m"),
    **INITIAL_POSE_STD,
}


@dataclass
class LandmarkState(OneRobotState):
    """``OneRobotState``, the realized MI of each copy's last step (N,) [nats] and each copy's static geometry."""

    mutual_information: np.ndarray = None
    geometries: list = None


STEP_FIELDS = ("observation", "numbers", "true_pose", "estimated_pose")
LandmarkStep = NamedTuple("LandmarkStep", [(name, np.ndarray) for name in (*LandmarkDecision._fields, *STEP_FIELDS)])
LandmarkStep.__doc__ = """Every copy's ``LandmarkDecision`` and what the same kernel computes at the prior: the
observation (n, 10 + 5K) float32, the ``INFO_NUMBERS`` but the poses (n, 5) and the true and estimated poses (n, 3)."""


class LandmarkSelection(OneRobotScenario):
    """``infonav/LandmarkSelection-v0`` as a scenario (spaces, reward, config: ``LandmarkSelectionEnv``)."""

    episode_metrics = LOCALIZATION_METRICS
    traits = EnvTraits(
        kb_per_copy=10,  # [kB] at the defaults, between peak RSS growth and traced allocations
        estimates_pose=True,
        rewards_information_at_once=True,
        reward_terms=("mutual_information",),
        main_metric="cumulative_mi",
    )

    @classmethod
    def default_config(cls) -> dict:
        return {
            **shared_config(),
            "scenario": "field",  # "field" (random), "corridor" (the paper's Fig. 1), or registered (register_scenario)
            "n_candidates": 8,  # K, size of the action space
            "time_step_s": 0.5,  # [s]
            "speed_mps": 1.0,  # cruise speed along the route [m/s]
            "mapping": False,  # True: landmark positions are uncertain and estimated (EKF-SLAM)
            "landmark_prior_std_m": 1.0,  # prior std of each landmark coordinate when mapping [m]
            "range_std_m": 0.1,  # [m]
            "range_std_per_m": 0.01,  # growth of the range std with distance [m/m]
            "bearing_std_rad": math.radians(2.0),  # [rad]
            "sensor_max_range_m": 15.0,  # [m]
            "sensor_fov_rad": math.pi,  # full field of view around the heading [rad]
            "odometry_speed_std_mps": 0.05,  # [m/s]
            "odometry_turn_rate_std_rps": 0.02,  # [rad/s]
            "initial_position_std_m": 0.1,  # [m]
            "initial_heading_std_rad": 0.02,  # [rad]
            "n_obstacles": 6,  # field scenario only
            "field_size_m": 30.0,  # side of the square field [m]
        }

    def __init__(self, config: dict, copies: int, owner: str, render_mode: str | None):
        super().__init__(config, copies, owner, render_mode)
        cfg = config
        check_choice(cfg, "scenario", scenario_names(team=False), owner)
        check_config(cfg, owner, CONFIG_INTERVALS)
        check_config_arguments(cfg, owner, "field", FIELD_ARGUMENTS, SCENARIO_KEYS)  # the corridor's speed too
        if cfg["scenario"] == "corridor" and cfg["n_candidates"] < CORRIDOR_LANDMARK_COUNT:
            raise ValueError(
                f"config key 'n_candidates' of {owner} must be >= {CORRIDOR_LANDMARK_COUNT} "
                f"(the corridor's landmarks), got {cfg['n_candidates']}"
            )
        self.use_observation_bounds([0, 0, -1, -1, 0] * cfg["n_candidates"], [1, BIG, 1, 1, BIG] * cfg["n_candidates"])
        self.action_space = spaces.Discrete(cfg["n_candidates"])
        self.use_sensors(range_bearing_sensor_from_config(cfg, owner), odometry_sensor_from_config(cfg, owner))

    def allocate(self, copies: int) -> LandmarkState:
        fields = self.robot_fields(copies, self.config["n_candidates"])
        return LandmarkState(**fields, mutual_information=np.zeros(copies), geometries=[None] * copies)

    def initial(self, state: LandmarkState, rows: np.ndarray, rngs: list) -> LandmarkState:
        """Draw each copy's scenario and prior (``start_episode``); with ``mapping`` every copy needs the same
        number of landmarks."""
        owner, n_copies, scenarios = self.owner, len(state.elapsed), []
        for copy, rng in zip(rows.tolist(), rngs):
            scenario, prior, odometry_rng, measurement_rng = start_episode(self.config, rng, owner)
            x, P = prior.state()
            if state.x is None or len(rows) == n_copies and copy == 0:
                state.x, state.P = np.zeros((n_copies, len(x))), np.zeros((n_copies, len(x), len(x)))
            if len(x) != state.x.shape[1]:
                raise ValueError(
                    f"sub-env {copy} of {owner}: with mapping=True every copy needs the same number of landmarks; "
                    f"scenario {scenario.name!r} has {len(scenario.landmarks)}, the other copies "
                    f"{(state.x.shape[1] - 3) // 2}"
                )
            state.worlds.reset_copy(copy, scenario)
            state.odometry_noise.restart(copy, odometry_rng)
            state.measurement_noise.restart(copy, measurement_rng)
            state.x[copy], state.P[copy] = x, P
            state.landmarks[copy] = 0.0
            state.landmarks[copy, : len(scenario.landmarks)] = scenario.landmarks
            scenarios.append(scenario)
        state.exists[rows] = np.arange(self.config["n_candidates"]) < [[len(s.landmarks)] for s in scenarios]
        started = StaticGeometry.from_scenarios(scenarios, state.worlds.wall_thickness_m)
        for index, copy in enumerate(rows.tolist()):
            state.geometries[copy] = started.single(index)
        state.geometry = started if len(rows) == n_copies else StaticGeometry.stack(state.geometries)
        state.chosen[rows], state.mutual_information[rows] = -1, 0.0
        if rows[0] == 0:
            self.follow_first_copy(state, restarted=True)
        return state

    def decision(self, state: LandmarkState, rows) -> LandmarkStep:
        """The landmarks each copy sees, their models and expected MI at its prior, with its observation and info
        numbers (``landmark_outputs``, on the scenario's threads)."""
        cfg = self.config
        full = isinstance(rows, slice)
        geometry = state.geometry if full else StaticGeometry.stack([state.geometries[row] for row in rows])
        true_poses, x, P = state.worlds.poses[rows, 0], state.x[rows], state.P[rows]
        arguments = decision_arguments(
            self.sensor, geometry, true_poses, x, P, state.landmarks[rows], state.exists[rows], cfg["mapping"]
        )
        per_copy, shared = (arguments, state.elapsed[rows]), (float(cfg["horizon"]), float(cfg["time_step_s"]))
        outputs = self.threads.map_rows(landmark_outputs, len(x), per_copy, (*shared, *self.bounds))
        decided, observation, numbers, *poses = outputs
        return LandmarkStep(*checked_fields(decided), observation, numbers, *poses)

    def transition(self, state: LandmarkState, decision: LandmarkStep, action, acting) -> LandmarkState:
        """Observe the chosen landmarks at the prior, then drive the ``acting`` copies along their routes."""
        chosen = action[:, 0]
        state.x, state.P, state.mutual_information = self.measured(state, decision, chosen)
        state.chosen = chosen
        n_acting = np.count_nonzero(acting)  # their worlds step, their EKFs predict from noisy odometry
        if n_acting == len(acting):  # all of them (the usual step): the predicted arrays are new ones
            state.x, state.P = self.moved(state, self.every_copy, state.x, state.P)
        elif n_acting:
            copies = np.flatnonzero(acting)
            state.x[copies], state.P[copies] = self.moved(state, copies, state.x[copies], state.P[copies])
        if acting[0]:
            self.follow_first_copy(state, restarted=False)
        return state

    def reward(self, decision, action, state: LandmarkState) -> np.ndarray:
        """The realized mutual information of each copy's update [nats] (0 without one)."""
        return state.mutual_information.copy()

    def observation(self, state: LandmarkState, decision: LandmarkStep, rows) -> np.ndarray:
        return decision.observation

    def info(self, state: LandmarkState, decision: LandmarkStep, rows, stepped) -> dict:
        """The decision's mask and gains, the reward term, the action taken and the ``INFO_NUMBERS``."""
        rewards = state.mutual_information[rows]
        info = decision_info(decision, stepped, state.chosen[rows], ("mutual_information",), rewards[None])
        info.update(zip(INFO_NUMBERS, (*decision.numbers.T, decision.true_pose, decision.estimated_pose)))
        return info

    def frame(self, state: LandmarkState, decision: LandmarkStep):
        """Copy 0 drawn: its scenario, landmarks (seen ones marked, the chosen one linked), the robot."""
        scenario, n_landmarks = state.worlds.scenario(0), int(state.exists[0].sum())
        mapped = state.x[0, POSE_DIM:].reshape(-1, 2) if self.config["mapping"] else None
        blocks = [state.P[0, 3 + 2 * i : 5 + 2 * i, 3 + 2 * i : 5 + 2 * i] for i in range(n_landmarks)]
        chosen = int(state.chosen[0])
        time_s = state.elapsed[0] * self.config["time_step_s"]
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            landmarks=scenario.landmarks,
            landmark_visible=decision.action_mask[0, :n_landmarks].astype(bool),
            chosen_landmark=None if chosen < 0 else chosen,
            robots=[self.first_robot_drawing(state)],
            landmark_estimates=mapped,
            landmark_covariances=np.array(blocks) if mapped is not None else None,
            caption=f"t = {time_s:.1f} s   pose entropy {decision.pose_entropy[0]:.2f} nats",
        )


class LandmarkSelectionVectorEnv(OneRobotDriver, scenario=LandmarkSelection):
    """N copies of ``infonav/LandmarkSelection-v0``, the driver bound to its scenario (``gym.make_vec``).

    Observations (N, 10 + 5K), ``info["action_mask"]`` (N, K). With ``mapping=True`` every copy's scenario must
    have the same number of landmarks (the stacked states share their size).
    """


class LandmarkSelectionEnv(SingleEnvView, vector_env=LandmarkSelectionVectorEnv):
    """A robot drives a fixed route; each step it observes one landmark, chosen for its information.

    ## Description
    The vehicle follows its route in a Pymunk world while an EKF tracks its
    pose from noisy odometry. Each step the agent picks one of ``n_candidates``
    landmarks; the EKF updates with a noisy range-bearing measurement of it. A
    greedy-entropy agent picks the landmark with the largest expected mutual
    information; the paper's Fig. 1-2 corridor is ``scenario="corridor"``.

    The agent decides at the predicted prior of the step at which the
    measurement is taken, so ``info["action_information_gain"][a]`` is the exact
    mutual information that action ``a`` will bring (the EKF's posterior
    covariance does not depend on the measured value).

    ## Action Space
    ``Discrete(n_candidates)``: the index of the landmark to observe. An action
    is valid when that landmark exists, lies within the sensor's range and field
    of view, and no wall or obstacle blocks the line of sight (``info["action_mask"]``; ``action_masks()``
    is all ``True`` when no landmark is visible: every action is then the no-op).

    ## Observation Space
    ``Box(float32, (10 + 5 * n_candidates,))``: estimated ``x, y`` [m], ``cos, sin``
    of the estimated heading, standard deviations of ``x, y`` [m] and heading
    [rad], the ``x-y`` correlation, the pose entropy [nats] and the elapsed
    fraction of the horizon; then per candidate: valid flag, estimated range [m],
    ``cos, sin`` of the estimated bearing, and the landmark's position standard
    deviation [m] (0 for a known map). Missing candidates are all zeros.

    ## Rewards
    The realized mutual information of the update, ``0.5 ln(det P_prior / det P_post)``
    [nats] (the paper's ``ic``, Eq. 3), over the pose, or over the whole state
    (pose and landmarks) when ``mapping=True``.

    ## Starting State
    The robot at the scenario's start pose; the initial estimate is drawn from the
    prior ``N(true pose, diag(initial_position_std_m^2, ..., initial_heading_std_rad^2))``.

    ## Episode End
    Truncated after ``horizon`` steps; never terminated.

    ## Arguments
    ``gym.make("infonav/LandmarkSelection-v0", render_mode=None, **config)`` with any key of ``default_config()``.

    ## Version History
    * v0: initial version.
    """


def start_episode(config: dict, np_random: np.random.Generator, owner: str):
    """``(scenario, prior, odometry_rng, measurement_rng)`` of an episode drawn from ``np_random`` in a fixed order:
    the scenario (one route, <= ``n_candidates`` landmarks), the sensors' generators, the initial estimate, the
    mapped landmarks' estimates; ``owner`` is named in config errors."""
    scenario = scenario_from_config(config, np_random, SCENARIO_KEYS, owner, 1, max_landmarks=config["n_candidates"])
    odometry_rng, measurement_rng = np_random.spawn(2)
    pose_std = np.array([config["initial_position_std_m"]] * 2 + [config["initial_heading_std_rad"]])
    initial_pose = np.array(start_poses(scenario)[0]) + pose_std * np_random.standard_normal(POSE_DIM)
    prior = Prior(initial_pose, np.diag(pose_std**2))
    if config["mapping"]:
        landmarks, prior_std = scenario.landmarks, config["landmark_prior_std_m"]
        estimates = landmarks + prior_std * np_random.standard_normal(landmarks.shape)
        prior = prior._replace(landmarks=estimates, landmark_variance=prior_std**2)
    return scenario, prior, odometry_rng, measurement_rng


@kernel
def landmark_outputs(arguments, elapsed, horizon, time_step_s, low, high):
    """``landmark_decisions(*arguments)`` (``decision_arguments``), then the observations (n, 10 + 5K) float32 (in
    float64, clipped to ``low``, ``high``, then rounded), the ``INFO_NUMBERS`` but the poses (n, 5), then the true and
    estimated poses (n, 3) of n copies; ``elapsed`` (n,) int: steps since each one's reset; ``horizon`` [steps] and
    ``time_step_s`` [s] as floats. A mapped landmark's position std is the root of the mean of its two variances."""
    decided = landmark_decisions(*arguments)
    x, P, true_poses, exists, mapped = arguments[0], arguments[1], arguments[3], arguments[4], arguments[5]
    action_mask, predicted, prior_log_det, pose_entropy = decided[0], decided[2], decided[5], decided[6]
    n_copies, n_candidates = exists.shape
    observation = np.empty((n_copies, len(low)), dtype=np.float32)
    values = np.zeros(len(low))
    n_mapped = (x.shape[1] - POSE_DIM) // 2 if mapped else 0
    numbers = np.empty((n_copies, len(INFO_NUMBERS) - 2))  # the INFO_NUMBERS but the poses
    for c in range(n_copies):
        values[:] = 0.0
        pose_features(values, x[c], P[c], pose_entropy[c], elapsed[c] / horizon)
        for k in range(n_candidates):
            row = POSE_FEATURES + CANDIDATE_FEATURES * k
            values[row] = action_mask[c, k]
            if exists[c, k]:
                range_bearing_features(values[row + 1 : row + 4], predicted[c, k, 0], predicted[c, k, 1])
            if k < n_mapped:
                i = POSE_DIM + 2 * k
                values[row + 4] = math.sqrt((P[c, i, i] + P[c, i + 1, i + 1]) / 2)
        clip_into(observation[c], values, low, high)
        numbers[c, 0], numbers[c, 1] = pose_entropy[c], gaussian_entropy_kernel(prior_log_det[c], x.shape[1])
        numbers[c, 2] = math.hypot(true_poses[c, 0] - x[c, 0], true_poses[c, 1] - x[c, 1])
        numbers[c, 3], numbers[c, 4] = abs(wrap(true_poses[c, 2] - x[c, 2])), elapsed[c] * time_step_s
    return decided, observation, numbers, true_poses.copy(), x[:, :POSE_DIM].copy()
