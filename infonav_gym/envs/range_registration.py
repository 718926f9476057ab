"""``infonav/RangeRegistration-v0``: which control-point patches feed ICP (the paper's Section V)."""

from __future__ import annotations

import time

import numpy as np
from gymnasium import spaces

from infonav_gym.config import Interval, check_choice, check_config, config_keys, from_config
from infonav_gym.envs.base import Decision, InfoNavEnv
from infonav_gym.envs.metrics import EpisodeMetric, mean_where, summed_reward
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.information import information_gain_of_information
from infonav_gym.registration.control_points import control_point_geometry
from infonav_gym.registration.frame_pairs import (
    DEFAULT_ODOMETRY_STD,
    FRAME_PAIR_ICP,
    check_odometry_std,
    frame_pair,
    registration_error,
    scan_on_terrain,
)
from infonav_gym.registration.gicp import gicp_covariances
from infonav_gym.registration.icp import METHODS, icp
from infonav_gym.registration.robust_kernels import ROBUST_KERNELS
from infonav_gym.scene import SENSOR_WEDGE_LENGTH_M, PathHistory, RobotDrawing, SceneFrame
from infonav_gym.sensors.ladar import Ladar, sensor_points, to_display_image
from infonav_gym.world.terrain_scenario import SCENE_CONFIG, check_scene_config, terrain_loop_from_config
from infonav_gym.world.world import TIME_STEP_S, World

MIN_CONTROL_POINTS = 3  # fewer cannot fix a rigid motion
GLOBAL_FEATURES = 2
MAX_PATCH_INFORMATION = 50.0  # observation bound of a patch's information [nats]
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses (patches: see __init__)
    "time_step_s": TIME_STEP_S,
    "point_cost": Interval(0.0, 1e3, unit="m per control point"),
    "icp_max_iterations": Interval(1, 10**4, integer=True),
    "max_correspondence_distance_m": Interval(0.0, 100.0, open_low=True, unit="m"),
    "icp_kernel_scale_m": Interval(0.0, 100.0, open_low=True, unit="m"),
}
ODOMETRY_KEYS = {  # the config key of each axis of the odometry error (frame_pair's odometry_std)
    "x": "odometry_xy_std_m",
    "y": "odometry_xy_std_m",
    "z": "odometry_z_std_m",
    "roll": "odometry_tilt_std_rad",
    "pitch": "odometry_tilt_std_rad",
    "yaw": "odometry_yaw_std_rad",
}


class RangeRegistrationEnv(InfoNavEnv):
    """A vehicle pitches and rolls over rugged terrain; per pair of LADAR frames the agent picks ICP's control points.

    ## Description
    The vehicle drives a closed route (Pymunk) through a random 2.5D scene at 1 m per
    frame; its roll and pitch follow the ground under its wheels. For each pair of
    consecutive LADAR frames (32 x 180) the odometry gives a noisy estimate of the motion
    between them with covariance ``P`` (6 x 6 over x, y, z and the rotations about them).
    The agent picks ``picks_per_pair`` patches of the newer frame's range image, one per
    step; then ICP (``icp``, warm-started at the odometry estimate) registers the points of
    the chosen patches onto the whole older frame. Correspondence search is the expensive
    part of ICP, so every control point costs ``point_cost``.

    ``info["action_information_gain"]`` is the mutual information a patch adds about the
    motion, given the patches already chosen for this pair: with point-to-plane Jacobians
    ``J_i`` and residual error standard deviations ``sigma_i`` (``control_point_geometry``,
    taken as independent here), a set ``S`` brings
    ``0.5 ln det(I + P sum_{i in S} J_i^T J_i / sigma_i^2)`` nats, the landmark-selection
    criterion of Section III applied to control points. A greedy-entropy agent therefore
    picks the most informative patch that complements the ones it has.

    ## Action Space
    ``Discrete(patch_rows * patch_columns)``: the patch (row-major over the image) to add.
    Valid while it has returns and was not chosen for this pair (``info["action_mask"]``).
    A masked action is a no-op with reward 0 (``invalid_action="noop"``) or raises
    ``ValueError`` (``invalid_action="raise"``). ``action_masks()`` gives the mask as bool, for
    ``MaskablePPO`` (all ``True`` when no patch can be picked: every action is then the no-op).

    ## Observation Space
    ``Box(float32, (5 * patches + 2,))``: per patch: valid, chosen, fraction of its pixels
    with a return, mean range over the maximum range, and its information alone [nats,
    clipped at 50]; then the fraction of this pair's picks made and of the horizon elapsed.

    ## Rewards
    0 while picking. At the last pick of a pair: how much ICP reduced the registration error
    [m] (``registration_error``: translation error combined with the rotation error's
    displacement 10 m away), minus ``point_cost`` times the number of control points.

    ## Starting State
    The vehicle at the start of its route; the first pair is its first two frames.

    ## Episode End
    Truncated after ``horizon`` steps (``horizon / picks_per_pair`` frame pairs); never terminated.

    ## Arguments
    ``gym.make("infonav/RangeRegistration-v0", render_mode=None, **config)`` with any key of
    ``default_config()``; an unknown key raises ``ValueError`` naming it.

    ## Version History
    * v0: initial version.
    """

    episode_metrics = (
        EpisodeMetric("cumulative_reward", "cumulative reward [m]", summed_reward),
        EpisodeMetric(
            "mean_error_after_m",
            "registration error after ICP [m]",
            mean_where("error_after_m", lambda info: info["registered"]),
        ),
        EpisodeMetric(
            "mean_control_points",
            "control points per frame pair",
            mean_where("n_control_points", lambda info: info["registered"]),
        ),
    )
    traits = EnvTraits(
        valid_gain_may_be_zero=True,  # a patch may hold no usable control point
        reward_terms=("error_reduction_m", "point_cost"),
        info_keys=frozenset(
            {"registered", "error_before_m", "error_after_m", "icp_iterations", "icp_time_s", "n_control_points"}
        ),
    )

    @classmethod
    def default_config(cls) -> dict:
        return {
            **super().default_config(),
            "horizon": 60,  # steps: 15 frame pairs of 4 picks
            "picks_per_pair": 4,  # patches chosen before ICP runs
            "patch_rows": 4,
            "patch_columns": 9,
            "point_cost": 1e-4,  # cost of one control point [m of registration error]
            "time_step_s": 0.5,  # between frames [s]
            "speed_mps": 2.0,  # [m/s]
            **SCENE_CONFIG,  # the terrain_loop scene
            "odometry_xy_std_m": DEFAULT_ODOMETRY_STD[0],  # std of the odometry's motion error along x and y [m]
            "odometry_z_std_m": DEFAULT_ODOMETRY_STD[2],  # ... along z [m]
            "odometry_tilt_std_rad": DEFAULT_ODOMETRY_STD[3],  # ... about x and y (inclinometers) [rad]
            "odometry_yaw_std_rad": DEFAULT_ODOMETRY_STD[5],  # ... about z [rad]
            "icp_method": FRAME_PAIR_ICP["method"],
            "icp_robust_kernel": FRAME_PAIR_ICP["robust_kernel"] or "none",  # "none" or one of ROBUST_KERNELS
            "icp_kernel_scale_m": FRAME_PAIR_ICP["kernel_scale"],  # [m]
            "icp_max_iterations": 30,
            "max_correspondence_distance_m": FRAME_PAIR_ICP["max_correspondence_distance"],
            "ladar_range_std_m": Ladar().range_std_m,
        }

    def __init__(self, render_mode: str | None = None, **config):
        super().__init__(render_mode=render_mode, **config)
        cfg, owner = self.config, type(self).__name__
        check_choice(cfg, "icp_method", METHODS, owner)
        check_choice(cfg, "icp_robust_kernel", ("none", *ROBUST_KERNELS), owner)
        check_config(cfg, owner, CONFIG_INTERVALS)
        check_scene_config(cfg, owner)
        with config_keys(owner, ODOMETRY_KEYS):
            self.odometry_std = check_odometry_std([cfg[key] for key in ODOMETRY_KEYS.values()])
        self.ladar = from_config(Ladar, cfg, {"range_std_m": "ladar_range_std_m"}, owner)
        patches = {"patch_rows": self.ladar.rows, "patch_columns": self.ladar.columns}  # at most the image's pixels
        check_config(cfg, owner, {key: Interval(1, pixels, integer=True) for key, pixels in patches.items()})
        self.n_patches = cfg["patch_rows"] * cfg["patch_columns"]
        check_config(cfg, owner, {"picks_per_pair": Interval(1, self.n_patches, integer=True)})
        self.action_space = spaces.Discrete(self.n_patches)
        high = np.tile([1.0, 1.0, 1.0, 1.0, MAX_PATCH_INFORMATION], self.n_patches)
        high = np.append(high, [1.0, 1.0]).astype(np.float32)
        self.observation_space = spaces.Box(np.zeros_like(high), high, dtype=np.float32)
        self.world = World()
        rows, columns = np.indices((self.ladar.rows, self.ladar.columns))
        patch_row = rows * cfg["patch_rows"] // self.ladar.rows
        self._pixel_patch = patch_row * cfg["patch_columns"] + columns * cfg["patch_columns"] // self.ladar.columns

    def _reset_episode(self) -> None:
        cfg = self.config
        scene = terrain_loop_from_config(self.np_random, cfg)
        self.terrain = scene.terrain
        self.world.reset(scene.scenario)
        self._sensor_rng, self._odometry_rng = self.np_random.spawn(2)
        self._current_frame = self._scan()
        self._true_path = PathHistory(self.world.pose[:2])
        self.last_registration = None
        self._registered_now = False
        self._covariances = {}
        self._next_pair()

    def _scan(self):
        return scan_on_terrain(self.ladar, self.terrain, self.world.pose, self._sensor_rng)

    def _next_pair(self) -> None:
        """Drive one frame on and set up the pair (previous frame, new frame) and its odometry estimate."""
        previous = self._current_frame
        self.world.step(self.config["time_step_s"])
        self._true_path.append(self.world.pose[:2])
        self._current_frame = self._scan()
        self.pair = frame_pair(previous, self._current_frame, self._odometry_rng, self.odometry_std)
        geometry = control_point_geometry(self._current_frame, self.pair.motion_covariance)
        returns = ~self._current_frame.no_return
        patch_of_return = self._pixel_patch[returns]
        self._source_points = sensor_points(self._current_frame)
        self._target_points = sensor_points(previous)
        self._covariances = {"target": self._covariances.get("source")}  # GICP's, by frame (_gicp_covariances)
        self._patch_of_return = patch_of_return
        error_std = geometry.error_std_m
        informative = np.isfinite(error_std)
        weighted = geometry.jacobians / np.where(informative, error_std, 1.0)[:, None]
        self._patch_information = np.zeros((self.n_patches, 6, 6))
        np.add.at(
            self._patch_information,
            patch_of_return[informative],
            weighted[informative, :, None] * weighted[informative, None, :],
        )
        self._prior_root = np.linalg.cholesky(self.pair.motion_covariance)
        pixels_per_patch = np.bincount(self._pixel_patch.ravel(), minlength=self.n_patches)
        self._return_fraction = np.bincount(patch_of_return, minlength=self.n_patches) / pixels_per_patch
        range_sum = np.bincount(patch_of_return, self._current_frame.ranges_m[returns], minlength=self.n_patches)
        self._mean_range = range_sum / np.maximum(1, np.bincount(patch_of_return, minlength=self.n_patches))
        self._chosen = np.zeros(self.n_patches, dtype=bool)
        self._pair_done = False
        self._patch_alone = np.array([self._mutual_information(info) for info in self._patch_information])

    def _mutual_information(self, information: np.ndarray) -> float:
        """``0.5 ln det(I + P A)`` [nats] of information ``A`` about the motion, with the pair's prior ``P``."""
        return information_gain_of_information(self._prior_root, information)

    def _next_decision(self) -> Decision:
        mask = ((self._return_fraction > 0) & ~self._chosen).astype(np.int8)
        chosen_information = self._patch_information[self._chosen].sum(axis=0)
        base = self._mutual_information(chosen_information)
        gains = np.zeros(self.n_patches)
        for patch in np.flatnonzero(mask):
            gains[patch] = self._mutual_information(chosen_information + self._patch_information[patch]) - base
        return Decision(mask, gains)

    def _apply_action(self, action: int | None, decision: Decision) -> dict:
        self._registered_now = False
        if action is None:
            return {"error_reduction_m": 0.0, "point_cost": 0.0}
        self._chosen[action] = True
        if self._chosen.sum() < self.config["picks_per_pair"] and self._next_mask_has_choice():
            return {"error_reduction_m": 0.0, "point_cost": 0.0}
        return self._register()

    def _next_mask_has_choice(self) -> bool:
        return bool(np.any((self._return_fraction > 0) & ~self._chosen))

    def _register(self) -> dict:
        """Run ICP on the chosen patches' points; the reward terms of the pair."""
        cfg, pair = self.config, self.pair
        source = self._source_points[self._chosen[self._patch_of_return]]
        before = registration_error(pair.odometry_motion, pair.true_motion)
        start = time.perf_counter()
        if len(source) >= MIN_CONTROL_POINTS:
            kernel = None if cfg["icp_robust_kernel"] == "none" else cfg["icp_robust_kernel"]
            result = icp(
                source,
                self._target_points,
                pair.odometry_motion,
                max_iterations=cfg["icp_max_iterations"],
                max_correspondence_distance=cfg["max_correspondence_distance_m"],
                method=cfg["icp_method"],
                robust_kernel=kernel,
                kernel_scale=cfg["icp_kernel_scale_m"],
                **self._gicp_covariances(),
            )
            transform, iterations, converged = result.transform, result.iterations, result.converged
        else:  # too few points to register: keep the odometry estimate
            transform, iterations, converged = pair.odometry_motion, 0, False
        elapsed = time.perf_counter() - start
        after = registration_error(transform, pair.true_motion)
        self.last_registration = {
            "error_before_m": before,
            "error_after_m": after,
            "icp_iterations": iterations,
            "icp_converged": converged,
            "icp_time_s": elapsed,
            "n_control_points": len(source),
            "transform": transform.copy(),
        }
        self._pair_done = self._registered_now = True
        return {"error_reduction_m": before - after, "point_cost": -cfg["point_cost"] * len(source)}

    def _gicp_covariances(self) -> dict:
        """For GICP, the covariances of the chosen returns (from the whole frame) and of the previous frame.

        Each frame's are computed once: as the current frame's, then kept for the next pair, whose target it is.
        """
        if self.config["icp_method"] != "gicp":
            return {}
        for name, points in (("source", self._source_points), ("target", self._target_points)):
            if self._covariances.get(name) is None:
                self._covariances[name] = gicp_covariances(points)
        chosen = self._chosen[self._patch_of_return]
        return {
            "source_covariances": self._covariances["source"][chosen],
            "target_covariances": self._covariances["target"],
        }

    def _advance(self) -> None:
        if self._pair_done:
            self._next_pair()

    def _observation(self) -> np.ndarray:
        valid = (self._return_fraction > 0) & ~self._chosen
        patches = np.stack(
            [
                valid,
                self._chosen,
                self._return_fraction,
                self._mean_range / self.ladar.max_range_m,
                np.minimum(self._patch_alone, MAX_PATCH_INFORMATION),
            ],
            axis=1,
        )
        progress = [self._chosen.sum() / self.config["picks_per_pair"], self._elapsed_steps / self.config["horizon"]]
        return np.append(patches.ravel(), progress).astype(np.float32)

    def _extra_info(self) -> dict:
        last = self.last_registration or {}
        return {
            "registered": self._registered_now,
            "error_before_m": last.get("error_before_m", 0.0),
            "error_after_m": last.get("error_after_m", 0.0),
            "icp_iterations": last.get("icp_iterations", 0),
            "icp_time_s": last.get("icp_time_s", 0.0),
            "n_control_points": last.get("n_control_points", 0),
            "odometry_error_m": registration_error(self.pair.odometry_motion, self.pair.true_motion),
            "motion_covariance": self.pair.motion_covariance.copy(),
            "true_pose": self.world.pose.copy(),
            "attitude_rad": np.array(self._current_frame.attitude_rad),
            "time_s": self._elapsed_steps * self.config["time_step_s"],
        }

    def _scene_frame(self):
        cfg, scenario, pose = self.config, self.world.scenario, self.world.pose
        caption = f"t = {self._elapsed_steps * cfg['time_step_s']:.1f} s   "
        caption += f"picked {int(self._chosen.sum())}/{cfg['picks_per_pair']} patches"
        if self.last_registration is not None:
            last = self.last_registration
            caption += f"   last ICP: error {last['error_before_m']:.3f} -> {last['error_after_m']:.3f} m"
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            robots=[RobotDrawing(true_pose=pose, true_path=self._true_path.points())],
            sensor_wedge=(float(pose[2]), self.ladar.horizontal_fov_rad, SENSOR_WEDGE_LENGTH_M),
            inset_image=to_display_image(self._current_frame),
            inset_title="newest LADAR range image (dark = near, white = no return); red: patches picked for ICP",
            inset_grid=(cfg["patch_rows"], cfg["patch_columns"]),
            inset_highlights=np.flatnonzero(self._chosen).tolist(),
            caption=caption,
        )
