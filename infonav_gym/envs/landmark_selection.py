"""``infonav/LandmarkSelection-v0``: choose which landmark to observe (the paper's Section III)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from infonav_gym.config import Interval, check_choice, check_config, check_config_arguments
from infonav_gym.envs.base import Decision, InfoNavEnv
from infonav_gym.envs.landmark_sight import LandmarkSight
from infonav_gym.envs.metrics import LOCALIZATION_METRICS
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.estimation.ekf import INITIAL_POSE_STD, POSE_DIM, PoseEKF
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import gaussian_entropy_from_log_det
from infonav_gym.scene import PathHistory, RobotDrawing, SceneFrame
from infonav_gym.sensors.odometry import odometry_sensor_from_config
from infonav_gym.sensors.range_bearing import range_bearing_sensor_from_config
from infonav_gym.world.scenarios import (
    CORRIDOR_LANDMARK_COUNT,
    FIELD_ARGUMENTS,
    MAX_LANDMARKS,
    scenario_from_config,
    scenario_names,
)
from infonav_gym.world.world import TIME_STEP_S, World, start_poses

SCENARIO_KEYS = {  # scenario builder parameter: the config key that gives it
    "speed_mps": "speed_mps",
    "n_landmarks": "n_candidates",
    "n_obstacles": "n_obstacles",
    "size_m": "field_size_m",
}
POSE_FEATURES = 10
CANDIDATE_FEATURES = 5
_BIG = 1e4
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "n_candidates": Interval(1, MAX_LANDMARKS, integer=True),
    "time_step_s": TIME_STEP_S,
    "landmark_prior_std_m": Interval(1e-4, 100.0, unit="m"),
    **INITIAL_POSE_STD,
}


class LandmarkSelectionEnv(InfoNavEnv):
    """A robot drives a fixed route; each step it observes one landmark, chosen for its information.

    ## Description
    The vehicle follows its route in a Pymunk world while a ``PoseEKF`` tracks its
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
    of view, and no wall or obstacle blocks the line of sight
    (``info["action_mask"]``). A masked action is a no-op with reward 0 by
    default (``invalid_action="noop"``; RL algorithms and env checkers sample
    actions blindly) or raises ``ValueError`` with ``invalid_action="raise"``.
    An integer outside the space always raises ``ValueError``. ``action_masks()`` gives the mask as
    bool, for ``MaskablePPO`` (all ``True`` when no landmark is visible: every action is then the no-op).

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
    ``gym.make("infonav/LandmarkSelection-v0", render_mode=None, **config)`` with any
    key of ``default_config()``; an unknown key raises ``ValueError`` naming it.

    ## Version History
    * v0: initial version.
    """

    episode_metrics = LOCALIZATION_METRICS
    traits = EnvTraits(estimates_pose=True, rewards_information_at_once=True, reward_terms=("mutual_information",))

    @classmethod
    def default_config(cls) -> dict:
        return {
            **super().default_config(),
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

    def __init__(self, render_mode: str | None = None, **config):
        super().__init__(render_mode=render_mode, **config)
        cfg, owner = self.config, type(self).__name__
        check_choice(cfg, "scenario", scenario_names(team=False), owner)
        check_config(cfg, owner, CONFIG_INTERVALS)
        check_config_arguments(cfg, owner, "field", FIELD_ARGUMENTS, SCENARIO_KEYS)  # the corridor's speed too
        if cfg["scenario"] == "corridor" and cfg["n_candidates"] < CORRIDOR_LANDMARK_COUNT:
            raise ValueError(
                f"config key 'n_candidates' of {owner} must be >= {CORRIDOR_LANDMARK_COUNT} "
                f"(the corridor's landmarks), got {cfg['n_candidates']}"
            )
        self.sensor = range_bearing_sensor_from_config(cfg, owner)
        self.odometry = odometry_sensor_from_config(cfg, owner)
        self._odometry_covariance = self.odometry.noise_covariance()
        self.world = World()
        self.action_space = spaces.Discrete(cfg["n_candidates"])
        low, high = self._observation_bounds(cfg["n_candidates"])
        self.observation_space = spaces.Box(low, high, dtype=np.float32)

    @staticmethod
    def _observation_bounds(n_candidates: int) -> tuple[np.ndarray, np.ndarray]:
        pose_low = [-_BIG, -_BIG, -1, -1, 0, 0, 0, -1, -100, 0]
        pose_high = [_BIG, _BIG, 1, 1, _BIG, _BIG, _BIG, 1, 100, 1]
        candidate_low, candidate_high = [0, 0, -1, -1, 0], [1, _BIG, 1, 1, _BIG]
        low = np.array(pose_low + candidate_low * n_candidates, dtype=np.float32)
        high = np.array(pose_high + candidate_high * n_candidates, dtype=np.float32)
        return low, high

    def _reset_episode(self) -> None:
        scenario, prior, self._odometry_rng, self._measurement_rng = start_episode(
            self.config, self.np_random, type(self).__name__
        )
        self.ekf = PoseEKF(*prior)
        self.world.reset(scenario)
        self._true_pose = self.world.pose
        self._true_path = PathHistory(self._true_pose[:2])
        self._estimated_path = PathHistory(self.ekf.x[:2])

    def _next_decision(self) -> Decision:
        """Visible landmarks and their expected MI at the prior; the payload is their ``LandmarkSight``."""
        landmarks = None if self.config["mapping"] else self.world.landmarks
        sight = LandmarkSight.at_prior(
            self.sensor, self.world, self._true_pose, self.ekf.P, *self.ekf.landmark_measurement_model(landmarks)
        )
        candidates = sight.visible_indices
        mask = np.zeros(self.action_space.n, dtype=np.int8)
        gains = np.zeros(self.action_space.n)
        mask[candidates] = 1
        if candidates.size:
            gains[candidates] = sight.information_gains(self.ekf.P, candidates)
        return Decision(mask, gains, sight)

    def _apply_action(self, action: int | None, decision: Decision) -> dict:
        """Observe landmark ``action`` and update the EKF at the decision's prior; a no-op observes nothing."""
        if action is None:
            return {"mutual_information": 0.0}
        measurement = self.sensor.measure(self._true_pose, self.world.landmarks[action], self._measurement_rng)
        return {"mutual_information": decision.payload.observe(self.ekf, action, measurement)}

    @property
    def _pose_entropy(self) -> float:
        """Entropy of the pose estimate at the current decision's prior [nats]."""
        return self._decision.payload.pose_entropy

    def _advance(self) -> None:
        dt = self.config["time_step_s"]
        control = self.world.step(dt)[0]
        self._true_pose = self.world.pose
        odometry = self.odometry.measure(control, self._odometry_rng)
        self.ekf.predict(odometry, dt, self._odometry_covariance, check_input=False)
        self._true_path.append(self._true_pose[:2])
        self._estimated_path.append(self.ekf.x[:2])  # PathHistory copies

    def _observation(self) -> np.ndarray:
        x, y, heading = self.ekf.x[:POSE_DIM].tolist()
        P = self.ekf.P
        var_x, var_y, var_heading = P[0, 0], P[1, 1], P[2, 2]
        pose = [x, y, math.cos(heading), math.sin(heading), math.sqrt(var_x), math.sqrt(var_y), math.sqrt(var_heading)]
        pose += [P[0, 1] / math.sqrt(var_x * var_y), self._pose_entropy, self._elapsed_steps / self.config["horizon"]]
        observation = np.zeros(self.observation_space.shape, dtype=np.float32)
        observation[:POSE_FEATURES] = pose
        predicted = self._decision.payload.predicted
        n_landmarks = len(predicted)
        candidates = observation[POSE_FEATURES:].reshape(-1, CANDIDATE_FEATURES)[:n_landmarks]
        candidates[:, 0] = self._decision.action_mask[:n_landmarks]
        candidates[:, 1] = predicted[:, 0]
        candidates[:, 2] = np.cos(predicted[:, 1])
        candidates[:, 3] = np.sin(predicted[:, 1])
        if self.config["mapping"]:
            candidates[:, 4] = np.sqrt(np.diagonal(P)[POSE_DIM:].reshape(-1, 2).mean(axis=1))
        return np.clip(observation, self.observation_space.low, self.observation_space.high, out=observation)

    def _extra_info(self) -> dict:
        true_x, true_y, true_heading = self._true_pose.tolist()
        x, y, heading = self.ekf.x[:POSE_DIM].tolist()
        return {
            "pose_entropy": self._pose_entropy,
            "state_entropy": gaussian_entropy_from_log_det(self._decision.payload.prior_log_det, self.ekf.dim_x),
            "position_error_m": math.hypot(true_x - x, true_y - y),
            "heading_error_rad": abs(wrap_angle(true_heading - heading)),
            "true_pose": self._true_pose.copy(),
            "estimated_pose": self.ekf.pose,
            "time_s": self._elapsed_steps * self.config["time_step_s"],
        }

    def _scene_frame(self):
        scenario, mapping = self.world.scenario, self.config["mapping"]
        n_landmarks = len(self.world.landmarks)
        landmark_blocks = [self.ekf.P[3 + 2 * i : 5 + 2 * i, 3 + 2 * i : 5 + 2 * i] for i in range(n_landmarks)]
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            landmarks=self.world.landmarks,
            landmark_visible=self._action_mask[:n_landmarks].astype(bool),
            chosen_landmark=self._chosen_action,
            robots=[RobotDrawing.tracked(self._true_pose, self.ekf, self._true_path, self._estimated_path)],
            landmark_estimates=self.ekf.landmark_positions if mapping else None,
            landmark_covariances=np.array(landmark_blocks) if mapping else None,
            caption=f"t = {self._elapsed_steps * self.config['time_step_s']:.1f} s   "
            f"pose entropy {self._pose_entropy:.2f} nats",
        )


class Prior(NamedTuple):
    """The estimator's prior at an episode's start: ``PoseEKF(*prior)``, diagonal covariances.

    Attributes:
        pose: the initial pose estimate (3,).
        pose_covariance: its covariance (3, 3), diagonal.
        landmarks: the mapped landmarks' estimates (L, 2), None without mapping.
        landmark_variance: the variance of each of their coordinates [m^2], None without mapping.
    """

    pose: np.ndarray
    pose_covariance: np.ndarray
    landmarks: np.ndarray | None = None
    landmark_variance: float | None = None

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x, P)`` of ``PoseEKF(*prior)``: the pose then the landmarks, block-diagonal covariance."""
        if self.landmarks is None:
            return self.pose.copy(), self.pose_covariance.copy()
        x = np.concatenate([self.pose, self.landmarks.ravel()])
        variances = np.concatenate(
            [np.diagonal(self.pose_covariance), np.full(self.landmarks.size, self.landmark_variance)]
        )
        return x, np.diag(variances)


def start_episode(config: dict, np_random: np.random.Generator, owner: str):
    """Start an episode of ``LandmarkSelection-v0``: draw its scenario and the estimator's prior from ``np_random``.

    Draws in a fixed order (the scenario, the sensors' generators, the initial estimate, the mapped landmarks'
    estimates), so the single and the vector env give the same episode for the same generator.

    Args:
        config: a checked ``LandmarkSelectionEnv`` config.
        np_random: the episode's generator.
        owner: the env named in config errors.

    Returns:
        ``(scenario, prior, odometry_rng, measurement_rng)``: the scenario ``config["scenario"]`` (one route,
        <= ``n_candidates`` landmarks), the estimator's ``Prior`` and the sensors' generators.
    """
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
