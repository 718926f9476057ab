"""``infonav/ActiveLocalization-v0``: drive to a goal, choosing how to move and what to observe under a budget, as
a scenario (its step in ``transition.py``, shared with its planning model)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from infonav_gym.config import Interval, check_config, check_config_arguments
from infonav_gym.envs.active_localization.planning import ActivePlanningModel, Belief
from infonav_gym.envs.active_localization.transition import (
    N_PRIMITIVES,
    REWARD_TERMS,
    REWARD_WEIGHT_KEYS,
    decode_actions,
    field_geometry,
    observation_bounds,
    outputs_of_copies,
    primitive_commands,
    start_episodes,
    step_rewards,
)
from infonav_gym.envs.base import MAX_EPISODE_STEPS, REWARD_WEIGHT, shared_config
from infonav_gym.envs.landmark_decision import LandmarkDecision
from infonav_gym.envs.metrics import LOCALIZATION_METRICS, SUCCESS_RATE
from infonav_gym.envs.one_robot import OneRobotDriver, OneRobotScenario, OneRobotState
from infonav_gym.envs.single_view import SingleEnvView
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.envs.vector_infos import decision_info
from infonav_gym.estimation.state import INITIAL_POSE_STD, POSE_DIM
from infonav_gym.scene import SceneFrame
from infonav_gym.sensors.odometry import odometry_sensor_from_config
from infonav_gym.sensors.range_bearing import range_bearing_sensor_from_config
from infonav_gym.world.active_scenarios import GOAL_FIELD_ARGUMENTS
from infonav_gym.world.physics import TIME_STEP_S
from infonav_gym.world.scenarios import SPEED_MPS

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
FIELD_KEYS = {"n_landmarks": "n_candidates", "n_obstacles": "n_obstacles", "size_m": "field_size_m"}


@dataclass
class ActiveState(OneRobotState):
    """``OneRobotState`` (every landmark ``exists``) and each copy's goal (N, 2) [m], sensing budget left (N,),
    whether it reached the goal or failed (N,), its round obstacles (centres (N, O, 2), radii (N, O) [m]: the map the
    agent knows) and what its last step brought: the reward terms (6, N) and their totals (N,) [nats]."""

    goals: np.ndarray = None
    observations_left: np.ndarray = None
    goal_reached: np.ndarray = None
    failed: np.ndarray = None
    obstacle_centers: np.ndarray = None
    obstacle_radii: np.ndarray = None
    terms: np.ndarray = None
    rewards: np.ndarray = None


STEP_FIELDS = ("action_mask", "action_information_gain", "visible", "landmark_gains", *LandmarkDecision._fields[2:])


class ActiveStep(NamedTuple("ActiveStep", [(name, np.ndarray) for name in (*STEP_FIELDS, "observation", "numbers")])):
    """Every copy's action mask and gains (n, 5 (1 + K)), its landmarks' ``LandmarkDecision`` (its mask and gains
    named ``visible``, ``landmark_gains``) at its EKF's prior, and what ``outputs_of_copies`` computes:
    observations and info ``numbers``."""


class ActiveLocalization(OneRobotScenario):
    """``infonav/ActiveLocalization-v0`` as a scenario (spaces, rewards, config: ``ActiveLocalizationEnv``)."""

    episode_metrics = (*LOCALIZATION_METRICS, SUCCESS_RATE)
    traits = EnvTraits(
        kb_per_copy=40,  # [kB] at the defaults, between peak RSS growth and traced allocations
        estimates_pose=True,
        reports_success=True,
        may_terminate=True,
        idle_actions=frozenset(range(N_PRIMITIVES)),  # the primitives without an observation
        reward_terms=REWARD_TERMS,
        main_metric="success_rate",
        info_keys=frozenset(
            {"goal", "goal_reached", "failed", "success", "observations_left", "distance_to_goal_m", "position_std_m"}
        ),
    )

    @classmethod
    def default_config(cls) -> dict:
        return {
            **shared_config(),
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

    def __init__(self, config: dict, copies: int, owner: str, render_mode: str | None):
        super().__init__(config, copies, owner, render_mode)
        cfg = config
        check_config_arguments(cfg, owner, "goal_field", GOAL_FIELD_ARGUMENTS, FIELD_KEYS)
        check_config(cfg, owner, CONFIG_INTERVALS)
        if cfg["max_position_std_m"] <= cfg["initial_position_std_m"]:
            raise ValueError(
                f"config key 'max_position_std_m' of {owner} must exceed initial_position_std_m "
                f"({cfg['initial_position_std_m']}), got {cfg['max_position_std_m']}"
            )
        self.use_observation_bounds(*observation_bounds(cfg["n_candidates"], cfg["n_obstacles"]))
        self.action_space = spaces.Discrete(N_PRIMITIVES * (1 + cfg["n_candidates"]))
        self.use_sensors(range_bearing_sensor_from_config(cfg, owner), odometry_sensor_from_config(cfg, owner))

    def allocate(self, copies: int) -> ActiveState:
        cfg = self.config
        fields = self.robot_fields(copies, cfg["n_candidates"])
        fields["exists"][:] = True
        return ActiveState(
            **{**fields, "x": np.zeros((copies, POSE_DIM)), "P": np.zeros((copies, POSE_DIM, POSE_DIM))},
            goals=np.zeros((copies, 2)),
            observations_left=np.zeros(copies, dtype=int),
            **{name: np.zeros(copies, dtype=bool) for name in ("goal_reached", "failed")},
            obstacle_centers=np.zeros((copies, cfg["n_obstacles"], 2)),
            obstacle_radii=np.zeros((copies, cfg["n_obstacles"])),
            terms=np.zeros((len(REWARD_TERMS), copies)),
            rewards=np.zeros(copies),
        )

    def initial(self, state: ActiveState, rows: np.ndarray, rngs: list) -> ActiveState:
        """Draw each copy's goal field and prior (``start_episodes``); its static geometry joins the state's."""
        starts = start_episodes(self.config, rngs)
        generators = starts.sensor_generators
        for copy, scenario, (odometry_rng, measurement_rng) in zip(rows.tolist(), starts.scenarios, generators):
            state.worlds.reset_copy(copy, scenario)
            state.odometry_noise.restart(copy, odometry_rng)
            state.measurement_noise.restart(copy, measurement_rng)
        layouts = starts.layouts
        state.x[rows], state.P[rows] = starts.poses, starts.pose_covariance
        state.goals[rows], state.landmarks[rows] = layouts.goals, layouts.landmarks
        obstacles = (layouts.obstacle_centers, layouts.obstacle_radii)
        state.obstacle_centers[rows], state.obstacle_radii[rows] = obstacles
        state.observations_left[rows] = self.config["max_observations"]
        state.goal_reached[rows] = state.failed[rows] = False
        state.chosen[rows], state.terms[:, rows], state.rewards[rows] = -1, 0.0, 0.0
        geometry = field_geometry(starts.scenarios[0].walls, state.worlds.wall_thickness_m, *obstacles)
        everyone = len(rows) == len(state.elapsed)
        state.geometry = geometry if everyone else state.geometry.with_copies(rows, geometry)
        if rows[0] == 0:
            self.follow_first_copy(state, restarted=True)
        return state

    def decision(self, state: ActiveState, rows) -> ActiveStep:
        """The landmarks each copy sees and their models at its prior, the action layout, its observation and info
        numbers (``outputs_of_copies``)."""
        if isinstance(rows, slice):
            geometry = state.geometry
        else:
            walls = state.worlds.scenario(int(rows[0])).walls
            centers, radii = state.obstacle_centers[rows], state.obstacle_radii[rows]
            geometry = field_geometry(walls, state.worlds.wall_thickness_m, centers, radii)
        x, P, true_poses = state.x[rows], state.P[rows], state.worlds.poses[rows, 0]
        sight = LandmarkDecision.at_prior(
            self.sensor, geometry, true_poses, x, P, state.landmarks[rows], state.exists[rows], False, self.threads
        )
        obstacles = (state.obstacle_centers[rows], state.obstacle_radii[rows])
        arrays = (x, P, true_poses, state.goals[rows], state.elapsed[rows], state.observations_left[rows], *obstacles)
        landmarks = sight.action_mask, sight.action_information_gain, sight.predicted, sight.pose_entropy
        shared = (self.config["horizon"], self.config["max_observations"], *self.bounds)
        action_mask, gains, *outputs = self.threads.map_rows(outputs_of_copies, len(x), (*landmarks, *arrays), shared)
        return ActiveStep(action_mask, gains, *sight, *outputs)

    def transition(self, state: ActiveState, decision: ActiveStep, action, acting) -> ActiveState:
        """Observe the chosen landmarks at the prior, then drive the ``acting`` copies' primitives; the step's
        reward terms, totals and outcome stay in the state. A no-op (-1) stands still observing nothing."""
        chosen = action[:, 0]
        landmarks, primitives = decode_actions(chosen)
        driving = chosen >= 0  # -1: a no-op, or a copy not acting
        landmarks[~driving] = primitives[~driving] = -1
        state.x, state.P, mutual_information = self.measured(state, decision, landmarks)
        observed = landmarks >= 0
        state.observations_left -= observed
        copies, before = np.flatnonzero(acting), state.worlds.poses[:, 0, :2].copy()
        if copies.size:
            rows = slice(None) if len(copies) == len(acting) else copies
            commands = primitive_commands(self.config, state.goals[rows], state.x[rows], primitives[rows])
            state.worlds.static_geometry = state.geometry  # its contact test grows the geometry kept there
            state.x[rows], state.P[rows] = self.moved(state, copies, state.x[rows], state.P[rows], commands)
        after, arrays = state.worlds.poses[:, 0, :2], (state.goals, state.P, mutual_information, observed, driving)
        state.terms, state.rewards, reached, failed = step_rewards(self.config, before, after, *arrays, acting)
        np.copyto(state.goal_reached, reached, where=acting)
        np.copyto(state.failed, failed, where=acting)
        state.chosen = chosen
        if acting[0]:
            self.follow_first_copy(state, restarted=False)
        return state

    def reward(self, decision, action, state: ActiveState) -> np.ndarray:
        """The sum of each copy's reward terms (``step_rewards``) [nats] (0 without a step)."""
        return state.rewards.copy()

    def terminal(self, state: ActiveState) -> np.ndarray:
        """The copies that reached their goal or crossed the uncertainty bound."""
        return state.goal_reached | state.failed

    def observation(self, state: ActiveState, decision: ActiveStep, rows) -> np.ndarray:
        return decision.observation

    def info(self, state: ActiveState, decision: ActiveStep, rows, stepped) -> dict:
        """The decision's mask and gains, the six reward terms, the action taken, the errors, the goal and outcome."""
        position_error, heading_error, position_std, distance_to_goal = decision.numbers.T
        goal_reached = state.goal_reached[rows]
        info = decision_info(decision, stepped, state.chosen[rows], REWARD_TERMS, state.terms[:, rows])
        info.update(
            pose_entropy=decision.pose_entropy.copy(),
            state_entropy=decision.pose_entropy.copy(),
            position_error_m=position_error,
            heading_error_rad=heading_error,
            position_std_m=position_std,
            true_pose=state.worlds.poses[rows, 0].copy(),
            estimated_pose=state.x[rows, :POSE_DIM].copy(),
            goal=state.goals[rows].copy(),
            distance_to_goal_m=distance_to_goal,
            observations_left=state.observations_left[rows].copy(),
            goal_reached=goal_reached.copy(),
            success=goal_reached.copy(),  # the evaluation harness's success flag
            failed=state.failed[rows].copy(),
            time_s=state.elapsed[rows] * self.config["time_step_s"],
        )
        return info

    def frame(self, state: ActiveState, decision: ActiveStep):
        """Copy 0 drawn: its field, landmarks (visible ones marked, the observed one linked), goal and robot."""
        scenario, goal = state.worlds.scenario(0), state.goals[0]
        landmark = int(decode_actions(state.chosen[:1])[0][0]) if state.chosen[0] >= 0 else -1
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            landmarks=state.landmarks[0].copy(),
            landmark_visible=decision.visible[0].astype(bool),
            chosen_landmark=None if landmark < 0 else landmark,
            robots=[self.first_robot_drawing(state)],
            goal=tuple(goal),
            goal_radius_m=self.config["goal_radius_m"],
            caption=f"t = {state.elapsed[0] * self.config['time_step_s']:.0f} s   "
            f"goal ({goal[0]:.0f}, {goal[1]:.0f}) m, {state.observations_left[0]} observations left",
        )


class ActiveLocalizationVectorEnv(OneRobotDriver, scenario=ActiveLocalization):
    """N copies of ``infonav/ActiveLocalization-v0``, the driver bound to its scenario (``gym.make_vec``).

    Observations (N, 14 + 4K + 4O), ``info["action_mask"]`` (N, 5 (1 + K)), all six reward terms;
    ``planning_model(copy)`` is sub-env ``copy``'s planning model.
    """

    def planning_model(self, copy: int = 0) -> ActivePlanningModel:
        """The planning model of sub-env ``copy`` (the same object on every call), for look-ahead agents
        (``agents.planner.PlannerAgent``)."""
        models = self.__dict__.setdefault("_planning_models", {})
        if copy not in models:
            models[copy] = ActivePlanningModel(self, copy)
        return models[copy]

    @property
    def odometry_covariance(self) -> np.ndarray:
        """The covariance of the odometry's ``[speed, turn rate]`` readings (2, 2)."""
        return self.env_scenario.odometry_covariance

    def episode_goal(self, copy: int = 0) -> np.ndarray:
        """Sub-env ``copy``'s goal position [m] (2,), a view."""
        return self.state.goals[copy]

    def episode_landmarks(self, copy: int = 0) -> np.ndarray:
        """Sub-env ``copy``'s landmark positions [m] (K, 2), a view."""
        return self.state.landmarks[copy]

    def episode_obstacles(self, copy: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Sub-env ``copy``'s round obstacles: centres (O, 2) [m] and radii (O,) [m] (the map the agent knows)."""
        return self.state.obstacle_centers[copy], self.state.obstacle_radii[copy]

    def belief(self, copy: int = 0) -> Belief:
        """Sub-env ``copy``'s estimator state at its current decision as a batch of one (visibility: from the true
        pose, as ``info["action_mask"]``)."""
        if self.decision is None:
            raise RuntimeError(f"{self.owner_name}: call reset() before belief()")
        state, rows = self.state, slice(copy, copy + 1)
        return Belief(
            pose=state.x[rows].copy(),
            covariance=state.P[rows].copy(),
            observations_left=state.observations_left[rows].copy(),
            visible=self.decision.visible[rows].astype(bool),
            done=state.goal_reached[rows] | state.failed[rows],
        )


class ActiveLocalizationEnv(SingleEnvView, vector_env=ActiveLocalizationVectorEnv):
    """Drive a robot to a goal, deciding each step how to move and which landmark (if any) to observe.

    ## Description
    A robot crosses a square field (``goal_field``) from a start on the left to a goal
    on the right, tracking its pose with an EKF from noisy odometry. Landmarks
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
    hides it, and budget is left; observing nothing is always valid. The no-op of a masked action
    stands still and observes nothing.

    ## Observation Space
    ``Box(float32, (14 + 4 * n_candidates + 4 * n_obstacles,))``: the 10 pose features
    of ``LandmarkSelection-v0``; the estimated distance to the goal
    [m], ``cos, sin`` of its estimated bearing, and the fraction of the sensing budget
    left; per landmark: visible flag, estimated range [m], ``cos, sin`` of the estimated
    bearing; per obstacle: estimated range to its centre [m], ``cos, sin`` of its
    bearing, radius [m] (the map is known).

    ## Rewards
    the terms at ``info["reward_" + term]``, summed: ``mutual_information`` of the update [nats];
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
    ``planning_model()`` (``env.get_wrapper_attr("planning_model")()`` through wrappers) is the env's batched
    step (``transition.py``) on beliefs, for look-ahead agents (``PlannerAgent``): the EKF covariance propagated
    under the linearization, the motion predicted from the estimated pose and visibility judged from it.

    ## Arguments
    ``gym.make("infonav/ActiveLocalization-v0", render_mode=None, **config)`` with any key of ``default_config()``.

    ## Version History
    * v0: initial version.
    """
