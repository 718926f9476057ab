"""``CooperativeLocalizationEnv``: a heterogeneous team localizes through relative-pose observations (PettingZoo)."""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from infonav_gym.config import Interval, check_choice, check_config, check_config_arguments, config_keys
from infonav_gym.envs.base import EPISODE_STEPS, SceneRendering, discrete_action_index
from infonav_gym.estimation.ekf import INITIAL_POSE_STD, POSE_DIM, JointEKF
from infonav_gym.estimation.models import relative_pose
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import gaussian_entropy_from_log_det
from infonav_gym.multi.team import DEFAULT_OUTAGE, parse_outages, parse_suites
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.odometry import odometry_sensor_from_config
from infonav_gym.sensors.relative_pose import RELATIVE_POSE_SENSORS, noise_covariances, noisy_relative_poses
from infonav_gym.world.scenarios import (
    DEFAULT_WAYPOINTS,
    MAX_ROBOTS,
    SCENARIOS,
    TEAM_FIELD_ARGUMENTS,
    team_route_bands,
)
from infonav_gym.world.world import TIME_STEP_S, World

TEAM_SCENARIOS = ("team_field", "convoy")
ESTIMATORS = ("joint", "independent")
OWN_FEATURES = 10
TEAMMATE_FEATURES = 5
NO_OBSERVATION = 0
_BIG = 1e4
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "max_cycles": EPISODE_STEPS,
    "n_robots": Interval(2, MAX_ROBOTS, integer=True),  # a team; team_field: no more than fit in it
    "team_reward": Interval(0.0, 1.0),
    "time_step_s": TIME_STEP_S,
    **INITIAL_POSE_STD,
}


class CooperativeLocalizationEnv(SceneRendering, ParallelEnv):
    """Robots without (or losing) DGPS localize through relative-pose observations of teammates.

    ## Description
    The paper's Section III-C. N robots follow their routes in a Pymunk world; a
    ``JointEKF`` over all poses fuses every robot's odometry, the DGPS fixes of
    the robots that have them (DGPS drops out on a time schedule and under
    GPS-denied canopy zones) and the relative-pose observations the agents choose.
    Each step each robot may observe one teammate with its laser or camera: the
    measured range, bearing and relative heading update both robots' poses and
    correlate them. A greedy-entropy agent picks the teammate whose observation
    brings the most information on its own pose.

    ## Agents
    ``robot_0 .. robot_{N-1}`` (``team_field`` fits up to 4 robots in its default
    40 m field; ``convoy`` any number). Each robot's sensor suite comes from
    ``robot_sensors`` (default: suite ``k % 4`` of ``gps+laser, gps+laser,
    laser, vision``; odometry always).

    ## Action Space
    ``Discrete(N + 1)`` per agent: 0 = no relative observation (always valid),
    ``1 + j`` = observe ``robot_j``. Valid when the robot carries a relative-pose
    sensor, ``robot_j`` is another robot inside its range and field of view and no
    wall or obstacle blocks the line of sight (``infos[agent]["action_mask"]``). A
    masked action is a no-op (``invalid_action="noop"``, the default, as in the
    single-agent envs) or raises ``ValueError`` (``invalid_action="raise"``). An
    integer outside the space always raises ``ValueError``.

    ## Observation Space
    ``Box(float32, (10 + 5 N,))`` per agent: the robot's estimated ``x, y`` [m],
    ``cos, sin`` of its estimated heading, standard deviations of ``x, y`` [m] and
    heading [rad], its pose entropy [nats], whether it has a DGPS fix now, and the
    elapsed fraction of ``max_cycles``; then per robot ``j``: whether observing it
    is valid, its estimated range [m], ``cos, sin`` of its estimated bearing and its
    position standard deviation [m] (zeros for the robot itself).

    ## Rewards
    The realized mutual information on the robot's own pose of this step's
    relative-pose updates, ``0.5 ln(det P_ii,prior / det P_ii,post)`` [nats], mixed
    with the team's (the MI on the joint state) by ``team_reward`` in [0, 1]:
    ``(1 - team_reward) * own + team_reward * team``. The observations of one step
    are taken at the same time and fused as one stacked EKF update, so a robot's
    reward also counts what teammates' observations of it brought;
    ``action_information_gain[a]`` is the MI action ``a`` alone would bring to the
    robot's own pose at the step's prior.

    ## Info
    ``infos[agent]``: ``action_mask`` (int8), ``action_information_gain`` (expected
    reward of each action [nats], 0 where masked), ``reward_terms`` (own and team MI),
    ``chosen_action``, ``invalid_action``, ``gps_available``, ``pose_std`` (x, y,
    heading std at the step's prior), ``pose_std_after_update`` (right after the
    step's relative updates), ``pose_entropy``, ``position_error_m``,
    ``heading_error_rad``, ``true_pose``, ``estimated_pose``, ``time_s``.

    ## Starting State
    The robots at their routes' starts; initial estimates drawn from
    ``N(true pose, diag(initial_position_std_m^2, ..., initial_heading_std_rad^2))``.

    ## Episode End
    All agents are truncated after ``max_cycles`` steps; never terminated.

    ## Arguments
    ``parallel_env(render_mode=None, **config)`` with any key of
    ``default_config()``; an unknown key raises ``ValueError`` naming it.
    ``estimator="independent"`` drops the cross-covariances (overconfident, for
    comparison).

    ## Version History
    * v0: initial version.
    """

    metadata = {
        "name": "cooperative_localization_v0",
        "render_modes": ["human", "rgb_array"],
        "render_fps": 10,
        "is_parallelizable": True,
    }

    @classmethod
    def default_config(cls) -> dict:
        """A fresh dict of every config key with its default."""
        return {
            "max_cycles": 200,  # episode length [steps]; all agents are truncated after it
            "scenario": "team_field",  # "team_field" (random loops, canopies) or "convoy" (the paper's Fig. 3)
            "n_robots": 4,
            "robot_sensors": None,  # one suite per robot, e.g. ["gps+laser", "vision"]; None: the default team
            "gps_outages": (DEFAULT_OUTAGE,),  # (robot, start_s, end_s) spans without DGPS [s]
            "estimator": "joint",  # "joint" (cross-covariances) or "independent" (drops them)
            "team_reward": 0.0,  # weight of the team's MI in each robot's reward, in [0, 1]
            "invalid_action": "noop",  # a masked action: "noop" or "raise" (ValueError)
            "time_step_s": 0.5,  # [s]
            "speed_mps": 1.0,  # cruise speed along the routes [m/s]
            "gps_std_m": 0.1,  # DGPS position noise per coordinate [m]
            "odometry_speed_std_mps": 0.05,  # [m/s]
            "odometry_turn_rate_std_rps": 0.02,  # [rad/s]
            "initial_position_std_m": 0.1,  # [m]
            "initial_heading_std_rad": 0.02,  # [rad]
            "n_obstacles": 6,  # team_field only
            "n_canopies": 2,  # GPS-denied zones, team_field only
            "field_size_m": 40.0,  # side of the square field, team_field only [m]
            "render_size_px": 600,  # longer side of rendered frames [px]
        }

    def __init__(self, render_mode: str | None = None, **config):
        self._configure(render_mode, config)
        cfg, owner = self.config, type(self).__name__
        check_choice(cfg, "scenario", TEAM_SCENARIOS, owner)
        check_choice(cfg, "estimator", ESTIMATORS, owner)
        check_config(cfg, owner, CONFIG_INTERVALS)
        field_keys = {key: key for key in ("n_obstacles", "n_canopies", "speed_mps")}
        field_keys["size_m"] = "field_size_m"
        check_config_arguments(cfg, owner, "team_field", TEAM_FIELD_ARGUMENTS, field_keys)  # the convoy's speed too
        if cfg["scenario"] == "team_field":
            with config_keys(owner, {"n_robots": "n_robots"}):
                team_route_bands(cfg["n_robots"], cfg["field_size_m"], DEFAULT_WAYPOINTS)
        n = cfg["n_robots"]
        self.suites = parse_suites(cfg["robot_sensors"], n, cfg["scenario"])
        outages = parse_outages(cfg["gps_outages"], n)
        with config_keys(owner, {"position_std_m": "gps_std_m"}):
            self.gps = [
                GPSSensor(cfg["gps_std_m"], spans) if suite.gps else None for suite, spans in zip(self.suites, outages)
            ]
        self.relative_sensors = [RELATIVE_POSE_SENSORS.get(suite.relative_sensor) for suite in self.suites]
        self.odometry = odometry_sensor_from_config(cfg, owner)
        self._odometry_covariances = np.repeat(self.odometry.noise_covariance()[None], n, axis=0)
        self.max_cycles = cfg["max_cycles"]
        self.possible_agents = [f"robot_{k}" for k in range(n)]
        self.agents = []
        self._action_spaces = {agent: spaces.Discrete(n + 1) for agent in self.possible_agents}
        low, high = self._observation_bounds(n)
        self._observation_spaces = {agent: spaces.Box(low, high, dtype=np.float32) for agent in self.possible_agents}
        pairs = [(i, j) for i in range(n) for j in range(n) if i != j and self.relative_sensors[i] is not None]
        self._observers = np.array([i for i, _ in pairs], dtype=int)
        self._targets = np.array([j for _, j in pairs], dtype=int)
        self._pair_noise = np.array([self.relative_sensors[i].noise_parameters() for i, _ in pairs]).reshape(-1, 5)
        self._pair_max_range = np.array([self.relative_sensors[i].max_range_m for i, _ in pairs])
        self._pair_half_fov = np.array([0.5 * self.relative_sensors[i].range_bearing.fov_rad for i, _ in pairs])
        self._sight_lines = sorted({(min(i, j), max(i, j)) for i, j in pairs})  # line of sight is symmetric
        self._pair_sight_line = np.array([self._sight_lines.index((min(i, j), max(i, j))) for i, j in pairs], dtype=int)
        self.world = World()
        self.np_random = None

    @staticmethod
    def _observation_bounds(n_robots: int) -> tuple[np.ndarray, np.ndarray]:
        own_low, own_high = [-_BIG, -_BIG, -1, -1, 0, 0, 0, -100, 0, 0], [_BIG, _BIG, 1, 1, _BIG, _BIG, _BIG, 100, 1, 1]
        teammate_low, teammate_high = [0, 0, -1, -1, 0], [1, _BIG, 1, 1, _BIG]
        low = np.array(own_low + teammate_low * n_robots, dtype=np.float32)
        high = np.array(own_high + teammate_high * n_robots, dtype=np.float32)
        return low, high

    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._action_spaces[agent]

    # ------------------------------------------------------------------ reset / step

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode; ``seed`` re-seeds ``np_random`` (else it continues); ``options`` are unused."""
        if seed is not None or self.np_random is None:
            self.np_random, _ = seeding.np_random(seed)
        cfg = self.config
        self.world.reset(self._build_scenario())
        self._odometry_rng, self._gps_rng, self._relative_rng = self.np_random.spawn(3)
        n = cfg["n_robots"]
        pose_std = np.array([cfg["initial_position_std_m"]] * 2 + [cfg["initial_heading_std_rad"]])
        self._true_poses = self.world.poses
        initial = self._true_poses + pose_std * self.np_random.standard_normal((n, POSE_DIM))
        covariances = np.repeat(np.diag(pose_std**2)[None], n, axis=0)
        self.ekf = JointEKF(initial, covariances, cross_covariances=cfg["estimator"] == "joint")
        self.agents = list(self.possible_agents)
        self._elapsed_steps = 0
        self._time_s = 0.0
        self._gps_fixes()
        self._observed_pairs = []
        self._chosen = np.zeros(n, dtype=int)
        self._invalid = np.zeros(n, dtype=bool)
        self._reward_terms = [{"own_mutual_information": 0.0, "team_mutual_information": 0.0}] * n
        self._updated_pose_std = None
        self._true_paths = [[pose[:2]] for pose in self._true_poses]
        self._estimated_paths = [[pose[:2]] for pose in self.ekf.poses]
        self._decide()
        if self.render_mode == "human":
            self.render()
        return self._observations(), self._infos()

    def _build_scenario(self):
        cfg = self.config
        if cfg["scenario"] == "convoy":
            return SCENARIOS["convoy"](self.np_random, n_robots=cfg["n_robots"], speed_mps=cfg["speed_mps"])
        return SCENARIOS["team_field"](
            self.np_random,
            n_robots=cfg["n_robots"],
            n_obstacles=cfg["n_obstacles"],
            n_canopies=cfg["n_canopies"],
            size_m=cfg["field_size_m"],
            speed_mps=cfg["speed_mps"],
        )

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError(f"{type(self).__name__}: call reset() before step() (and after the episode ends)")
        chosen, invalid = self._validated_actions(actions)
        self._chosen, self._invalid = chosen, invalid
        own_before = self._pose_log_det
        joint_before = np.linalg.slogdet(self.ekf.P)[1]
        self._observe(chosen)
        own_log_dets, self._updated_pose_std = self._pose_uncertainty()
        own_mi = 0.5 * (own_before - own_log_dets)
        team_mi = 0.5 * (joint_before - np.linalg.slogdet(self.ekf.P)[1])
        weight = self.config["team_reward"]
        self._reward_terms = [
            {"own_mutual_information": float(own), "team_mutual_information": float(team_mi)} for own in own_mi
        ]
        rewards = {
            agent: float((1.0 - weight) * own + weight * team_mi) for agent, own in zip(self.possible_agents, own_mi)
        }
        self._advance()
        self._decide()
        observations, infos = self._observations(), self._infos()
        truncated = self._elapsed_steps >= self.max_cycles
        terminations = dict.fromkeys(self.agents, False)
        truncations = dict.fromkeys(self.agents, truncated)
        if truncated:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return observations, rewards, terminations, truncations, infos

    def _validated_actions(self, actions: dict) -> tuple[np.ndarray, np.ndarray]:
        """Every live agent's action as an index (masked ones become no-ops), checked before anything changes."""
        if not isinstance(actions, dict) or set(actions) != set(self.agents):
            given = sorted(actions) if isinstance(actions, dict) else actions
            raise ValueError(f"actions must be a dict with one action per live agent {self.agents}, got {given!r}")
        chosen = np.zeros(len(self.possible_agents), dtype=int)
        invalid = np.zeros(len(self.possible_agents), dtype=bool)
        for robot, agent in enumerate(self.possible_agents):
            action = discrete_action_index(actions[agent], self._action_spaces[agent])
            if self._action_mask[robot, action]:
                chosen[robot] = action
                continue
            if self.config["invalid_action"] == "raise":
                raise ValueError(
                    f"action {action} of {agent} is not valid now (action_mask "
                    f"{self._action_mask[robot].tolist()}); pick an action whose infos[{agent!r}]['action_mask'] "
                    'entry is 1, or set invalid_action="noop"'
                )
            invalid[robot] = True
        return chosen, invalid

    def _observe(self, chosen: np.ndarray) -> None:
        """Apply the chosen relative-pose observations, taken at the same time, as one stacked update."""
        observers = np.flatnonzero(chosen != NO_OBSERVATION)
        targets = chosen[observers] - 1
        self._observed_pairs = list(zip(observers.tolist(), targets.tolist()))
        if observers.size == 0:
            return
        rows = self._candidate_row[observers, chosen[observers]]
        predicted, H_observer, H_target, R = (part[rows] for part in self._candidates)
        pairs = self._valid_pairs[rows]
        measurements = noisy_relative_poses(self._geometry[pairs], self._pair_noise[pairs], self._relative_rng)
        self.ekf.relative_pose_update(
            observers, targets, measurements, predicted, H_observer, H_target, R, check_input=False
        )

    def _advance(self) -> None:
        """Move every robot, predict with its noisy odometry, then fuse the DGPS fixes available."""
        dt = self.config["time_step_s"]
        controls = self.world.step(dt)
        self._true_poses = self.world.poses
        odometry = self.odometry.measure(controls, self._odometry_rng)
        self.ekf.predict(odometry, dt, self._odometry_covariances, check_input=False)
        self._elapsed_steps += 1
        self._time_s = self._elapsed_steps * dt
        self._gps_fixes()
        for robot, (true_pose, estimate) in enumerate(zip(self._true_poses, self.ekf.x.reshape(-1, POSE_DIM))):
            self._true_paths[robot].append(true_pose[:2])
            self._estimated_paths[robot].append(estimate[:2].copy())

    def _gps_fixes(self) -> None:
        denied = self.world.gps_denied(self._true_poses[:, :2])
        self._gps_available = np.array(
            [gps is not None and gps.available(self._time_s, bool(denied[k])) for k, gps in enumerate(self.gps)]
        )
        robots = np.flatnonzero(self._gps_available)
        if robots.size:
            fixes = np.array([self.gps[k].measure(self._true_poses[k, :2], self._gps_rng) for k in robots])
            covariances = np.array([self.gps[k].noise_covariance() for k in robots])
            self.ekf.gps_update(robots, fixes, covariances, check_input=False)

    def _pose_uncertainty(self) -> tuple[np.ndarray, np.ndarray]:
        """Per robot, ``ln det`` of its pose covariance (N,) and its x, y, heading standard deviations (N, 3)."""
        covariances = self.ekf.pose_covariances()
        return np.linalg.slogdet(covariances)[1], np.sqrt(np.diagonal(covariances, axis1=1, axis2=2))

    def _decide(self) -> None:
        """Action masks (who can see whom) and expected gains on the observer's own pose, at the current prior."""
        n = len(self.possible_agents)
        truth = self._true_poses
        self._geometry = relative_pose(truth[self._observers], truth[self._targets])
        covered = np.flatnonzero(
            (self._geometry[:, 0] <= self._pair_max_range) & (np.abs(self._geometry[:, 1]) <= self._pair_half_fov)
        )
        lines = sorted(set(self._pair_sight_line[covered].tolist()))
        clear = dict(zip(lines, self.world.robots_in_sight([self._sight_lines[line] for line in lines])))
        valid = self._valid_pairs = covered[[clear[line] for line in self._pair_sight_line[covered].tolist()]]
        observers, targets = self._observers[valid], self._targets[valid]
        self._action_mask = np.zeros((n, n + 1), dtype=np.int8)
        self._action_mask[:, NO_OBSERVATION] = 1
        self._action_mask[observers, targets + 1] = 1
        self._action_information_gain = np.zeros((n, n + 1))
        self._candidate_row = np.full((n, n + 1), -1)
        self._candidate_row[observers, targets + 1] = np.arange(valid.size)
        if valid.size:
            predicted, H_observer, H_target = self.ekf.relative_pose_model(observers, targets)
            R = noise_covariances(self._pair_noise[valid], predicted[:, 0])
            own, joint = self.ekf.relative_pose_information_gains(observers, targets, H_observer, H_target, R)
            weight = self.config["team_reward"]
            self._action_information_gain[observers, targets + 1] = (1.0 - weight) * own + weight * joint
            self._candidates = (predicted, H_observer, H_target, R)
        self._pose_log_det, self._pose_std = self._pose_uncertainty()

    # ------------------------------------------------------------------ observations, infos

    def _observations(self) -> dict:
        n = len(self.possible_agents)
        estimates = self.ekf.x.reshape(-1, POSE_DIM)
        std = self._pose_std
        features = np.zeros((n, OWN_FEATURES + TEAMMATE_FEATURES * n), dtype=np.float32)
        features[:, 0:2] = estimates[:, :2]
        features[:, 2] = np.cos(estimates[:, 2])
        features[:, 3] = np.sin(estimates[:, 2])
        features[:, 4:7] = std
        features[:, 7] = gaussian_entropy_from_log_det(self._pose_log_det, POSE_DIM)
        features[:, 8] = self._gps_available
        features[:, 9] = self._elapsed_steps / self.max_cycles
        teammates = features[:, OWN_FEATURES:].reshape(n, n, TEAMMATE_FEATURES)
        offsets = estimates[None, :, :2] - estimates[:, None, :2]
        bearings = np.arctan2(offsets[..., 1], offsets[..., 0]) - estimates[:, None, 2]
        teammates[..., 0] = self._action_mask[:, 1:]
        teammates[..., 1] = np.hypot(offsets[..., 0], offsets[..., 1])
        teammates[..., 2] = np.cos(bearings)
        teammates[..., 3] = np.sin(bearings)
        teammates[..., 4] = np.hypot(std[:, 0], std[:, 1])[None, :]
        teammates[np.arange(n), np.arange(n)] = 0.0
        space = self._observation_spaces[self.possible_agents[0]]
        np.clip(features, space.low, space.high, out=features)
        return {agent: features[robot] for robot, agent in enumerate(self.agents)}

    def _infos(self) -> dict:
        estimates = self.ekf.x.reshape(-1, POSE_DIM)
        std = self._pose_std
        updated_std = std if self._updated_pose_std is None else self._updated_pose_std
        entropies = gaussian_entropy_from_log_det(self._pose_log_det, POSE_DIM)
        infos = {}
        for robot, agent in enumerate(self.agents):
            true_pose, estimate = self._true_poses[robot], estimates[robot]
            infos[agent] = {
                "action_mask": self._action_mask[robot].copy(),
                "action_information_gain": self._action_information_gain[robot].copy(),
                "reward_terms": dict(self._reward_terms[robot]),
                "chosen_action": int(self._chosen[robot]),
                "invalid_action": bool(self._invalid[robot]),
                "gps_available": bool(self._gps_available[robot]),
                "position_error_m": math.dist(true_pose[:2], estimate[:2]),
                "heading_error_rad": abs(wrap_angle(float(true_pose[2] - estimate[2]))),
                "pose_entropy": float(entropies[robot]),
                "pose_std": std[robot].copy(),
                "pose_std_after_update": updated_std[robot].copy(),
                "true_pose": true_pose.copy(),
                "estimated_pose": estimate.copy(),
                "time_s": self._time_s,
            }
        return infos

    # ------------------------------------------------------------------ rendering

    def _scene_frame(self):
        from infonav_gym.rendering import RobotDrawing, SceneFrame

        scenario = self.world.scenario
        estimates = self.ekf.poses
        robots = [
            RobotDrawing(
                true_pose=self._true_poses[k],
                estimated_pose=estimates[k],
                pose_covariance=self.ekf.pose_covariance(k),
                true_path=np.array(self._true_paths[k]),
                estimated_path=np.array(self._estimated_paths[k]),
                label=f"{k}{'' if self._gps_available[k] else ' no GPS'}",
            )
            for k in range(len(self.possible_agents))
        ]
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            robots=robots,
            observations=list(self._observed_pairs),
            gps_denied_zones=scenario.gps_denied_zones,
            caption=f"t = {self._time_s:.1f} s",
        )
