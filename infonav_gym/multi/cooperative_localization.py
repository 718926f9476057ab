"""``CooperativeLocalizationEnv``: a heterogeneous team localizes through relative-pose observations (PettingZoo)."""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from infonav_gym.config import Interval, check_choice, check_config, check_config_arguments, config_keys
from infonav_gym.envs.base import EPISODE_STEPS, Decision
from infonav_gym.envs.metrics import TEAM_LOCALIZATION_METRICS
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.estimation.ekf import INITIAL_POSE_STD, POSE_DIM, JointEKF
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import gaussian_entropy_from_log_det
from infonav_gym.multi.base import InfoNavParallelEnv, team_metadata
from infonav_gym.multi.team import DEFAULT_OUTAGE, parse_outages, parse_suites
from infonav_gym.multi.team_paths import TeamPaths
from infonav_gym.multi.team_sensing import NO_OBSERVATION, RelativeSight, SensingPairs, TeamSensing, team_prior
from infonav_gym.scene import SceneFrame
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.odometry import odometry_sensor_from_config
from infonav_gym.sensors.relative_pose import RELATIVE_POSE_SENSORS, noise_covariances
from infonav_gym.world.scenarios import (
    DEFAULT_WAYPOINTS,
    MAX_ROBOTS,
    TEAM_FIELD_ARGUMENTS,
    scenario_from_config,
    scenario_names,
    team_route_bands,
)
from infonav_gym.world.world import TIME_STEP_S, World, start_poses

ESTIMATORS = ("joint", "independent")
TEAM_SCENARIO_KEYS = {  # scenario builder parameter: the config key that gives it
    "n_robots": "n_robots",
    "n_obstacles": "n_obstacles",
    "n_canopies": "n_canopies",
    "size_m": "field_size_m",
    "speed_mps": "speed_mps",
}
OWN_FEATURES = 10
TEAMMATE_FEATURES = 5
_BIG = 1e4
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "max_cycles": EPISODE_STEPS,
    "n_robots": Interval(2, MAX_ROBOTS, integer=True),  # a team; team_field: no more than fit in it
    "team_reward": Interval(0.0, 1.0),
    "time_step_s": TIME_STEP_S,
    **INITIAL_POSE_STD,
}


class CooperativeLocalizationEnv(TeamSensing, TeamPaths, InfoNavParallelEnv):
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
    position standard deviation [m] (zeros for the robot itself). With
    ``observe_gains=True``, ``N + 1`` more: ``action_information_gain`` of each
    action (what a greedy agent ranks by [nats]), so ``Box(float32, (11 + 6 N,))``.

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

    episode_metrics = TEAM_LOCALIZATION_METRICS
    traits = EnvTraits(
        idle_actions=frozenset({NO_OBSERVATION}),
        reward_terms=("own_mutual_information", "team_mutual_information"),
        info_keys=frozenset(
            {"gps_available", "pose_std", "pose_std_after_update", "pose_entropy", "position_error_m"}
            | {"heading_error_rad", "estimated_pose"}
        ),
        reward_config_keys=("team_reward",),
        noop_action=NO_OBSERVATION,
    )

    metadata = team_metadata("cooperative_localization_v0")

    @classmethod
    def default_config(cls) -> dict:
        """A fresh dict of every config key with its default."""
        return {
            "max_cycles": 200,  # episode length [steps]; all agents are truncated after it
            "scenario": "team_field",  # "team_field" (random loops), "convoy" (the paper's Fig. 3), or registered
            "n_robots": 4,
            "robot_sensors": None,  # one suite per robot, e.g. ["gps+laser", "vision"]; None: the default team
            "gps_outages": (DEFAULT_OUTAGE,),  # (robot, start_s, end_s) spans without DGPS [s]
            "estimator": "joint",  # "joint" (cross-covariances) or "independent" (drops them)
            "team_reward": 0.0,  # weight of the team's MI in each robot's reward, in [0, 1]
            "observe_gains": False,  # True: each observation ends with the expected reward of each action
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
        check_choice(cfg, "scenario", scenario_names(team=True), owner)
        check_choice(cfg, "estimator", ESTIMATORS, owner)
        check_config(cfg, owner, CONFIG_INTERVALS)
        check_config_arguments(cfg, owner, "team_field", TEAM_FIELD_ARGUMENTS, TEAM_SCENARIO_KEYS)  # the convoy's too
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
        low, high = self._observation_bounds(n, cfg["observe_gains"])
        self._observation_spaces = {agent: spaces.Box(low, high, dtype=np.float32) for agent in self.possible_agents}
        self.pairs = SensingPairs.of_team(self.relative_sensors)
        self.world = World()
        self.np_random = None

    @staticmethod
    def _observation_bounds(n_robots: int, observe_gains: bool) -> tuple[np.ndarray, np.ndarray]:
        own_low, own_high = [-_BIG, -_BIG, -1, -1, 0, 0, 0, -100, 0, 0], [_BIG, _BIG, 1, 1, _BIG, _BIG, _BIG, 100, 1, 1]
        teammate_low, teammate_high = [0, 0, -1, -1, 0], [1, _BIG, 1, 1, _BIG]
        gain_low, gain_high = ([0] * (n_robots + 1), [_BIG] * (n_robots + 1)) if observe_gains else ([], [])
        low = np.array(own_low + teammate_low * n_robots + gain_low, dtype=np.float32)
        high = np.array(own_high + teammate_high * n_robots + gain_high, dtype=np.float32)
        return low, high

    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._action_spaces[agent]

    # ------------------------------------------------------------------ the episode

    def _reset_episode(self) -> None:
        scenario, poses, covariances, *generators = start_episode(self.config, self.np_random, type(self).__name__)
        self._odometry_rng, self._gps_rng, self._relative_rng = generators
        self.ekf = JointEKF(poses, covariances, cross_covariances=self.config["estimator"] == "joint")
        self.world.reset(scenario)
        self._true_poses = self.world.poses
        n = len(self.possible_agents)
        self._time_s = 0.0
        self._gps_fixes()
        self._observed_pairs = []
        self._reward_terms = [{"own_mutual_information": 0.0, "team_mutual_information": 0.0}] * n
        self._updated_pose_std = None
        self._start_paths()

    def _apply_actions(self, actions: np.ndarray, decision: Decision) -> np.ndarray:
        """Fuse the chosen observations; each robot's reward mixes its own and the team's MI by ``team_reward``."""
        sight = decision.payload
        joint_before = np.linalg.slogdet(self.ekf.P)[1]
        self._observe(actions, sight)
        own_log_dets, self._updated_pose_std = self._pose_uncertainty()
        own_mi = 0.5 * (sight.pose_log_det - own_log_dets)
        team_mi = 0.5 * (joint_before - np.linalg.slogdet(self.ekf.P)[1])
        weight = self.config["team_reward"]
        self._reward_terms = [
            {"own_mutual_information": float(own), "team_mutual_information": float(team_mi)} for own in own_mi
        ]
        return (1.0 - weight) * own_mi + weight * team_mi

    def _advance(self) -> None:
        """Move every robot, predict with its noisy odometry, then fuse the DGPS fixes available."""
        dt = self.config["time_step_s"]
        controls = self.world.step(dt)
        self._true_poses = self.world.poses
        self.ekf.predict(
            self.odometry.measure(controls, self._odometry_rng), dt, self._odometry_covariances, check_input=False
        )
        self._time_s = self._elapsed_steps * dt
        self._gps_fixes()
        self._extend_paths()

    def _next_decision(self) -> Decision:
        """Action masks (who can see whom) and expected gains on the observer's own pose, at the current prior."""
        n = len(self.possible_agents)
        pairs = self.pairs
        geometry, valid = self._observable_pairs()
        observers, targets = pairs.observers[valid], pairs.targets[valid]
        mask = np.zeros((n, n + 1), dtype=np.int8)
        mask[:, NO_OBSERVATION] = 1
        mask[observers, targets + 1] = 1
        gains = np.zeros((n, n + 1))
        candidate_row = np.full((n, n + 1), -1)
        candidate_row[observers, targets + 1] = np.arange(valid.size)
        candidates = None
        if valid.size:
            predicted, H_observer, H_target = self.ekf.relative_pose_model(observers, targets)
            R = noise_covariances(pairs.noise[valid], predicted[:, 0])
            own, joint = self.ekf.relative_pose_information_gains(observers, targets, H_observer, H_target, R)
            weight = self.config["team_reward"]
            gains[observers, targets + 1] = (1.0 - weight) * own + weight * joint
            candidates = (predicted, H_observer, H_target, R)
        pose_log_det, pose_std = self._pose_uncertainty()
        return Decision(mask, gains, RelativeSight(geometry, valid, candidate_row, candidates, pose_log_det, pose_std))

    # ------------------------------------------------------------------ observations, infos

    def _observations(self) -> dict:
        sight = self._decision.payload
        features = team_observations(
            self.ekf.x.reshape(-1, POSE_DIM),
            sight.pose_std,
            sight.pose_log_det,
            self._gps_available,
            self._elapsed_steps / self.max_cycles,
            self._decision.action_mask[:, 1:],
            self._observation_spaces[self.possible_agents[0]],
            self._decision.action_information_gain if self.config["observe_gains"] else None,
        )
        return {agent: features[robot] for robot, agent in enumerate(self.agents)}

    def _infos(self) -> dict:
        estimates = self.ekf.x.reshape(-1, POSE_DIM)
        decision = self._decision
        std = decision.payload.pose_std
        updated_std = std if self._updated_pose_std is None else self._updated_pose_std
        entropies = gaussian_entropy_from_log_det(decision.payload.pose_log_det, POSE_DIM)
        infos = {}
        for robot, agent in enumerate(self.agents):
            true_pose, estimate = self._true_poses[robot], estimates[robot]
            infos[agent] = {
                **self._decision_info(robot),
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
        scenario = self.world.scenario
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            robots=self._robot_drawings(),
            observations=list(self._observed_pairs),
            gps_denied_zones=scenario.gps_denied_zones,
            caption=f"t = {self._time_s:.1f} s   {len(self._observed_pairs)} relative observations this step",
        )


def start_episode(config: dict, np_random: np.random.Generator, owner: str):
    """Start an episode of the team env: draw its scenario and the joint estimator's prior from ``np_random``.

    Draws in a fixed order (the scenario, the sensors' generators, the initial estimates), so the
    parallel and the vector env give the same episode for the same generator.

    Args:
        config: a checked ``CooperativeLocalizationEnv`` config.
        np_random: the episode's generator.
        owner: the env named in config errors.

    Returns:
        ``(scenario, poses, covariances, odometry_rng, gps_rng, relative_rng)``: the team scenario
        ``config["scenario"]`` (one route per robot), the robots' initial estimates (R, 3) and their
        covariances (R, 3, 3) (the ``JointEKF`` prior, no cross-covariance) and the sensors' generators.
    """
    n = config["n_robots"]
    scenario = scenario_from_config(config, np_random, TEAM_SCENARIO_KEYS, owner, n)
    odometry_rng, gps_rng, relative_rng = np_random.spawn(3)
    initial, covariances = team_prior(config, np.array(start_poses(scenario)), np_random)
    return scenario, initial, covariances, odometry_rng, gps_rng, relative_rng


def team_observations(
    estimates, pose_std, pose_log_det, gps_available, elapsed_fraction, teammate_valid, space: spaces.Box, gains=None
) -> np.ndarray:
    """Every robot's observation (see ``CooperativeLocalizationEnv``), float32 clipped to ``space``, for R robots.

    Any leading dimensions (L...) are batch dimensions (the vector env's copies).

    Args:
        estimates: estimated poses (L..., R, 3).
        pose_std: x, y, heading standard deviations of each robot at the prior (L..., R, 3).
        pose_log_det: ``ln det`` of each robot's pose covariance at the prior (L..., R).
        gps_available: whether each robot has a DGPS fix now (L..., R).
        elapsed_fraction: elapsed fraction of ``max_cycles``, broadcastable to (L..., R) (a number, or (L..., 1)).
        teammate_valid: whether each robot may observe each robot now (L..., R, R).
        space: one robot's observation space.
        gains: each robot's ``action_information_gain`` (L..., R, R + 1) to append (``observe_gains``), or None.

    Returns:
        (L..., R, 10 + 5 R), or (L..., R, 11 + 6 R) with ``gains``.
    """
    lead, n = estimates.shape[:-2], estimates.shape[-2]
    features = np.zeros((*lead, n, space.shape[0]), dtype=np.float32)
    features[..., 0:2] = estimates[..., :2]
    features[..., 2] = np.cos(estimates[..., 2])
    features[..., 3] = np.sin(estimates[..., 2])
    features[..., 4:7] = pose_std
    features[..., 7] = gaussian_entropy_from_log_det(pose_log_det, POSE_DIM)
    features[..., 8] = gps_available
    features[..., 9] = elapsed_fraction
    teammates_end = OWN_FEATURES + TEAMMATE_FEATURES * n
    teammates = features[..., OWN_FEATURES:teammates_end].reshape(*lead, n, n, TEAMMATE_FEATURES)
    offsets = estimates[..., None, :, :2] - estimates[..., :, None, :2]
    bearings = np.arctan2(offsets[..., 1], offsets[..., 0]) - estimates[..., :, None, 2]
    teammates[..., 0] = teammate_valid
    teammates[..., 1] = np.hypot(offsets[..., 0], offsets[..., 1])
    teammates[..., 2] = np.cos(bearings)
    teammates[..., 3] = np.sin(bearings)
    teammates[..., 4] = np.hypot(pose_std[..., 0], pose_std[..., 1])[..., None, :]
    robots = np.arange(n)
    teammates[..., robots, robots, :] = 0.0
    if gains is not None:
        features[..., teammates_end:] = gains
    return np.clip(features, space.low, space.high, out=features)
