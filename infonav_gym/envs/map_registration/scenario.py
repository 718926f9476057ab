"""``infonav/MapRegistration-v0``: what of each LADAR scan to register to an a-priori map (the paper's Section V
outlook: GPS-denied registration of sensed scans to a-priori terrain maps), as a scenario."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from infonav_gym.config import Interval, check_config, from_config
from infonav_gym.envs.base import shared_config
from infonav_gym.envs.driver import Driver
from infonav_gym.envs.metrics import (
    CUMULATIVE_MI_TITLE,
    RMSE_TITLE,
    EpisodeMetric,
    count_where,
    mean_where,
    root_mean_square,
    summed_info,
    summed_reward,
    summed_reward_term,
)
from infonav_gym.envs.protocol import EnvScenario, State
from infonav_gym.envs.single_view import SingleEnvView
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.envs.vector_infos import Decision, decision_info
from infonav_gym.estimation.kernels import kalman_updates, predict_poses
from infonav_gym.estimation.state import INITIAL_POSE_STD
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import gaussian_entropy_from_log_det, log_det_spd, mutual_information_from_log_dets
from infonav_gym.registration.control_points import select_control_points
from infonav_gym.registration.frame_pairs import scan_on_terrain
from infonav_gym.registration.map_registration import (
    MIN_INLIERS,
    match_to_map,
    motion_covariances,
    planar_covariance,
    planar_pose_map,
    point_jacobians,
    register_to_map,
    sensor_pose_on_map,
)
from infonav_gym.registration.prior_map import MapErrors, prior_map
from infonav_gym.scene import SENSOR_WEDGE_LENGTH_M, PathHistory, RobotDrawing, SceneFrame, extended_paths
from infonav_gym.sensors.ladar import Ladar, sensor_points, to_display_image
from infonav_gym.sensors.odometry import odometry_sensor_from_config
from infonav_gym.world.physics import TIME_STEP_S
from infonav_gym.world.terrain_scenario import SCENE_CONFIG, check_scene_config, terrain_loop_from_config
from infonav_gym.world.world_batch import WorldBatch

MAP_KEYS = {  # MapErrors' field: the config key that gives it
    "cell_m": "map_cell_m",
    "height_std_m": "map_height_std_m",
    "feature_offset_std_m": "map_feature_offset_std_m",
    "missing_fraction": "map_missing_fraction",
    "extra_features": "map_extra_features",
}
FAILURE_SIGMAS = 3.0  # a fused registration this many sigmas (Mahalanobis) off the truth is a failure
MAX_GAIN = 50.0  # observation bound of an expected gain [nats]
MAX_POSITION_STD_M = 10.0  # observation bound of the position std [m]
FIXED_ACTIONS = ("none", "all")  # then one per sector, then SEGMENTS, then "control_points"
SEGMENTS = ("ground", "features")  # the returns the map says hit the ground, or one of its features
CONTROL_POINT_ACTION_STRATEGY = "stratified_information"  # the best information-based selector measured
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "time_step_s": TIME_STEP_S,
    "n_sectors": Interval(1, 32, integer=True),
    "control_point_fraction": Interval(0.0, 1.0, open_low=True),
    "point_cost": Interval(0.0, 1.0, unit="nats per point"),
    "gate_nis": Interval(0.0, 1e6, open_low=True),
    "icp_max_iterations": Interval(1, 1000, integer=True),
    "max_correspondence_distance_m": Interval(0.0, 100.0, open_low=True, unit="m"),
    **INITIAL_POSE_STD,
}


def failed(info: dict) -> bool:
    """Whether the step fused a fix ``FAILURE_SIGMAS`` off the truth."""
    return bool(info["registration_failed"])


def fused(info: dict) -> bool:
    """Whether the step fused a fix."""
    return bool(info["fused"])


def action_names(n_sectors: int) -> tuple[str, ...]:
    """The name of each action: ``none``, ``all``, ``sector_0`` .. (left to right), the segments, ``control_points``."""
    return (*FIXED_ACTIONS, *(f"sector_{s}" for s in range(n_sectors)), *SEGMENTS, "control_points")


@dataclass
class MapState(State):
    """Every copy's vehicle (``worlds``), true terrain, prior map, generators (scan, odometry, map), EKF ``x`` (N, 3)
    and ``P`` (N, 3, 3) of the planar pose on the map, newest scan and its points (sensor frame); per action the
    returns it registers (``subsets``: (K, n) bool per copy), its predicted fix covariance (N, K, 3, 3), whether
    the map predicts enough matches (N, K) and its point count (N, K); the last residual variance (N,) [m^2]; the
    step's chosen action (N,), realized MI and point cost (N,) [nats], registered returns (N,), whether a fix was
    fused or refused, its NIS and NEES (NaN: none) and whether it failed; copy 0's true and estimated paths."""

    worlds: WorldBatch
    terrains: list
    maps: list
    scan_rngs: list
    odometry_rngs: list
    scans: list
    points: list
    subsets: list
    x: np.ndarray
    P: np.ndarray
    fix_covariances: np.ndarray
    enough: np.ndarray
    point_counts: np.ndarray
    residual_variance: np.ndarray
    chosen: np.ndarray
    mutual_information: np.ndarray
    cost: np.ndarray
    registered_points: np.ndarray
    fused: np.ndarray
    refused: np.ndarray
    fix_nees: np.ndarray
    nis: np.ndarray
    failed: np.ndarray
    paths: tuple[PathHistory, PathHistory] | None = None


class MapRegistration(EnvScenario):
    """``infonav/MapRegistration-v0`` as a scenario (spaces, reward, config: ``MapRegistrationEnv``)."""

    episode_metrics = (
        EpisodeMetric("cumulative_reward", "cumulative reward [nats]", summed_reward),
        EpisodeMetric("cumulative_mi", CUMULATIVE_MI_TITLE, summed_reward_term("mutual_information")),
        EpisodeMetric("pose_rmse_m", RMSE_TITLE, root_mean_square("position_error_m")),
        EpisodeMetric("registered_points", "registered returns [points]", summed_info("registered_points")),
        EpisodeMetric("registration_failures", "registration failures [-]", count_where(failed)),
        EpisodeMetric("registration_nees", "mean NEES of the fused fixes [-]", mean_where("registration_nees", fused)),
    )
    traits = EnvTraits(
        kb_per_copy=1000,  # [kB] at the defaults, between peak RSS growth and traced allocations
        estimates_pose=True,
        gain_known_before_measuring=False,  # a fix's covariance comes from its own matches
        idle_actions=frozenset({0}),
        valid_gain_may_be_zero=True,  # a registration the filter already knows all of adds ~nothing
        reward_terms=("mutual_information", "point_cost"),
        info_keys=frozenset(
            {"fused", "refused", "registered_points", "registration_nees", "registration_failed", "nis"}
        ),
        noop_action=0,
        everything_action=1,
        main_metric="cumulative_reward",
    )

    @classmethod
    def default_config(cls) -> dict:
        return {
            **shared_config(),
            "horizon": 60,  # steps
            "time_step_s": 0.5,  # between scans [s]
            "speed_mps": 2.0,  # [m/s]
            **SCENE_CONFIG,  # the terrain_loop scene
            "map_cell_m": 1.0,  # the map's grid and sample spacing [m]
            "map_height_std_m": 0.05,  # error of each of its heights [m]
            "map_feature_offset_std_m": 0.2,  # error of each of its features' position along x and y [m]
            "map_missing_fraction": 0.1,  # features the map misses
            "map_extra_features": 3,  # features the map has and the scene has not
            "n_sectors": 2,  # azimuth sectors of the scan an action may register
            "control_point_fraction": 0.1,  # of the returns, for the "control_points" action
            "point_cost": 1e-4,  # [nats per registered return]
            "gate_nis": 7.81,  # a fix whose NIS exceeds this is refused (chi-square, 3 dof, 95 %)
            "icp_max_iterations": 50,
            "max_correspondence_distance_m": 2.0,  # [m]
            "odometry_speed_std_mps": 0.1,  # [m/s]
            "odometry_turn_rate_std_rps": 0.03,  # [rad/s]
            "initial_position_std_m": 0.3,  # [m]
            "initial_heading_std_rad": 0.02,  # [rad]
            "ladar_range_std_m": Ladar().range_std_m,  # [m]
        }

    def __init__(self, config: dict, copies: int, owner: str, render_mode: str | None):
        super().__init__(config, copies, owner, render_mode)
        cfg = config
        check_config(cfg, owner, CONFIG_INTERVALS)
        check_scene_config(cfg, owner)
        self.ladar = from_config(Ladar, cfg, {"range_std_m": "ladar_range_std_m"}, owner)
        self.odometry = odometry_sensor_from_config(cfg, owner)
        self.map_errors = from_config(MapErrors, cfg, MAP_KEYS, owner)
        self.actions = action_names(cfg["n_sectors"])
        n_actions = len(self.actions)
        self.action_space = spaces.Discrete(n_actions)
        high = np.append(np.tile([1.0, MAX_GAIN, 1.0], n_actions), [MAX_POSITION_STD_M, math.pi, 1.0, 1.0])
        self.observation_space = spaces.Box(np.zeros_like(high, np.float32), high.astype(np.float32), dtype=np.float32)
        self.initial_variance = np.array([cfg["initial_position_std_m"]] * 2 + [cfg["initial_heading_std_rad"]]) ** 2
        self.first_residual_variance = cfg["ladar_range_std_m"] ** 2 + cfg["map_height_std_m"] ** 2

    def allocate(self, copies: int) -> MapState:
        n_actions = self.action_space.n
        return MapState(
            elapsed=np.zeros(copies, dtype=int),
            worlds=WorldBatch(copies),
            **{name: [None] * copies for name in ("terrains", "maps", "scan_rngs", "odometry_rngs", "scans", "points")},
            subsets=[np.zeros((n_actions, 0), dtype=bool)] * copies,
            x=np.zeros((copies, 3)),
            P=np.tile(np.eye(3), (copies, 1, 1)),
            fix_covariances=np.tile(np.eye(3), (copies, n_actions, 1, 1)),
            enough=np.zeros((copies, n_actions), dtype=bool),
            point_counts=np.zeros((copies, n_actions), dtype=int),
            registered_points=np.zeros(copies, dtype=int),
            residual_variance=np.full(copies, self.first_residual_variance),
            chosen=np.full(copies, -1),
            **{name: np.zeros(copies) for name in ("mutual_information", "cost")},
            **{name: np.zeros(copies, dtype=bool) for name in ("fused", "refused", "failed")},
            fix_nees=np.full(copies, np.nan),
            nis=np.full(copies, np.nan),
        )

    def initial(self, state: MapState, rows: np.ndarray, rngs: list) -> MapState:
        """Draw each copy's scene and its map, the EKF's initial estimate, and scan the first frame."""
        for copy, rng in zip(rows.tolist(), rngs):
            scene = terrain_loop_from_config(rng, self.config)
            state.worlds.reset_copy(copy, scene.scenario)
            map_rng, state.scan_rngs[copy], state.odometry_rngs[copy], start_rng = rng.spawn(4)
            state.terrains[copy] = scene.terrain
            state.maps[copy] = prior_map(scene.terrain, map_rng, self.map_errors)
            state.x[copy] = state.worlds.poses[copy, 0] + np.sqrt(self.initial_variance) * start_rng.standard_normal(3)
            state.x[copy, 2] = wrap_angle(state.x[copy, 2])
        state.P[rows] = np.diag(self.initial_variance)
        state.residual_variance[rows] = self.first_residual_variance
        state.chosen[rows], state.mutual_information[rows], state.cost[rows] = -1, 0.0, 0.0
        state.registered_points[rows] = 0
        state.fused[rows] = state.refused[rows] = state.failed[rows] = False
        state.fix_nees[rows] = state.nis[rows] = np.nan
        self._scan(state, rows)
        self._follow_first_copy(state, rows, restarted=True)
        return state

    def _scan(self, state: MapState, copies: np.ndarray) -> None:
        """Each of ``copies`` scans from its true pose; the returns of each action and their predicted fix."""
        for copy in copies.tolist():
            pose = state.worlds.poses[copy, 0].copy()
            scan = scan_on_terrain(self.ladar, state.terrains[copy], pose, state.scan_rngs[copy])
            state.scans[copy], state.points[copy] = scan, sensor_points(scan)
            self._predict_fixes(state, copy)

    def _predict_fixes(self, state: MapState, copy: int) -> None:
        """The returns each action registers, and the covariance of the fix the map predicts from them at the
        estimate: its matches there (``match_to_map``) with the last residual variance."""
        cfg, scan, prior = self.config, state.scans[copy], state.maps[copy]
        init = self._sensor_at_estimate(state, copy)
        moved = state.points[copy] @ init[:3, :3].T + init[:3, 3]
        matches = match_to_map(moved, prior, cfg["max_correspondence_distance_m"])
        jacobians = point_jacobians(moved, matches.normals, init[:3, 3])
        columns = np.nonzero(~scan.no_return)[1]
        n_sectors, n_returns = cfg["n_sectors"], len(moved)
        subsets = np.zeros((self.action_space.n, n_returns), dtype=bool)
        subsets[1] = True
        subsets[2 + columns * n_sectors // scan.no_return.shape[1], np.arange(n_returns)] = True
        subsets[2 + n_sectors] = matches.features < 0
        subsets[3 + n_sectors] = matches.features >= 0
        subsets[4 + n_sectors, self._control_points(scan)] = True
        matched = subsets & matches.inliers
        motion = motion_covariances(
            jacobians, matches, matched, state.residual_variance[copy], cfg["map_feature_offset_std_m"]
        )
        state.subsets[copy] = subsets
        state.fix_covariances[copy] = planar_covariance(motion, planar_pose_map(init, self.ladar.mount_height_m)[1])
        state.enough[copy] = matched.sum(axis=1) >= MIN_INLIERS
        state.enough[copy, 0] = True
        state.point_counts[copy] = subsets.sum(axis=1)

    def _control_points(self, scan) -> np.ndarray:
        """The ``control_point_fraction`` of the returns the suite's information-based selector picks
        (``select_control_points``' ``CONTROL_POINT_ACTION_STRATEGY``)."""
        returns = int(np.count_nonzero(~scan.no_return))
        k = math.ceil(self.config["control_point_fraction"] * returns)
        try:
            return select_control_points(scan, k, CONTROL_POINT_ACTION_STRATEGY) if k else np.zeros(0, np.int64)
        except ValueError:  # fewer returns with a surface normal than k: every return
            return np.arange(returns)

    def decision(self, state: MapState, rows) -> Decision:
        """Each action's expected MI about the pose: ``0.5 ln det(P + R_k) / det(R_k)``, ``R_k`` its predicted fix
        covariance; valid with enough predicted matches (``none`` always, gain 0)."""
        R = state.fix_covariances[rows]
        gains = mutual_information_from_log_dets(
            log_det_spd(state.P[rows][:, None] + R, check_input=False), log_det_spd(R, check_input=False)
        )
        mask = state.enough[rows].copy()
        gains[:, 0] = 0.0
        return Decision(mask.astype(np.int8), np.where(mask, np.maximum(gains, 0.0), 0.0))

    def transition(self, state: MapState, decision: Decision, action, acting) -> MapState:
        """Register each acting copy's chosen returns and fuse the fix (unless its NIS exceeds ``gate_nis``); then
        every acting copy drives one step on, predicts from its odometry and scans."""
        cfg = self.config
        chosen = action[:, 0]
        state.chosen = chosen
        n = len(chosen)
        state.mutual_information, state.cost = np.zeros(n), np.zeros(n)
        state.registered_points = np.zeros(n, dtype=int)
        state.fused, state.refused, state.failed = np.zeros(n, bool), np.zeros(n, bool), np.zeros(n, bool)
        state.fix_nees, state.nis = np.full(n, np.nan), np.full(n, np.nan)
        residuals, noise, used = np.zeros((n, 1, 3)), np.tile(np.eye(3), (n, 1, 1, 1)), np.zeros((n, 1), dtype=bool)
        for copy in np.flatnonzero(chosen > 0).tolist():
            subset = state.subsets[copy][chosen[copy]]
            state.registered_points[copy] = np.count_nonzero(subset)
            state.cost[copy] = -cfg["point_cost"] * state.registered_points[copy]
            fix = self._gated_fix(state, copy, subset)
            if fix is not None:
                residuals[copy, 0], noise[copy, 0], used[copy, 0] = fix
        if used.any():
            prior_log_det = log_det_spd(state.P, check_input=False)
            identity = np.tile(np.eye(3), (n, 1, 1, 1))
            state.x, state.P = kalman_updates(state.x, state.P, residuals, identity, noise, used, 1, True)
            posterior_log_det = log_det_spd(state.P, check_input=False)
            gains = mutual_information_from_log_dets(prior_log_det, posterior_log_det)
            state.mutual_information = np.where(used[:, 0], gains, 0.0)
        moving = np.flatnonzero(acting)
        if moving.size:
            self._drive(state, moving)
            self._scan(state, moving)
            self._follow_first_copy(state, moving, restarted=False)
        return state

    def _gated_fix(self, state: MapState, copy: int, subset: np.ndarray):
        """Register ``copy``'s returns ``subset``; the fix's residual and covariance to fuse, or None if it is refused
        (no fix, or its NIS beyond ``gate_nis``); its NIS, its NEES against the truth and whether it failed."""
        fix = self._register(state, copy, subset)
        state.refused[copy] = True
        if fix is None:
            return None
        residual = fix.pose - state.x[copy]
        residual[2] = wrap_angle(residual[2])
        state.nis[copy] = float(residual @ np.linalg.solve(state.P[copy] + fix.covariance, residual))
        if state.nis[copy] > self.config["gate_nis"]:
            return None
        error = fix.pose - state.worlds.poses[copy, 0]
        error[2] = wrap_angle(error[2])
        state.fix_nees[copy] = float(error @ np.linalg.solve(fix.covariance, error))
        state.failed[copy] = state.fix_nees[copy] > FAILURE_SIGMAS**2
        state.residual_variance[copy] = fix.residual_std_m**2
        state.refused[copy], state.fused[copy] = False, True
        return residual, fix.covariance, True

    def _register(self, state: MapState, copy: int, subset: np.ndarray):
        """The ``MapFix`` of ``copy``'s returns ``subset`` from its estimate, or None (``register_to_map``)."""
        cfg = self.config
        return register_to_map(
            state.points[copy][subset],
            state.maps[copy],
            self._sensor_at_estimate(state, copy),
            self.ladar.mount_height_m,
            cfg["map_feature_offset_std_m"],
            max_iterations=cfg["icp_max_iterations"],
            max_correspondence_distance=cfg["max_correspondence_distance_m"],
        )

    def _sensor_at_estimate(self, state: MapState, copy: int) -> np.ndarray:
        """``map_from_sensor`` of ``copy``'s vehicle at its estimate, on the map's ground, at its scan's attitude."""
        estimate, prior = state.x[copy], state.maps[copy]
        ground = float(prior.terrain.height_at(estimate[:2]))
        return sensor_pose_on_map(estimate, state.scans[copy].attitude_rad, ground, self.ladar.mount_height_m)

    def _drive(self, state: MapState, copies: np.ndarray) -> None:
        """Drive ``copies`` one step along their routes; the EKF predicts from their noisy odometry."""
        dt = float(self.config["time_step_s"])
        controls = state.worlds.step(dt, copies)
        readings = np.array(
            [
                self.odometry.measure(controls[row, 0], state.odometry_rngs[copy])
                for row, copy in enumerate(copies.tolist())
            ]
        )
        covariances = np.tile(self.odometry.noise_covariance(), (len(copies), 1, 1, 1))
        x, P = predict_poses(state.x[copies], state.P[copies], readings[:, None], dt, covariances)
        state.x[copies], state.P[copies] = x, P

    def _follow_first_copy(self, state: MapState, rows: np.ndarray, restarted: bool) -> None:
        if self.drawing and rows[0] == 0:
            points = (state.worlds.poses[0, 0, :2], state.x[0, :2])
            state.paths = extended_paths(state.paths, points, restarted)

    def reward(self, decision, action, state: MapState) -> np.ndarray:
        """The realized MI of each copy's fused fix [nats] plus its point cost."""
        return state.mutual_information + state.cost

    def observation(self, state: MapState, decision: Decision, rows) -> np.ndarray:
        """Per action: valid, its expected gain [nats, clipped at ``MAX_GAIN``] and the fraction of the returns it
        registers; then the position's largest std [m, clipped], the heading's std [rad], the fraction of the
        horizon elapsed and whether the last step fused a fix."""
        counts = state.point_counts[rows]
        fraction = counts / np.maximum(counts[:, 1:2], 1)
        actions = np.stack(
            [decision.action_mask, np.minimum(decision.action_information_gain, MAX_GAIN), fraction], axis=-1
        )
        P = state.P[rows]
        position_std = np.sqrt(np.linalg.eigvalsh(P[:, :2, :2])[:, -1])
        pose = np.stack(
            [
                np.minimum(position_std, MAX_POSITION_STD_M),
                np.minimum(np.sqrt(P[:, 2, 2]), math.pi),
                state.elapsed[rows] / self.config["horizon"],
                state.fused[rows],
            ],
            axis=1,
        )
        return np.concatenate([actions.reshape(len(pose), -1), pose], axis=1).astype(np.float32)

    def info(self, state: MapState, decision: Decision, rows, stepped) -> dict:
        """The decision, both reward terms, the pose estimate against the truth and the step's registration."""
        terms = np.stack([state.mutual_information[rows], state.cost[rows]])
        info = decision_info(decision, stepped, state.chosen[rows], self.traits.reward_terms, terms)
        truth, estimate = state.worlds.poses[rows, 0].copy(), state.x[rows].copy()
        entropy = gaussian_entropy_from_log_det(log_det_spd(state.P[rows], check_input=False), 3)
        info.update(
            pose_entropy=entropy,
            state_entropy=entropy.copy(),
            position_error_m=np.hypot(*(estimate[:, :2] - truth[:, :2]).T),
            heading_error_rad=np.abs(wrap_angle(estimate[:, 2] - truth[:, 2])),
            estimated_pose=estimate,
            true_pose=truth,
            time_s=state.elapsed[rows] * self.config["time_step_s"],
            fused=state.fused[rows] & stepped,
            refused=state.refused[rows] & stepped,
            registered_points=np.where(stepped, state.registered_points[rows], 0),
            registration_nees=np.where(stepped & state.fused[rows], state.fix_nees[rows], 0.0),
            registration_failed=state.failed[rows] & stepped,
            nis=np.where(stepped & np.isfinite(state.nis[rows]), state.nis[rows], 0.0),
        )
        return info

    def frame(self, state: MapState, decision: Decision):
        """Copy 0: its scene, its map's features, the vehicle's truth and estimate, and its newest range image."""
        cfg, scenario = self.config, state.worlds.scenario(0)
        mapped = state.maps[0].terrain
        features = np.array(
            [c.center_m for c in mapped.cylinders]
            + [np.add(b.min_corner_m[:2], b.max_corner_m[:2]) / 2 for b in mapped.boxes]
        ).reshape(-1, 2)
        pose = state.worlds.poses[0, 0].copy()
        chosen = int(state.chosen[0])
        caption = f"t = {state.elapsed[0] * cfg['time_step_s']:.1f} s   "
        caption += f"registered: {self.actions[chosen] if chosen >= 0 else 'none'}"
        if state.fused[0]:
            caption += f" (fused, {state.mutual_information[0]:.2f} nats)"
        elif state.refused[0]:
            caption += " (refused)"
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            robots=[
                RobotDrawing(
                    true_pose=pose,
                    estimated_pose=state.x[0].copy(),
                    pose_covariance=state.P[0].copy(),
                    true_path=state.paths[0].points(),
                    estimated_path=state.paths[1].points(),
                )
            ],
            landmark_estimates=features,
            landmark_covariances=np.tile(cfg["map_feature_offset_std_m"] ** 2 * np.eye(2), (len(features), 1, 1)),
            landmark_estimate_label="map feature (missing, misplaced or extra)",
            sensor_wedge=(float(pose[2]), self.ladar.horizontal_fov_rad, SENSOR_WEDGE_LENGTH_M),
            inset_image=to_display_image(state.scans[0]),
            inset_title="newest LADAR range image (dark = near, white = no return)",
            caption=caption,
        )


class MapRegistrationVectorEnv(Driver, scenario=MapRegistration):
    """N copies of ``infonav/MapRegistration-v0``, the driver bound to its scenario (``gym.make_vec``).

    Scans and registrations run copy by copy.
    """


class MapRegistrationEnv(SingleEnvView, vector_env=MapRegistrationVectorEnv):
    """A GPS-denied vehicle registers LADAR scans to an a-priori map of its terrain; the agent picks what to register.

    ## Description
    The vehicle drives a closed route (Pymunk) through a random 2.5D scene (hills, trees, rocks, buildings), its roll
    and pitch following the ground. An EKF tracks its planar pose on the map from odometry. It holds a map of the
    terrain made as real prior maps are: heights every ``map_cell_m`` with errors of ``map_height_std_m``, its
    features (trees, rocks, buildings) misplaced by ``map_feature_offset_std_m`` each, a ``map_missing_fraction``
    of them missing and ``map_extra_features`` that are not there. Each step the vehicle takes a LADAR scan (32 x
    180) and the agent chooses which of its returns to register to the map: none, all, one azimuth sector, the
    returns the map places on the ground or on its features, or the control points the fix leans on most.
    Point-to-plane ICP from the estimate gives the pose on the map; its covariance is ICP's sandwich covariance
    under the map's errors (``registration.map_registration``); the EKF fuses it unless its NIS exceeds
    ``gate_nis``.

    ``info["action_information_gain"]`` is the MI a fix of each choice would bring about the pose, from the map's
    predicted matches at the estimate: ``0.5 ln det(P + R_k) / det(R_k)``.

    ## Action Space
    ``Discrete(5 + n_sectors)``: ``action_names(n_sectors)``.

    ## Observation Space
    ``Box(float32, (3 * actions + 4,))``: per action valid, expected gain [nats, clipped at 50] and the fraction of
    the returns it registers; then the position's largest std [m], the heading's std [rad], the fraction of the
    horizon elapsed and whether the last step fused a fix.

    ## Rewards
    The realized MI of the fused fix [nats] minus ``point_cost`` per registered return.

    ## Starting State
    The vehicle at the start of its route, its estimate off by ``initial_position_std_m`` and
    ``initial_heading_std_rad``.

    ## Episode End
    Truncated after ``horizon`` steps; never terminated.

    ## Arguments
    ``gym.make("infonav/MapRegistration-v0", render_mode=None, **config)`` with any key of ``default_config()``.

    ## Version History
    * v0: initial version.
    """
