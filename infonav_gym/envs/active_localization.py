"""``infonav/ActiveLocalization-v0``: drive to a goal, choosing how to move and what to observe under a budget.

Written once, on (N, ...) arrays: ``ActiveLocalizationVectorEnv`` is the env (``gym.make_vec``), its one step in
``envs.active_transition`` (shared with its planning model, ``envs.active_planning``); ``ActiveLocalizationEnv``
is its N = 1 view (``gym.make``).
"""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from infonav_gym.config import Interval, check_config, check_config_arguments
from infonav_gym.envs.active_planning import ActivePlanningModel, Belief
from infonav_gym.envs.active_transition import (
    N_PRIMITIVES,
    PRIMITIVE_NAMES,
    PRIMITIVE_OFFSETS_RAD,
    REWARD_TERMS,
    copy_outputs,
    decode_actions,
    field_geometry,
    observation_bounds,
    primitive_commands,
    start_episode,
    start_episodes,
    step_rewards,
)
from infonav_gym.envs.base import MAX_EPISODE_STEPS, REWARD_WEIGHT
from infonav_gym.envs.landmark_decision import LandmarkDecision
from infonav_gym.envs.metrics import LOCALIZATION_METRICS, SUCCESS_RATE
from infonav_gym.envs.one_robot_vector import OneRobotVectorEnv
from infonav_gym.envs.single_view import SingleEnvView
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.envs.vector_infos import in_every_copy, set_rows
from infonav_gym.estimation.state import INITIAL_POSE_STD, POSE_DIM
from infonav_gym.scene import SceneFrame
from infonav_gym.sensors.odometry import odometry_sensor_from_config
from infonav_gym.sensors.range_bearing import range_bearing_sensor_from_config
from infonav_gym.world.active_scenarios import GOAL_FIELD_ARGUMENTS
from infonav_gym.world.physics import TIME_STEP_S
from infonav_gym.world.scenarios import SPEED_MPS
from infonav_gym.world.visibility import StaticGeometry

__all__ = [
    "N_PRIMITIVES",
    "PRIMITIVE_NAMES",
    "PRIMITIVE_OFFSETS_RAD",
    "REWARD_TERMS",
    "REWARD_WEIGHT",
    "ActiveLocalizationEnv",
    "ActiveLocalizationVectorEnv",
    "primitive_commands",
    "start_episode",
]

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
MASKS = tuple(f"_{key}" for key in REWARD_TERMS)  # the reward terms' info masks
FIELD_KEYS = {"n_landmarks": "n_candidates", "n_obstacles": "n_obstacles", "size_m": "field_size_m"}


class ActiveLocalizationVectorEnv(OneRobotVectorEnv):
    """N copies of ``infonav/ActiveLocalization-v0`` on stacked arrays: the env's one implementation.

    See ``ActiveLocalizationEnv`` (its N = 1 view) for the spaces, rewards and config keys.
    ``gym.make_vec("infonav/ActiveLocalization-v0", num_envs=N, **config)`` returns it. The estimation runs on
    the batched EKF core (``estimation.batched``), the visibility on ``world.visibility``, the physics in a
    ``WorldBatch`` driven by the primitives' commands and each copy's sensor noise from its own streams
    (``NoiseStreams``), so sub-env ``i`` after ``reset(seed=s)`` gives the numbers of
    ``gym.make("infonav/ActiveLocalization-v0")`` after ``reset(seed=s + i)``.

    ## Vector API
    ``step`` takes one action per sub-env (N,) and returns observations (N, 14 + 4K + 4O), rewards,
    ``terminated`` (goal reached or uncertainty bound crossed) and ``truncated`` (horizon) (N,). Infos hold the
    single env's keys as arrays with a leading N dimension, each with Gymnasium's ``_key`` mask
    (``reward_terms`` is a dict of such arrays, all six terms); ``info["action_mask"]`` is (N, 5 (1 + K)).
    ``action_masks()`` gives the bool masks for ``MaskablePPO``; ``planning_model(copy)`` the planning model of
    sub-env ``copy``.

    ## Autoreset
    As ``LandmarkSelectionVectorEnv``: ``NEXT_STEP`` by default (``metadata["autoreset_mode"]``), ``SAME_STEP``
    (the last outputs in ``info["final_obs"]`` / ``info["final_info"]``) or ``DISABLED``; an episode ends
    terminated or truncated.

    ## Arguments
    ``num_envs`` (N >= 1), ``autoreset_mode`` (an ``AutoresetMode`` or its value) and any key of
    ``default_config()``. ``render_mode`` (``"rgb_array"`` or ``"human"``): ``render()`` draws sub-env 0.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10, "autoreset_mode": AutoresetMode.NEXT_STEP}
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
    n_primitives = N_PRIMITIVES

    @classmethod
    def default_config(cls) -> dict:
        return {
            **OneRobotVectorEnv.default_config(),
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

    def _parts(self):
        """Check the env's own config keys and set the spaces; its range-bearing sensor and odometry."""
        cfg, owner = self.config, self.owner_name
        check_config_arguments(cfg, owner, "goal_field", GOAL_FIELD_ARGUMENTS, FIELD_KEYS)
        check_config(cfg, owner, CONFIG_INTERVALS)
        if cfg["max_position_std_m"] <= cfg["initial_position_std_m"]:
            raise ValueError(
                f"config key 'max_position_std_m' of {owner} must exceed initial_position_std_m "
                f"({cfg['initial_position_std_m']}), got {cfg['max_position_std_m']}"
            )
        self.n_slots = 1 + cfg["n_candidates"]
        low, high = observation_bounds(cfg["n_candidates"], cfg["n_obstacles"])
        self._set_spaces(spaces.Box(low, high, dtype=np.float32), spaces.Discrete(N_PRIMITIVES * self.n_slots))
        return range_bearing_sensor_from_config(cfg, owner), odometry_sensor_from_config(cfg, owner)

    def _allocate(self) -> None:
        num_envs, cfg = self.num_envs, self.config
        self._x, self._P = np.zeros((num_envs, POSE_DIM)), np.zeros((num_envs, POSE_DIM, POSE_DIM))
        self._goals = np.zeros((num_envs, 2))
        self._observations_left = np.zeros(num_envs, dtype=int)
        self._goal_reached = np.zeros(num_envs, dtype=bool)
        self._failed = np.zeros(num_envs, dtype=bool)
        self._chosen = np.full(num_envs, -1)  # the last action of each copy, -1 after a reset or a no-op
        self._landmarks = np.zeros((num_envs, cfg["n_candidates"], 2))
        self._obstacle_centers = np.zeros((num_envs, cfg["n_obstacles"], 2))
        self._obstacle_radii = np.zeros((num_envs, cfg["n_obstacles"]))
        self._planning_models: dict[int, ActivePlanningModel] = {}
        self._everywhere = np.ones((num_envs, cfg["n_candidates"]), dtype=bool)  # every landmark exists
        space = self.single_observation_space
        self._bounds = (space.low.astype(float), space.high.astype(float))  # what the outputs kernel takes

    # ------------------------------------------------------------------ the episode and the step

    def _reset_copies(self, copies: np.ndarray) -> StaticGeometry:
        """Start a new episode in each of ``copies`` from its own generator; the static geometry of those copies."""
        starts = start_episodes(self.config, [self._np_randoms[copy] for copy in copies.tolist()])
        generators = zip(starts.odometry_generators, starts.measurement_generators)
        for copy, scenario, (odometry_rng, measurement_rng) in zip(copies.tolist(), starts.scenarios, generators):
            self._worlds.reset_copy(copy, scenario)
            self._odometry_noise.restart(copy, odometry_rng)
            self._measurement_noise.restart(copy, measurement_rng)
        layouts = starts.layouts
        self._x[copies], self._P[copies] = starts.poses, starts.pose_covariance
        self._goals[copies], self._landmarks[copies] = layouts.goals, layouts.landmarks
        obstacles = (layouts.obstacle_centers, layouts.obstacle_radii)  # the round obstacles: the map the agent knows
        self._obstacle_centers[copies], self._obstacle_radii[copies] = obstacles
        self._observations_left[copies] = self.config["max_observations"]
        self._goal_reached[copies] = self._failed[copies] = False
        return field_geometry(starts.scenarios[0].walls, self._worlds.wall_thickness_m, *obstacles)

    def _act(self, acting: np.ndarray, chosen: np.ndarray) -> tuple:
        """The whole transition of the ``acting`` copies (observe at the prior, then drive); their reward terms
        (6, N), rewards (N,) (0 for the others) and which reached the goal or failed. A no-op (``chosen`` -1) stands
        still observing nothing."""
        landmarks, primitives = decode_actions(chosen)
        driving = chosen >= 0  # -1: a no-op, or a copy not acting
        landmarks[~driving] = primitives[~driving] = -1
        self._x, self._P, mutual_information = self._measured(self._decision.sight, landmarks)
        observed = landmarks >= 0
        self._observations_left -= observed
        copies, before = np.flatnonzero(acting), self._worlds.poses[:, 0, :2].copy()
        if copies.size:
            rows = self._rows(copies)
            commands = primitive_commands(self.config, self._goals[rows], self._x[rows], primitives[rows])
            self._worlds.static_geometry = self._geometry  # its contact test grows the geometry kept here
            self._x[rows], self._P[rows] = self._moved(copies, self._x[rows], self._P[rows], commands)
        after, arrays = self._worlds.poses[:, 0, :2], (self._goals, self._P, mutual_information, observed, driving)
        terms, rewards, reached, failed = step_rewards(self.config, before, after, *arrays, acting)
        np.copyto(self._goal_reached, reached, where=acting)
        np.copyto(self._failed, failed, where=acting)
        return terms, rewards, acting & (self._goal_reached | self._failed)

    # ------------------------------------------------------------------ decision, observation and info

    def _no_step_record(self, n: int) -> np.ndarray:
        """No reward terms (6, 1), for every copy alike."""
        return np.zeros((len(REWARD_TERMS), 1))

    def _outputs(self, copies, geometry, stepped, chosen, terms) -> tuple[np.ndarray, dict]:
        """Decide again at the priors of ``copies`` (geometry: theirs); their observations and infos.

        Args:
            copies: the copies (n,).
            geometry: their static geometry (n copies).
            stepped: which of them acted in this step (n,) bool; the others give their reset info.
            chosen: the action each took (n,), -1 for a no-op.
            terms: their reward terms (6, n) or (6, 1) [nats] (any where not ``stepped``).
        """
        rows = self._rows(copies)
        x, P, true_poses, goals = self._x[rows], self._P[rows], self._worlds.poses[rows, 0], self._goals[rows]
        everywhere = self._everywhere[: len(copies)]
        sight = LandmarkDecision.at_prior(
            self._sensor, geometry, true_poses, x, P, self._landmarks[rows], everywhere, False
        )
        left, obstacles = self._observations_left[rows], (self._obstacle_centers[rows], self._obstacle_radii[rows])
        state = (x, P, true_poses, goals, self._elapsed[rows], left, *obstacles)
        decision, observation, values = copy_outputs(sight, state, self.config, self._bounds)
        if len(copies) == self.num_envs:
            self._decision = decision
        else:
            self._decision.action_mask[copies] = decision.action_mask
            self._decision.action_information_gain[copies] = decision.action_information_gain
            set_rows(self._decision.sight._asdict(), copies, sight._asdict())
        self._chosen[rows] = np.where(stepped, chosen, -1)
        self._track_first_copy(copies, stepped)
        position_error, heading_error, position_std, distance_to_goal = values
        masks = stepped.copy()
        info = {
            "action_mask": decision.action_mask.copy(),
            "action_information_gain": decision.action_information_gain.copy(),
            "reward_terms": {**dict(zip(REWARD_TERMS, np.where(stepped, terms, 0.0))), **dict.fromkeys(MASKS, masks)},
            "chosen_action": self._chosen[rows].copy(),
            "invalid_action": stepped & (chosen < 0),
            "pose_entropy": sight.pose_entropy.copy(),
            "state_entropy": sight.pose_entropy.copy(),
            "position_error_m": position_error,
            "heading_error_rad": heading_error,
            "position_std_m": position_std,
            "true_pose": true_poses.copy(),
            "estimated_pose": x[:, :POSE_DIM].copy(),
            "goal": goals.copy(),
            "distance_to_goal_m": distance_to_goal,
            "observations_left": left.copy(),
            "goal_reached": self._goal_reached[rows].copy(),
            "success": self._goal_reached[rows].copy(),  # the evaluation harness's success flag
            "failed": self._failed[rows].copy(),
            "time_s": self._elapsed[rows] * self.config["time_step_s"],
        }
        return observation, in_every_copy(info, len(copies))

    # ------------------------------------------------------------------ the planning model and drawing

    def planning_model(self, copy: int = 0) -> ActivePlanningModel:
        """The planning model of sub-env ``copy`` (the same object on every call), for look-ahead agents
        (``agents.planner.PlannerAgent``)."""
        if copy not in self._planning_models:
            self._planning_models[copy] = ActivePlanningModel(self, copy)
        return self._planning_models[copy]

    @property
    def odometry_covariance(self) -> np.ndarray:
        """The covariance of the odometry's ``[speed, turn rate]`` readings (2, 2)."""
        return self._odometry_covariance

    def episode_goal(self, copy: int = 0) -> np.ndarray:
        """Sub-env ``copy``'s goal position [m] (2,), a view."""
        return self._goals[copy]

    def episode_landmarks(self, copy: int = 0) -> np.ndarray:
        """Sub-env ``copy``'s landmark positions [m] (K, 2), a view."""
        return self._landmarks[copy]

    def episode_obstacles(self, copy: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Sub-env ``copy``'s round obstacles: centres (O, 2) [m] and radii (O,) [m] (the map the agent knows)."""
        return self._obstacle_centers[copy], self._obstacle_radii[copy]

    def belief(self, copy: int = 0) -> Belief:
        """Sub-env ``copy``'s estimator state at its current decision as a batch of one (visibility: from the true
        pose, as ``info["action_mask"]``)."""
        if self._decision is None:
            raise RuntimeError(f"{self.owner_name}: call reset() before belief()")
        rows = slice(copy, copy + 1)
        return Belief(
            pose=self._x[rows].copy(),
            covariance=self._P[rows].copy(),
            observations_left=self._observations_left[rows].copy(),
            visible=self._decision.sight.action_mask[rows].astype(bool),
            done=self._goal_reached[rows] | self._failed[rows],
        )

    def _scene_frame(self):
        """Sub-env 0 drawn: its field, landmarks (visible ones marked, the observed one linked), goal and robot."""
        scenario, goal = self._worlds.scenario(0), self._goals[0]
        landmark = int(decode_actions(self._chosen[:1])[0][0]) if self._chosen[0] >= 0 else -1
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            landmarks=self._landmarks[0].copy(),
            landmark_visible=self._decision.sight.action_mask[0].astype(bool),
            chosen_landmark=None if landmark < 0 else landmark,
            robots=[self._first_robot_drawing()],
            goal=tuple(goal),
            goal_radius_m=self.config["goal_radius_m"],
            caption=f"t = {self._elapsed[0] * self.config['time_step_s']:.0f} s   "
            f"goal ({goal[0]:.0f}, {goal[1]:.0f}) m, {self._observations_left[0]} observations left",
        )


class ActiveLocalizationEnv(SingleEnvView, vector_env=ActiveLocalizationVectorEnv):
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
    (``agents.planner.PlannerAgent``, through wrappers with
    ``env.get_wrapper_attr("planning_model")()``), with ``belief()``, ``plan_decision(belief)``
    and ``plan_step(belief, actions)``: the env's batched step (``envs.active_transition``) on a
    batch of beliefs, the EKF covariance propagated under the linearization, with the motion
    predicted from the estimated pose and visibility judged from it.

    ## Arguments
    ``gym.make("infonav/ActiveLocalization-v0", render_mode=None, **config)`` with any
    key of ``default_config()``; an unknown key raises ``ValueError`` naming it.

    ## Version History
    * v0: initial version.
    """

    def planning_model(self) -> ActivePlanningModel:
        """The env's planning model (``ActivePlanningModel`` of its one copy), for ``PlannerAgent``.

        Reachable through Gymnasium wrappers: ``env.get_wrapper_attr("planning_model")()``.
        """
        return self.vector.planning_model(0)
