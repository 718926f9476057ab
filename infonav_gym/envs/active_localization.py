"""``infonav/ActiveLocalization-v0``: drive to a goal, choosing how to move and what to observe under a budget."""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from infonav_gym.config import Interval, check_config, check_config_arguments
from infonav_gym.envs.active_planning import (
    N_PRIMITIVES,
    PRIMITIVE_OFFSETS_RAD,
    ActivePlanningModel,
)
from infonav_gym.envs.base import MAX_EPISODE_STEPS, Decision, InfoNavEnv
from infonav_gym.envs.landmark_selection import Prior
from infonav_gym.envs.landmark_sight import LandmarkSight
from infonav_gym.envs.metrics import LOCALIZATION_METRICS, SUCCESS_RATE
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.estimation.ekf import INITIAL_POSE_STD, POSE_DIM, PoseEKF
from infonav_gym.estimation.models import range_bearing, range_bearing_linearized
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import largest_position_std
from infonav_gym.scene import PathHistory, RobotDrawing, SceneFrame
from infonav_gym.sensors.odometry import odometry_sensor_from_config
from infonav_gym.sensors.range_bearing import range_bearing_sensor_from_config
from infonav_gym.world.active_scenarios import GOAL_FIELD_ARGUMENTS, CommandedWorld, goal_field
from infonav_gym.world.scenarios import SPEED_MPS, Scenario
from infonav_gym.world.world import TIME_STEP_S, start_poses

POSE_FEATURES = 10
GOAL_FEATURES = 4
LANDMARK_FEATURES = 4
OBSTACLE_FEATURES = 4
REWARD_TERMS = ("mutual_information", "sensing_cost", "motion_cost", "progress", "goal_bonus", "failure_penalty")
_BIG = 1e4
REWARD_WEIGHT = Interval(0.0, 1e6)  # a cost, reward or bonus weight [nats, or nats per unit]
REWARD_WEIGHT_KEYS = (
    "observation_cost_nats",
    "motion_cost_per_step",
    "progress_reward_per_m",
    "goal_bonus",
    "failure_penalty",
)
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "time_step_s": TIME_STEP_S,
    "speed_mps": SPEED_MPS,
    "max_turn_rate_rps": Interval(0.0, 10.0, open_low=True, unit="rad/s"),
    "goal_radius_m": Interval(0.0, 100.0, open_low=True, unit="m"),
    "max_position_std_m": Interval(0.0, 1000.0, open_low=True, unit="m"),  # and above initial_position_std_m
    "max_observations": Interval(0, MAX_EPISODE_STEPS, integer=True),
    **INITIAL_POSE_STD,
    **{key: REWARD_WEIGHT for key in REWARD_WEIGHT_KEYS},
}


class ActiveLocalizationEnv(ActivePlanningModel, InfoNavEnv):
    """Drive a robot to a goal, deciding each step how to move and which landmark (if any) to observe.

    ## Description
    A robot crosses a square field (``goal_field``) from a start on the left to a goal
    on the right, tracking its pose with a ``PoseEKF`` from noisy odometry. Landmarks
    light only parts of the way: two ahead of the start, one before the goal, and the
    rest along one side of the middle, farther from the straight line than the sensor
    reaches; round obstacles on the other side hide some of them. Each step the agent
    observes one visible landmark (a range-bearing update) or nothing, then drives one
    motion primitive. Observations are limited (``max_observations``) and cost
    ``observation_cost_nats`` each. Drifting too far from certainty ends the episode, so
    a myopic agent that spends its budget where landmarks are plentiful, or drives
    straight through the dark middle, may be left blind: this is where planning ahead
    pays.

    The observation is taken at the start of the step, at the EKF's predicted prior, and
    the motion follows. ``info["action_information_gain"][a]`` is therefore the exact
    mutual information action ``a`` brings (the posterior covariance does not depend on
    the measured value), and ``info["action_mask"]`` shows what is visible from the true
    pose, as for ``LandmarkSelection-v0``.

    ## Action Space
    ``Discrete(5 * (1 + n_candidates))``; action ``a`` is observation slot ``a // 5``
    (0: observe nothing, ``j + 1``: observe landmark ``j``) and primitive ``a % 5``.
    The primitives steer, on the *estimated* pose, for a heading relative to the
    estimated bearing of the goal: ``to_goal`` (0), ``veer_left`` / ``veer_right``
    (+-45 deg) and ``sidestep_left`` / ``sidestep_right`` (+-90 deg); the turn rate is
    limited to ``max_turn_rate_rps`` and the speed is ``speed_mps * max(cos(turn), 0)``
    for the heading change still to make. Pymunk executes the motion. Observing
    landmark ``j`` is valid while it lies within range and field of view, no obstacle
    hides it, and budget is left; observing nothing is always valid. A masked action
    is a no-op (stand still, observe nothing) by default (``invalid_action="noop"``) or
    raises ``ValueError`` with ``invalid_action="raise"``. ``action_masks()`` gives the mask as bool,
    for ``MaskablePPO``.

    ## Observation Space
    ``Box(float32, (14 + 4 * n_candidates + 4 * n_obstacles,))``: the 10 pose features
    of ``LandmarkSelection-v0`` (estimated ``x, y`` [m], ``cos, sin`` of the heading,
    standard deviations of ``x, y`` [m] and heading [rad], ``x-y`` correlation, pose
    entropy [nats], elapsed fraction of the horizon); the estimated distance to the goal
    [m], ``cos, sin`` of its estimated bearing, and the fraction of the sensing budget
    left; per landmark: visible flag, estimated range [m], ``cos, sin`` of the estimated
    bearing; per obstacle: estimated range to its centre [m], ``cos, sin`` of its
    bearing, radius [m] (the map is known).

    ## Rewards
    ``info["reward_terms"]``, summed: ``mutual_information`` of the update [nats];
    ``sensing_cost`` ``-observation_cost_nats`` per observation; ``motion_cost``
    ``-motion_cost_per_step`` per primitive executed (driving or turning); ``progress`` ``progress_reward_per_m``
    per metre the true distance to the goal shrank; ``goal_bonus`` on reaching the goal;
    ``failure_penalty`` ``-failure_penalty`` when the uncertainty bound is crossed. A
    no-op earns 0 unless the uncertainty crosses the bound meanwhile.

    ## Starting State
    At the scenario's start, facing the goal; the estimate is drawn from
    ``N(true pose, diag(initial_position_std_m^2, ..., initial_heading_std_rad^2))``.

    ## Episode End
    Terminated when the true position comes within ``goal_radius_m`` of the goal
    (success, ``info["goal_reached"]`` and ``info["success"]``), or when the largest position standard deviation
    of the estimate exceeds ``max_position_std_m`` (failure, ``info["failed"]``).
    Truncated after ``horizon`` steps.

    ## Planning model
    ``planning_model()`` returns the env's own model for look-ahead agents
    (``agents.planner.PlannerAgent``), with ``belief()``, ``plan_decision(belief)`` and
    ``plan_step(belief, actions)``: the EKF covariance propagated under the linearization, with
    the motion predicted from the estimated pose and visibility judged from it.

    ## Arguments
    ``gym.make("infonav/ActiveLocalization-v0", render_mode=None, **config)`` with any
    key of ``default_config()``; an unknown key raises ``ValueError`` naming it.

    ## Version History
    * v0: initial version.
    """

    episode_metrics = (*LOCALIZATION_METRICS, SUCCESS_RATE)
    traits = EnvTraits(
        estimates_pose=True,
        reports_success=True,
        may_terminate=True,
        idle_actions=frozenset(range(N_PRIMITIVES)),  # the primitives without an observation
        reward_terms=REWARD_TERMS,
        info_keys=frozenset(
            {"goal", "goal_reached", "failed", "success", "observations_left", "distance_to_goal_m", "position_std_m"}
        ),
    )

    @classmethod
    def default_config(cls) -> dict:
        return {
            **super().default_config(),
            "horizon": 100,  # [steps]
            "n_candidates": 8,  # number of landmarks K (>= 4)
            "n_obstacles": 4,
            "field_size_m": 40.0,  # side of the square field [m]
            "time_step_s": 1.0,  # [s]
            "speed_mps": 1.0,  # cruise speed [m/s]
            "max_turn_rate_rps": 1.0,  # [rad/s]
            "goal_radius_m": 1.5,  # the goal is reached within this distance [m]
            "max_observations": 12,  # sensing budget per episode
            "observation_cost_nats": 0.1,  # cost of one observation [nats]
            "motion_cost_per_step": 0.1,  # cost of executing a primitive for one step, driving or turning [nats]
            "progress_reward_per_m": 0.1,  # reward per metre of progress toward the goal [nats/m]
            "goal_bonus": 10.0,  # [nats]
            "failure_penalty": 10.0,  # [nats], subtracted
            "max_position_std_m": 1.0,  # failure bound on the largest position std [m]
            "range_std_m": 0.1,  # [m]
            "range_std_per_m": 0.01,  # [m/m]
            "bearing_std_rad": math.radians(2.0),  # [rad]
            "sensor_max_range_m": 6.0,  # [m]
            "sensor_fov_rad": math.pi,  # [rad]
            "odometry_speed_std_mps": 0.05,  # [m/s]
            "odometry_turn_rate_std_rps": 0.02,  # [rad/s]
            "initial_position_std_m": 0.1,  # [m]
            "initial_heading_std_rad": 0.02,  # [rad]
        }

    def __init__(self, render_mode: str | None = None, **config):
        super().__init__(render_mode=render_mode, **config)
        cfg, owner = self.config, type(self).__name__
        field_keys = {"n_landmarks": "n_candidates", "n_obstacles": "n_obstacles", "size_m": "field_size_m"}
        check_config_arguments(cfg, owner, "goal_field", GOAL_FIELD_ARGUMENTS, field_keys)
        check_config(cfg, owner, CONFIG_INTERVALS)
        if cfg["max_position_std_m"] <= cfg["initial_position_std_m"]:
            raise ValueError(
                f"config key 'max_position_std_m' of {owner} must exceed initial_position_std_m "
                f"({cfg['initial_position_std_m']}), got {cfg['max_position_std_m']}"
            )
        self.sensor = range_bearing_sensor_from_config(cfg, owner)
        self.odometry = odometry_sensor_from_config(cfg, owner)
        self._odometry_covariance = self.odometry.noise_covariance()
        self.world = CommandedWorld()
        self.n_primitives = N_PRIMITIVES
        self.n_slots = 1 + cfg["n_candidates"]
        self.action_space = spaces.Discrete(N_PRIMITIVES * self.n_slots)
        low, high = self._observation_bounds(cfg["n_candidates"], cfg["n_obstacles"])
        self.observation_space = spaces.Box(low, high, dtype=np.float32)

    @staticmethod
    def _observation_bounds(n_landmarks: int, n_obstacles: int) -> tuple[np.ndarray, np.ndarray]:
        low = [-_BIG, -_BIG, -1, -1, 0, 0, 0, -1, -100, 0] + [0, -1, -1, 0]
        high = [_BIG, _BIG, 1, 1, _BIG, _BIG, _BIG, 1, 100, 1] + [_BIG, 1, 1, 1]
        low += [0, 0, -1, -1] * n_landmarks + [0, -1, -1, 0] * n_obstacles
        high += [1, _BIG, 1, 1] * n_landmarks + [_BIG, 1, 1, _BIG] * n_obstacles
        return np.array(low, dtype=np.float32), np.array(high, dtype=np.float32)

    @staticmethod
    def decode_action(action: int) -> tuple[int | None, int]:
        """``(landmark or None, primitive)`` of an action index."""
        slot, primitive = divmod(int(action), N_PRIMITIVES)
        return (slot - 1 if slot else None), primitive

    # ------------------------------------------------------------------ the episode

    def _reset_episode(self) -> None:
        scenario, prior, self._odometry_rng, self._measurement_rng = start_episode(self.config, self.np_random)
        self.world.reset(scenario)
        self.ekf = PoseEKF(*prior)
        self.goal = episode_goal(scenario)
        self._obstacle_centers, self._obstacle_radii = obstacle_discs(scenario)
        self._true_pose = self.world.pose
        self.observations_left = self.config["max_observations"]
        self.goal_reached = self.failed = False
        self._true_path = PathHistory(self._true_pose[:2])
        self._estimated_path = PathHistory(self.ekf.x[:2])

    def _next_decision(self) -> Decision:
        """Every primitive with no observation or with a visible landmark while budget is left, gains at the prior.

        The payload is the landmarks' ``LandmarkSight`` (its model linearized at the estimated pose).
        """
        predicted, H, _ = range_bearing_linearized(self.ekf.x, self.world.landmarks)
        sight = LandmarkSight.at_prior(self.sensor, self.world, self._true_pose, self.ekf.P, predicted, H)
        mask = np.zeros((self.n_slots, N_PRIMITIVES), dtype=np.int8)
        gains = np.zeros((self.n_slots, N_PRIMITIVES))
        mask[0] = 1
        observable = sight.visible_indices if self.observations_left > 0 else np.zeros(0, dtype=int)
        mask[1 + observable] = 1
        if observable.size:
            gains[1 + observable] = sight.information_gains(self.ekf.P, observable)[:, None]
        return Decision(mask.ravel(), gains.ravel(), sight)

    @property
    def _visible(self) -> np.ndarray:
        """Which landmarks the sensor sees at the current decision (K,) bool."""
        return self._decision.payload.visible

    @property
    def _pose_entropy(self) -> float:
        """Entropy of the pose estimate at the current decision's prior [nats]."""
        return self._decision.payload.pose_entropy

    def _apply_action(self, action: int | None, decision: Decision) -> dict:
        """The whole transition: observe (at the prior), then drive; a no-op stands still observing nothing."""
        cfg = self.config
        terms = dict.fromkeys(REWARD_TERMS, 0.0)
        landmark, primitive = (None, None) if action is None else self.decode_action(action)
        if landmark is not None:
            measurement = self.sensor.measure(self._true_pose, self.world.landmarks[landmark], self._measurement_rng)
            terms["mutual_information"] = decision.payload.observe(self.ekf, landmark, measurement)
            terms["sensing_cost"] = -cfg["observation_cost_nats"]
            self.observations_left -= 1
        speed, turn_rate = (0.0, 0.0) if primitive is None else self._commands(self.ekf.x[None], [primitive])[0]
        distance_before = math.dist(self._true_pose[:2], self.goal)
        self.world.command(speed, turn_rate)
        dt = cfg["time_step_s"]
        control = self.world.step(dt)[0]
        self._true_pose = self.world.pose
        odometry = self.odometry.measure(control, self._odometry_rng)
        self.ekf.predict(odometry, dt, self._odometry_covariance, check_input=False)
        if primitive is not None:
            terms["motion_cost"] = -cfg["motion_cost_per_step"]
            terms["progress"] = cfg["progress_reward_per_m"] * (
                distance_before - math.dist(self._true_pose[:2], self.goal)
            )
        self.goal_reached = bool(math.dist(self._true_pose[:2], self.goal) <= cfg["goal_radius_m"])
        self.failed = (
            not self.goal_reached and float(self.position_std(self.ekf.P[None])[0]) > cfg["max_position_std_m"]
        )
        terms["goal_bonus"] = cfg["goal_bonus"] if self.goal_reached else 0.0
        terms["failure_penalty"] = -cfg["failure_penalty"] if self.failed else 0.0
        return terms

    def _advance(self) -> None:
        self._true_path.append(self._true_pose[:2])
        self._estimated_path.append(self.ekf.x[:2])  # PathHistory copies

    def _is_terminated(self) -> bool:
        return self.goal_reached or self.failed

    position_std = staticmethod(largest_position_std)  # the planning model's, on (B, 3, 3) covariances

    def _commands(self, poses: np.ndarray, primitives) -> np.ndarray:
        """``[speed, turn rate]`` (B, 2) that each primitive commands from each estimated pose (B, 3)."""
        return primitive_commands(self.config, self.goal, poses, primitives)

    # ------------------------------------------------------------------ observation and info

    def _observation(self) -> np.ndarray:
        x, y, heading = self.ekf.x.tolist()
        P = self.ekf.P
        var_x, var_y, var_heading = P[0, 0], P[1, 1], P[2, 2]
        goal_range, goal_bearing = range_bearing(self.ekf.x, self.goal)[0]
        budget = self.config["max_observations"]
        features = [x, y, math.cos(heading), math.sin(heading), math.sqrt(var_x), math.sqrt(var_y)]
        features += [math.sqrt(var_heading), P[0, 1] / math.sqrt(var_x * var_y), self._pose_entropy]
        features += [self._elapsed_steps / self.config["horizon"], goal_range, math.cos(goal_bearing)]
        features += [math.sin(goal_bearing), self.observations_left / budget if budget else 0.0]
        predicted = self._decision.payload.predicted
        landmarks = np.column_stack([self._visible, predicted[:, 0], np.cos(predicted[:, 1]), np.sin(predicted[:, 1])])
        obstacles = np.zeros((len(self._obstacle_radii), OBSTACLE_FEATURES))
        if len(obstacles):
            seen = range_bearing(self.ekf.x, self._obstacle_centers)
            obstacles[:] = np.column_stack([seen[:, 0], np.cos(seen[:, 1]), np.sin(seen[:, 1]), self._obstacle_radii])
        observation = np.concatenate([features, landmarks.ravel(), obstacles.ravel()]).astype(np.float32)
        return np.clip(observation, self.observation_space.low, self.observation_space.high, out=observation)

    def _extra_info(self) -> dict:
        true_x, true_y, true_heading = self._true_pose.tolist()
        x, y, heading = self.ekf.x.tolist()
        return {
            "pose_entropy": self._pose_entropy,
            "state_entropy": self._pose_entropy,
            "position_error_m": math.hypot(true_x - x, true_y - y),
            "heading_error_rad": abs(wrap_angle(true_heading - heading)),
            "position_std_m": float(self.position_std(self.ekf.P[None])[0]),
            "true_pose": self._true_pose.copy(),
            "estimated_pose": self.ekf.pose,
            "goal": self.goal.copy(),
            "distance_to_goal_m": math.dist(self._true_pose[:2], self.goal),
            "observations_left": self.observations_left,
            "goal_reached": self.goal_reached,
            "success": self.goal_reached,  # the evaluation harness's success flag
            "failed": self.failed,
            "time_s": self._elapsed_steps * self.config["time_step_s"],
        }

    def _scene_frame(self):
        scenario = self.world.scenario
        landmark = None if self._chosen_action is None else self.decode_action(self._chosen_action)[0]
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            landmarks=self.world.landmarks,
            landmark_visible=self._visible,
            chosen_landmark=landmark,
            robots=[RobotDrawing.tracked(self._true_pose, self.ekf, self._true_path, self._estimated_path)],
            goal=tuple(self.goal),
            goal_radius_m=self.config["goal_radius_m"],
            caption=f"t = {self._elapsed_steps * self.config['time_step_s']:.0f} s   "
            f"goal ({self.goal[0]:.0f}, {self.goal[1]:.0f}) m, {self.observations_left} observations left",
        )


def start_episode(config: dict, np_random: np.random.Generator):
    """Start an episode of ``ActiveLocalization-v0``: draw its goal field and the estimator's prior from ``np_random``.

    Draws in a fixed order (the field, the sensors' generators, the initial estimate), so the single and the
    vector env give the same episode for the same generator.

    Args:
        config: a checked ``ActiveLocalizationEnv`` config.
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


def primitive_commands(config: dict, goals: np.ndarray, poses: np.ndarray, primitives) -> np.ndarray:
    """``[speed, turn rate]`` (B, 2) that each motion primitive commands from each estimated pose.

    Args:
        config: a checked ``ActiveLocalizationEnv`` config.
        goals: the goal position [m], one (2,) for all poses or one per pose (B, 2).
        poses: estimated poses ``[x, y, heading]`` (B, 3).
        primitives: the primitive of each pose (B,), indices of ``PRIMITIVE_OFFSETS_RAD``.
    """
    goals = np.asarray(goals)
    goal_bearing = np.arctan2(goals[..., 1] - poses[:, 1], goals[..., 0] - poses[:, 0])
    desired = goal_bearing + np.take(PRIMITIVE_OFFSETS_RAD, primitives)
    turn = wrap_angle(desired - poses[:, 2])
    max_turn = config["max_turn_rate_rps"] * config["time_step_s"]
    executed_turn = np.clip(turn, -max_turn, max_turn)
    speed = config["speed_mps"] * np.maximum(np.cos(turn), 0.0)
    return np.stack([speed, executed_turn / config["time_step_s"]], axis=-1)
