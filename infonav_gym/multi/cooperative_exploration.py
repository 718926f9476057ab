"""``CooperativeExplorationEnv``: a team maps a field, each robot choosing where to go and what to see (PettingZoo)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from gymnasium import spaces

from infonav_gym.config import Interval, check_config, check_config_arguments, config_keys
from infonav_gym.envs.active_localization import REWARD_WEIGHT
from infonav_gym.envs.base import EPISODE_STEPS, MAX_EPISODE_STEPS, Decision
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.estimation.ekf import INITIAL_POSE_STD, POSE_DIM, JointEKF
from infonav_gym.information import largest_position_std
from infonav_gym.multi.base import InfoNavParallelEnv, team_metadata
from infonav_gym.multi.exploration_planning import (
    N_MOTIONS,
    NOOP_ACTION,
    STAY,
    ExplorationPlanningModel,
    action_gains,
    clear_motions,
    motion_plan,
    reward_terms,
    total_reward,
)
from infonav_gym.multi.exploration_views import (
    EXPLORATION_INFO_KEYS,
    EXPLORATION_METRICS,
    ExplorationSight,
    ExplorationViews,
)
from infonav_gym.multi.landmark_sensing import LandmarkSensing
from infonav_gym.multi.team import parse_outages, parse_speeds, parse_suites
from infonav_gym.multi.team_localization import team_observation_bounds
from infonav_gym.multi.team_sensing import (
    NO_OBSERVATION,
    RelativeSight,
    SensingPairs,
    TeamSensing,
    gps_schedule,
    team_prior,
)
from infonav_gym.multi.terrain_map import TerrainMapModel
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.odometry import odometry_sensor_from_config
from infonav_gym.sensors.relative_pose import RELATIVE_POSE_SENSORS, noise_covariances
from infonav_gym.world.active_scenarios import CommandedWorld
from infonav_gym.world.exploration_scenarios import EXPLORATION_FIELD_ARGUMENTS, exploration_field
from infonav_gym.world.scenarios import MAX_ROBOTS, MAX_SPEED_MPS
from infonav_gym.world.visibility import StaticGeometry
from infonav_gym.world.world import TIME_STEP_S, start_poses

DEFAULT_SPEEDS_MPS = (0.8, 0.8, 1.2, 1.2)  # robot k of the default team: the DGPS robots are the slower ones
RANGE_KEYS = {"laser": "laser_range_m", "vision": "vision_range_m"}  # the config key of each sensor's range
REWARD_TERMS = ("own_pose_information", "team_map_information", "sensing_cost", "motion_cost", "lost_penalty")
SCENARIO_KEYS = {  # exploration_field parameter: the config key that gives it
    "n_robots": "n_robots",
    "n_obstacles": "n_obstacles",
    "n_canopies": "n_canopies",
    "n_landmarks": "n_landmarks",
    "size_m": "field_size_m",
}
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "max_cycles": EPISODE_STEPS,
    "n_robots": Interval(2, MAX_ROBOTS, integer=True),
    "team_reward": Interval(0.0, 1.0),
    "time_step_s": TIME_STEP_S,
    "turn_time_s": TIME_STEP_S,  # and below time_step_s
    "map_cells_per_side": Interval(2, 100, integer=True),
    "map_prior_std_m": Interval(0.0, 100.0, open_low=True, unit="m"),  # and above covered_std_m
    "scan_radius_m": Interval(0.0, 1000.0, open_low=True, unit="m"),
    "scan_std_m": Interval(1e-3, 100.0, unit="m"),
    "terrain_slope": Interval(0.0, 10.0, unit="m/m"),
    "covered_std_m": Interval(0.0, 100.0, open_low=True, unit="m"),
    "coverage_target": Interval(0.0, 1.0, open_low=True),
    "max_position_std_m": Interval(0.0, 1000.0, open_low=True, unit="m"),  # and above initial_position_std_m
    "max_observations": Interval(0, MAX_EPISODE_STEPS, integer=True),
    **INITIAL_POSE_STD,
    **{key: REWARD_WEIGHT for key in ("observation_cost_nats", "motion_cost_per_step", "lost_penalty")},
}


class CooperativeExplorationEnv(
    ExplorationPlanningModel, ExplorationViews, LandmarkSensing, TeamSensing, InfoNavParallelEnv
):
    """A heterogeneous team maps a field; each robot chooses where to drive and what to observe, together.

    ## Description
    The paper's Section III-C, distributed heterogeneous multirobot exploration. The team
    starts at a base in one corner of a square Pymunk field (``exploration_field``) with
    round obstacles, GPS-denied canopy zones and a few landmarks, and must map the terrain:
    a grid of cells whose heights are Gaussian estimates (``terrain_map``). A robot that
    drives scans the cells around it; a position error ``sigma`` puts heights at the wrong
    place, so a scan's height noise grows as ``scan_std_m^2 + (terrain_slope * sigma)^2``:
    a badly localized robot maps poorly. A ``JointEKF`` over all poses fuses odometry, DGPS
    fixes (robots with DGPS, outside the canopies) and the observations the agents choose:
    a known landmark (range-bearing) or a teammate (relative pose, which correlates the two).

    Why a myopic agent fails: the robots without DGPS drift on odometry alone and stay
    localized only while a landmark or a well-localized teammate is within their sensor's
    short range. The unmapped cells lie far from both, so the action with the most immediate
    information (drive to fresh cells, observe whatever is in sight) leads the GPS-less
    robots away from every reference; their position std then crosses
    ``max_position_std_m`` and the team fails. Succeeding needs plans over several steps:
    scouts that cover far cells while returning near a teammate or a landmark in time, DGPS
    robots that escort them and leave the canopies, and a budget kept for when it matters.

    ## Agents
    ``robot_0 .. robot_{N-1}`` (default 4). Suites from ``robot_sensors`` (default: suite
    ``k % 4`` of ``gps+laser, gps+laser, laser, vision``; odometry always), speeds from
    ``robot_speeds_mps`` (default ``0.8, 0.8, 1.2, 1.2`` m/s: the DGPS robots are slower).
    The laser sees all around up to ``laser_range_m``, the camera a 60 deg field of view up
    to ``vision_range_m``; a robot observes landmarks and teammates with its one sensor.

    ## Action Space
    ``Discrete(5 * (1 + L + N))`` per agent, ``L = n_landmarks``: action ``a`` is slot
    ``a // 5`` and motion ``a % 5``. Slots: 0 observe nothing, ``1 + j`` landmark ``j``,
    ``1 + L + j`` ``robot_j``. A motion (``stay``, ``east``, ``north``, ``west``, ``south``)
    turns the robot on the spot for ``turn_time_s`` until its heading *estimated at the decision* is the
    compass heading, then drives it straight at its speed for the rest of the step (``stay`` does neither);
    Pymunk executes both phases, and both are exact unicycle motions for the EKF. A motion is valid while its
    true path keeps ``clearance.CLEARANCE_M`` (5 cm) from walls, obstacles and wherever a teammate's motions can take it
    (``world.clearance``): no contact ever pushes a robot unseen by its odometry. An observation is valid while the
    target is in range and field of view with a clear line of sight and the robot has budget
    left (``max_observations``); every observation goes with every valid motion, and action 0 (stay,
    observe nothing) is always valid. A masked
    action is action 0 (``invalid_action="noop"``) or raises ``ValueError`` (``"raise"``).

    ## Observation Space
    ``Box(float32, (10 + 5 N + 4 L + 3 + G,))``, ``G = map_cells_per_side^2``: the 10 own and
    5 per-robot features of ``cooperative_localization_v0``; per landmark: whether observing
    it is valid, its estimated range [m], ``cos, sin`` of its estimated bearing; the robot's
    speed [m/s], its budget left (fraction), the team's coverage; per cell (row-major from the
    lower left corner) the height std left, as a fraction of ``map_prior_std_m``.

    ## Rewards
    ``(1 - team_reward) * own_pose_information + team_reward * team_map_information`` plus
    the costs, with ``info["reward_terms"]``: ``own_pose_information``, the realized MI of
    the step's observations on the robot's own pose [nats]; ``team_map_information``, the map
    entropy reduction of every robot's scans this step [nats]; ``sensing_cost``
    ``-observation_cost_nats`` per observation; ``motion_cost`` ``-motion_cost_per_step`` per
    step driven; ``lost_penalty`` ``-lost_penalty`` for every robot when one is lost.
    ``info["action_information_gain"][a]`` is the immediate expected information of ``a``:
    ``(1 - team_reward)`` times the MI its observation alone brings to the robot's pose at the
    prior, plus ``team_reward`` times the map information its scan alone would bring, from the
    position the motion predicts, at the robot's current position std (0 where masked).
    A scan is taken only after driving forward: standing or turning in place sees the same
    view again, with the same errors, so it brings nothing new (action 0 has gain 0).

    ## Info
    ``infos[agent]``: ``action_mask`` (int8), ``action_information_gain``, ``reward_terms``,
    ``chosen_action``, ``invalid_action``, ``gps_available``, ``pose_std``, ``position_std_m``
    (largest, at the decision), ``pose_entropy``, ``position_error_m``, ``heading_error_rad``,
    ``true_pose``, ``estimated_pose``, ``time_s``, ``observations_left``, ``coverage``
    (team), ``lost`` (this robot), ``failed`` and ``success`` (the team).

    ## Starting State
    Parked at the base, facing the field's centre; estimates drawn from
    ``N(true pose, diag(initial_position_std_m^2, ..., initial_heading_std_rad^2))``; the map
    at its prior (std ``map_prior_std_m`` in every cell).

    ## Episode End
    Terminated for all agents when a robot's largest position std exceeds
    ``max_position_std_m`` (it is lost: ``failed``), or when the coverage reaches
    ``coverage_target`` (``success``); truncated after ``max_cycles`` steps (no success).

    ## Planning model
    ``planning_model()`` returns the env itself as the model look-ahead agents search
    (``multi.exploration_planning``): ``belief()`` copies the joint EKF, the map and the budgets,
    ``plan_decision(belief, robot)`` and ``plan_step(belief, team_actions)`` step copies of it under the
    expected measurements, never reading the true state (``agents.planner.PlannerAgent(env, robot)``).

    ## Arguments
    ``parallel_env(render_mode=None, **config)`` with any key of ``default_config()``; an
    unknown key or a bad value raises ``ValueError`` naming it.

    ## Version History
    * v0: initial version (issue 18; no batched version yet). Motions masked clear of contacts, and the
      planning model, added before any results were committed.
    """

    episode_metrics = EXPLORATION_METRICS
    traits = EnvTraits(
        reports_success=True,
        may_terminate=True,
        noop_action=NOOP_ACTION,
        idle_actions=frozenset({NOOP_ACTION}),  # stay, observe nothing
        reward_config_keys=("team_reward",),
        reward_terms=REWARD_TERMS,
        info_keys=EXPLORATION_INFO_KEYS,
    )

    metadata = team_metadata("cooperative_exploration_v0")

    @classmethod
    def default_config(cls) -> dict:
        """A fresh dict of every config key with its default."""
        return {
            "max_cycles": 200,  # episode length [steps]
            "n_robots": 4,
            "robot_sensors": None,  # one suite per robot, e.g. ["gps+laser", "vision"]; None: the default team
            "robot_speeds_mps": None,  # one cruise speed per robot [m/s]; None: DEFAULT_SPEEDS_MPS
            "gps_outages": (),  # (robot, start_s, end_s) spans without DGPS [s], besides the canopies
            "team_reward": 0.5,  # weight of the team's map information against the own pose MI, in [0, 1]
            "invalid_action": "noop",  # a masked action: "noop" or "raise" (ValueError)
            "time_step_s": 1.0,  # [s]
            "turn_time_s": 0.25,  # the turn phase of a step: a robot turns on the spot, then drives straight [s]
            "laser_range_m": 10.0,  # range of the lasers, on landmarks and teammates [m]
            "vision_range_m": 8.0,  # range of the cameras [m]
            "gps_std_m": 0.1,  # DGPS position noise per coordinate [m]
            "odometry_speed_std_mps": 0.05,  # [m/s]
            "odometry_turn_rate_std_rps": 0.02,  # [rad/s]
            "initial_position_std_m": 0.1,  # [m]
            "initial_heading_std_rad": 0.02,  # [rad]
            "max_position_std_m": 1.5,  # a robot whose largest position std exceeds this is lost [m]
            "max_observations": 100,  # sensing budget of each robot per episode
            "observation_cost_nats": 0.05,  # [nats] per observation
            "motion_cost_per_step": 0.01,  # [nats] per step driven
            "lost_penalty": 10.0,  # [nats], subtracted from every robot's reward when one is lost
            "map_cells_per_side": 20,  # the coverage map is a grid of this many cells squared (2 m cells)
            "map_prior_std_m": 1.0,  # terrain height std of an unscanned cell [m]
            "scan_radius_m": 4.0,  # a scan sees the cells whose centre lies this close [m]
            "scan_std_m": 0.1,  # height noise of a scan from a known position [m]
            "terrain_slope": 0.5,  # height error per metre of position error [m/m]
            "covered_std_m": 0.3,  # a cell is covered once its height std is at most this [m]
            "coverage_target": 0.6,  # success: this fraction of the cells covered, no robot lost
            "n_obstacles": 6,
            "n_canopies": 3,  # GPS-denied zones
            "n_landmarks": 4,
            "field_size_m": 40.0,  # side of the square field [m]
            "render_size_px": 600,  # longer side of rendered frames [px]
        }

    def __init__(self, render_mode: str | None = None, **config):
        self._configure(render_mode, config)
        cfg, owner = self.config, type(self).__name__
        check_config(cfg, owner, CONFIG_INTERVALS)
        check_config_arguments(cfg, owner, "exploration_field", EXPLORATION_FIELD_ARGUMENTS, SCENARIO_KEYS)
        floors = (("max_position_std_m", "initial_position_std_m"), ("map_prior_std_m", "covered_std_m"))
        for key, floor in (*floors, ("time_step_s", "turn_time_s")):
            if cfg[key] <= cfg[floor]:
                raise ValueError(f"config key {key!r} of {owner} must exceed {floor} ({cfg[floor]}), got {cfg[key]}")
        n, n_landmarks = cfg["n_robots"], cfg["n_landmarks"]
        self.suites = parse_suites(cfg["robot_sensors"], n, "exploration_field")
        self.speeds_mps = np.array(parse_speeds(cfg["robot_speeds_mps"], DEFAULT_SPEEDS_MPS, n, MAX_SPEED_MPS))
        outages = parse_outages(cfg["gps_outages"], n)
        with config_keys(owner, {"position_std_m": "gps_std_m"}):
            self.gps = [GPSSensor(cfg["gps_std_m"], spans) if s.gps else None for s, spans in zip(self.suites, outages)]
        self.relative_sensors = [self._ranged_sensor(suite.relative_sensor) for suite in self.suites]
        self.odometry = odometry_sensor_from_config(cfg, owner)
        self._odometry_covariances = np.repeat(self.odometry.noise_covariance()[None], n, axis=0)
        map_parameters = ("prior_std_m", "scan_radius_m", "scan_std_m", "terrain_slope", "covered_std_m")
        self.map_model = TerrainMapModel.square(
            cfg["field_size_m"],
            cfg["map_cells_per_side"],
            **{name: cfg[name if name != "prior_std_m" else "map_prior_std_m"] for name in map_parameters},
        )
        self.max_cycles = cfg["max_cycles"]
        self.possible_agents = [f"robot_{k}" for k in range(n)]
        self.agents = []
        self.n_slots = 1 + n_landmarks + n
        self._action_spaces = {agent: spaces.Discrete(N_MOTIONS * self.n_slots) for agent in self.possible_agents}
        team_low, team_high = team_observation_bounds(n, False)
        self._team_space = spaces.Box(team_low, team_high, dtype=np.float32)
        low, high = self._observation_bounds(team_low, team_high, n_landmarks, self.map_model.n_cells)
        self._observation_spaces = {agent: spaces.Box(low, high, dtype=np.float32) for agent in self.possible_agents}
        self.pairs = SensingPairs.of_team(self.relative_sensors)
        self._pair_lookup = np.full((n, n), -1)  # the pair index of (observer, target), -1 for none
        self._pair_lookup[self.pairs.observers, self.pairs.targets] = np.arange(len(self.pairs.observers))
        self._gps_schedule = gps_schedule(self.gps)
        self._gps_noise = np.array([np.eye(2) if gps is None else gps.noise_covariance() for gps in self.gps])
        self.world = CommandedWorld()
        self.np_random = None

    def _ranged_sensor(self, name: str | None):
        """The relative-pose sensor ``name`` with this env's range for it (None for no sensor)."""
        if name is None:
            return None
        sensor, key = RELATIVE_POSE_SENSORS[name], RANGE_KEYS[name]
        with config_keys(type(self).__name__, {"max_range_m": key}):
            return replace(sensor, range_bearing=replace(sensor.range_bearing, max_range_m=self.config[key]))

    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._action_spaces[agent]

    # ------------------------------------------------------------------ the episode

    def _reset_episode(self) -> None:
        cfg = self.config
        scenario, poses, covariances, *generators = start_episode(cfg, self.np_random)
        self._odometry_rng, self._gps_rng, self._relative_rng, self._landmark_rng = generators
        self.world.reset(scenario)
        self._static_geometry = StaticGeometry.from_world(self.world)
        self._tiled_geometries = {}  # the planning model's copies of it, by count
        self._true_poses = self.world.poses
        self.ekf = JointEKF(poses, covariances)
        n = len(self.possible_agents)
        self._time_s = 0.0
        self._gps_fixes()
        self.map_variances = self.map_model.prior_variances()
        self.coverage = 0.0
        self.observations_left = np.full(n, cfg["max_observations"])
        self.lost = np.zeros(n, dtype=bool)
        self.success = False
        self._observed_pairs, self._observed_landmarks = [], []
        self._reward_terms = [dict.fromkeys(REWARD_TERMS, 0.0)] * n
        self._start_paths()

    def _is_terminated(self) -> bool:
        return bool(self.lost.any()) or self.success

    def _next_decision(self) -> Decision:
        """Masks and immediate expected gains of every (observation, motion) pair, at the current prior."""
        n, n_landmarks = len(self.possible_agents), self.config["n_landmarks"]
        slot_valid = np.zeros((n, self.n_slots), dtype=bool)
        slot_valid[:, 0] = True
        observation_gain = np.zeros((n, self.n_slots))
        budget_left = self.observations_left > 0
        geometry, valid = self._observable_pairs()
        valid = valid[budget_left[self.pairs.observers[valid]]]
        observers, targets = self.pairs.observers[valid], self.pairs.targets[valid]
        candidate_row = np.full((n, n + 1), -1)
        candidate_row[observers, targets + 1] = np.arange(valid.size)
        candidates = None
        if valid.size:
            predicted, H_observer, H_target = self.ekf.relative_pose_model(observers, targets)
            R = noise_covariances(self.pairs.noise[valid], predicted[:, 0])
            own, _ = self.ekf.relative_pose_information_gains(observers, targets, H_observer, H_target, R)
            slot_valid[observers, 1 + n_landmarks + targets] = True
            observation_gain[observers, 1 + n_landmarks + targets] = own
            candidates = (predicted, H_observer, H_target, R)
        landmark_visible = self._visible_landmarks() & budget_left[:, None]
        robots, landmarks = np.nonzero(landmark_visible)
        if robots.size:
            _, H_pose, R = self._landmark_models(robots, landmarks)
            slot_valid[robots, 1 + landmarks] = True
            observation_gain[robots, 1 + landmarks] = self.ekf.landmark_information_gains(robots, H_pose, R)
        covariances = self.ekf.pose_covariances()
        pose_log_det = np.linalg.slogdet(covariances)[1]
        pose_std = np.sqrt(np.diagonal(covariances, axis1=1, axis2=2))
        position_std = largest_position_std(covariances)
        scan = self._scan_gains(self.ekf.x.reshape(-1, POSE_DIM), position_std, self.map_variances)
        mask = slot_valid[:, :, None] & self._clear_motions()[:, None, :]
        gains = action_gains(self.config["team_reward"], observation_gain, scan, mask).reshape(n, -1)
        relative = RelativeSight(geometry, valid, candidate_row, candidates, pose_log_det, pose_std)
        return Decision(
            mask.reshape(n, -1).astype(np.int8), gains, ExplorationSight(relative, slot_valid, position_std)
        )

    def _clear_motions(self) -> np.ndarray:
        """Which motions each robot may take (R, 5): those whose true path keeps clear of every contact
        (``clear_motions`` from the true poses, as the observations' masks)."""
        headings = self.ekf.x[None, 2::POSE_DIM]
        radius_m = self.world.robot_radius_m
        return clear_motions(
            self._static_geometry, self._true_poses[None], headings, self.speeds_mps, self._drive_s, radius_m
        )[0]

    def _apply_actions(self, actions: np.ndarray, decision: Decision) -> np.ndarray:
        """Observe at the prior, drive, predict, fuse DGPS, then scan; each robot's reward (see the class)."""
        cfg = self.config
        n_landmarks = cfg["n_landmarks"]
        relative = decision.payload.relative
        slots, motions = np.divmod(actions, N_MOTIONS)
        plan = motion_plan(motions, self.ekf.x[2::POSE_DIM], self.speeds_mps)  # the decision's, as masked
        observes_teammate = slots > n_landmarks
        teammate_choice = np.where(observes_teammate, slots - n_landmarks, NO_OBSERVATION)
        self._observe(teammate_choice, relative)
        landmark_observers = np.flatnonzero((slots > 0) & ~observes_teammate)
        self._observe_landmarks(landmark_observers, slots[landmark_observers] - 1)
        observed = slots > 0
        self.observations_left = self.observations_left - observed
        own_information = 0.5 * (relative.pose_log_det - np.linalg.slogdet(self.ekf.pose_covariances())[1])
        self._drive(*plan)
        self._time_s = (self._elapsed_steps + 1) * cfg["time_step_s"]
        self._gps_fixes()
        position_std = largest_position_std(self.ekf.pose_covariances())
        map_information = self._scan(motions != STAY, position_std)
        self.lost = position_std > cfg["max_position_std_m"]
        self.success = bool(self.coverage >= cfg["coverage_target"] and not self.lost.any())
        terms = reward_terms(self.config, own_information, map_information, observed, motions != STAY, self.lost.any())
        self._reward_terms = [{key: float(value[robot]) for key, value in terms.items()} for robot in range(len(slots))]
        return total_reward(self.config["team_reward"], terms)

    def _drive(self, turns: np.ndarray, speeds: np.ndarray) -> None:
        """Turn every robot on the spot, then drive it straight (Pymunk executes both); predict with odometry."""
        cfg = self.config
        turn_s = cfg["turn_time_s"]
        turning = np.column_stack([np.zeros_like(speeds), turns / turn_s])
        driving = np.column_stack([speeds, np.zeros_like(turns)])
        for phase_s, commands in ((turn_s, turning), (cfg["time_step_s"] - turn_s, driving)):
            for robot, (speed, turn_rate) in enumerate(commands.tolist()):
                self.world.command(speed, turn_rate, robot)
            controls = self.world.step(phase_s)
            odometry = self.odometry.measure(controls, self._odometry_rng)
            self.ekf.predict(odometry, phase_s, self._odometry_covariances, check_input=False)
        self._true_poses = self.world.poses

    def _scan(self, scanning: np.ndarray, position_std: np.ndarray) -> float:
        """Fuse the scans of the ``scanning`` robots from their true positions; the map information [nats]."""
        if not scanning.any():
            return 0.0
        model, before = self.map_model, self.map_variances
        footprints = model.footprints(self._true_poses[scanning, :2])
        self.map_variances = model.fused(before, footprints, model.scan_noise_variances(position_std[scanning]))
        self.coverage = float(model.coverage(self.map_variances))
        return 0.5 * math.fsum(np.log(before / self.map_variances))

    def _advance(self) -> None:
        self._extend_paths()


def start_episode(config: dict, np_random: np.random.Generator):
    """Start an episode: draw its field and the ``JointEKF`` prior from ``np_random``, in a fixed order.

    Returns:
        ``(scenario, poses (R, 3), covariances (R, 3, 3), odometry_rng, gps_rng, relative_rng, landmark_rng)``, so
        the parallel and the vector env draw the same episode from the same generator.
    """
    scenario = exploration_field(np_random, **{name: config[key] for name, key in SCENARIO_KEYS.items()})
    generators = np_random.spawn(4)
    poses, covariances = team_prior(config, np.array(start_poses(scenario)), np_random)
    return scenario, poses, covariances, *generators
