"""``infonav/RangeRegistration-v0``: which control-point patches feed ICP (the paper's Section V), as a scenario."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from infonav_gym.config import Interval, check_choice, check_config, config_keys, from_config
from infonav_gym.envs.base import shared_config
from infonav_gym.envs.driver import Driver
from infonav_gym.envs.metrics import EpisodeMetric, mean_where, summed_reward
from infonav_gym.envs.protocol import EnvScenario, State
from infonav_gym.envs.single_view import SingleEnvView
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.envs.vector_infos import Decision, decision_info, reward_term_key
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
from infonav_gym.registration.icp import METHODS, check_kernel_method, icp
from infonav_gym.registration.robust_kernels import ROBUST_KERNELS
from infonav_gym.scene import SENSOR_WEDGE_LENGTH_M, PathHistory, RobotDrawing, SceneFrame
from infonav_gym.sensors.ladar import Ladar, sensor_points, to_display_image
from infonav_gym.world.physics import TIME_STEP_S
from infonav_gym.world.terrain_scenario import SCENE_CONFIG, check_scene_config, terrain_loop_from_config
from infonav_gym.world.world_batch import WorldBatch

MIN_CONTROL_POINTS = 3  # fewer cannot fix a rigid motion
MAX_PATCH_INFORMATION = 50.0  # observation bound of a patch's information [nats]
PATCH_KB = 1.2  # [kB] a copy's memory per control-point patch, measured from 4 x 9 to 32 x 180 patches
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
REGISTRATION = np.dtype(  # what each copy's last ICP run gave (zeros before its first in an episode)
    [
        ("error_before_m", float),
        ("error_after_m", float),
        ("icp_iterations", np.int64),
        ("icp_time_s", float),
        ("n_control_points", np.int64),
        ("transform", float, (4, 4)),
    ]
)


@dataclass
class RegistrationState(State):
    """Every copy's vehicle (``worlds``), terrain, generators (sensor, odometry), newest LADAR frame (its pair's
    source), current ``FramePair``, the points of its newest frame and of the one before, the patch of each return of
    the newest frame and GICP's covariances by frame (``_gicp_covariances``); per patch its Fisher information about
    the motion (N, P, 6, 6), its information alone (N, P) [nats], fraction of returns, mean range [m] and whether it
    is picked for the pair (N, P); the Cholesky factor of the pair's motion covariance (N, 6, 6), the odometry error
    (N,) [m] and the newest frame's roll and pitch (N, 2) [rad]; whether it registered its pair at the last step, its
    last ICP run (``REGISTRATION``), its last action (N,) (-1: none) and the step's reward terms (N,) [m]; copy 0's
    true path (``paths``, when drawing)."""

    worlds: WorldBatch
    terrains: list
    sensor_rngs: list
    odometry_rngs: list
    frames: list
    pairs: list
    source_points: list
    target_points: list
    patch_of_return: list
    covariances: list
    patch_information: np.ndarray
    prior_root: np.ndarray
    patch_alone: np.ndarray
    return_fraction: np.ndarray
    mean_range: np.ndarray
    odometry_error: np.ndarray
    attitude: np.ndarray
    picked: np.ndarray
    registered: np.ndarray
    last_registration: np.ndarray
    chosen: np.ndarray
    reduction: np.ndarray
    cost: np.ndarray
    paths: tuple[PathHistory] | None = None


class RangeRegistration(EnvScenario):
    """``infonav/RangeRegistration-v0`` as a scenario (spaces, reward, config: ``RangeRegistrationEnv``)."""

    episode_metrics = (
        EpisodeMetric("cumulative_reward", "cumulative reward [m]", summed_reward),
        EpisodeMetric(
            "mean_error_after_m",
            "registration error after ICP [m]",
            mean_where("error_after_m", lambda info: info["registered"]),
        ),
        EpisodeMetric(
            "mean_control_points",
            "control points per frame pair [points]",
            mean_where("n_control_points", lambda info: info["registered"]),
        ),
    )
    traits = EnvTraits(
        kb_per_copy=900,  # [kB] at the defaults, between peak RSS growth and traced allocations
        valid_gain_may_be_zero=True,  # a patch may hold no usable control point
        reward_terms=("error_reduction_m", "point_cost"),
        main_metric="cumulative_reward",
        reward_unit="m",
        info_keys=frozenset(
            {"registered", "error_before_m", "error_after_m", "icp_iterations", "icp_time_s", "n_control_points"}
        ),
    )

    @classmethod
    def default_config(cls) -> dict:
        return {
            **shared_config(),
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

    @classmethod
    def copy_kb(cls, config: dict) -> float:
        """``kb_per_copy`` and ``PATCH_KB`` a patch beyond the default's (at most one per pixel of the LADAR)."""
        defaults = cls.default_config()
        patches = min(config["patch_rows"], Ladar.rows) * min(config["patch_columns"], Ladar.columns)
        more_patches = patches - defaults["patch_rows"] * defaults["patch_columns"]
        return cls.traits.kb_per_copy + PATCH_KB * max(more_patches, 0)

    def __init__(self, config: dict, copies: int, owner: str, render_mode: str | None):
        super().__init__(config, copies, owner, render_mode)
        cfg = config
        check_choice(cfg, "icp_method", METHODS, owner)
        check_choice(cfg, "icp_robust_kernel", ("none", *ROBUST_KERNELS), owner)
        self.robust_kernel = None if cfg["icp_robust_kernel"] == "none" else cfg["icp_robust_kernel"]
        try:  # icp()'s rule, checked now rather than at the first registration
            check_kernel_method(self.robust_kernel, cfg["icp_method"])
        except ValueError as error:
            raise ValueError(f"config keys 'icp_robust_kernel' and 'icp_method' of {owner}: {error}") from None
        check_config(cfg, owner, CONFIG_INTERVALS)
        check_scene_config(cfg, owner)
        with config_keys(owner, ODOMETRY_KEYS):
            self.odometry_std = check_odometry_std([cfg[key] for key in ODOMETRY_KEYS.values()])
        self.ladar = from_config(Ladar, cfg, {"range_std_m": "ladar_range_std_m"}, owner)
        patches = {"patch_rows": self.ladar.rows, "patch_columns": self.ladar.columns}  # at most the image's pixels
        check_config(cfg, owner, {key: Interval(1, pixels, integer=True) for key, pixels in patches.items()})
        self.n_patches = n_patches = cfg["patch_rows"] * cfg["patch_columns"]
        check_config(cfg, owner, {"picks_per_pair": Interval(1, n_patches, integer=True)})
        high = np.tile([1.0, 1.0, 1.0, 1.0, MAX_PATCH_INFORMATION], n_patches)
        high = np.append(high, [1.0, 1.0]).astype(np.float32)
        self.observation_space = spaces.Box(np.zeros_like(high), high, dtype=np.float32)
        self.action_space = spaces.Discrete(n_patches)
        rows, columns = np.indices((self.ladar.rows, self.ladar.columns))
        patch_row = rows * cfg["patch_rows"] // self.ladar.rows
        self.pixel_patch = patch_row * cfg["patch_columns"] + columns * cfg["patch_columns"] // self.ladar.columns
        self.pixels_per_patch = np.bincount(self.pixel_patch.ravel(), minlength=n_patches)

    def allocate(self, copies: int) -> RegistrationState:
        n_patches = self.n_patches
        return RegistrationState(
            elapsed=np.zeros(copies, dtype=int),
            worlds=WorldBatch(copies),
            **{name: [None] * copies for name in ("terrains", "sensor_rngs", "odometry_rngs", "frames", "pairs")},
            **{name: [None] * copies for name in ("source_points", "target_points", "patch_of_return")},
            covariances=[{} for _ in range(copies)],
            patch_information=np.zeros((copies, n_patches, 6, 6)),
            prior_root=np.zeros((copies, 6, 6)),
            **{name: np.zeros((copies, n_patches)) for name in ("patch_alone", "return_fraction", "mean_range")},
            **{name: np.zeros(copies) for name in ("odometry_error", "reduction", "cost")},
            attitude=np.zeros((copies, 2)),
            picked=np.zeros((copies, n_patches), dtype=bool),
            registered=np.zeros(copies, dtype=bool),
            last_registration=np.zeros(copies, dtype=REGISTRATION),
            chosen=np.full(copies, -1),
        )

    def initial(self, state: RegistrationState, rows: np.ndarray, rngs: list) -> RegistrationState:
        """Draw each copy's terrain loop, spawn its sensor and odometry generators and scan its first frame; then
        its first pair."""
        for copy, rng in zip(rows.tolist(), rngs):
            scene = terrain_loop_from_config(rng, self.config)
            state.worlds.reset_copy(copy, scene.scenario)
            state.sensor_rngs[copy], state.odometry_rngs[copy] = rng.spawn(2)
            state.terrains[copy] = scene.terrain
            state.frames[copy] = self._scan(state, copy)
            state.covariances[copy] = {}
        state.registered[rows] = False
        state.last_registration[rows] = 0
        state.chosen[rows], state.reduction[rows], state.cost[rows] = -1, 0.0, 0.0
        if self.drawing and rows[0] == 0:
            state.paths = (PathHistory(state.worlds.poses[0, 0, :2]),)
        self._next_pairs(state, rows)
        return state

    def _scan(self, state: RegistrationState, copy: int):
        pose = state.worlds.poses[copy, 0].copy()
        return scan_on_terrain(self.ladar, state.terrains[copy], pose, state.sensor_rngs[copy])

    def _next_pairs(self, state: RegistrationState, copies: np.ndarray) -> None:
        """Drive ``copies`` one frame on; each one's pair (previous frame, new frame), odometry estimate and patches."""
        state.worlds.step(self.config["time_step_s"], copies)
        if self.drawing and copies[0] == 0:
            state.paths[0].append(state.worlds.poses[0, 0, :2])
        n_patches = self.n_patches
        for copy in copies.tolist():
            previous, current = state.frames[copy], self._scan(state, copy)
            pair = frame_pair(previous, current, state.odometry_rngs[copy], self.odometry_std)
            geometry = control_point_geometry(current, pair.motion_covariance)
            returns = ~current.no_return
            patch_of_return = self.pixel_patch[returns]
            state.frames[copy], state.pairs[copy], state.patch_of_return[copy] = current, pair, patch_of_return
            state.source_points[copy], state.target_points[copy] = sensor_points(current), sensor_points(previous)
            state.covariances[copy] = {"target": state.covariances[copy].get("source")}
            informative = np.isfinite(geometry.error_std_m)
            weighted = geometry.jacobians[informative] / geometry.error_std_m[informative, None]
            information = state.patch_information[copy]
            information[:] = 0.0
            np.add.at(information, patch_of_return[informative], weighted[:, :, None] * weighted[:, None, :])
            state.prior_root[copy] = np.linalg.cholesky(pair.motion_covariance)
            returns_per_patch = np.bincount(patch_of_return, minlength=n_patches)
            state.return_fraction[copy] = returns_per_patch / self.pixels_per_patch
            range_sum = np.bincount(patch_of_return, current.ranges_m[returns], minlength=n_patches)
            state.mean_range[copy] = range_sum / np.maximum(1, returns_per_patch)
            state.odometry_error[copy] = registration_error(pair.odometry_motion, pair.true_motion)
            state.attitude[copy] = current.attitude_rad
        state.picked[copies] = False
        roots = state.prior_root[copies, None]
        state.patch_alone[copies] = information_gain_of_information(roots, state.patch_information[copies])

    def decision(self, state: RegistrationState, rows) -> Decision:
        """The decisions of the copies ``rows``: each valid patch's MI added to the patches picked for the pair."""
        picked, information = state.picked[rows], state.patch_information[rows]
        mask = (state.return_fraction[rows] > 0) & ~picked
        picked_information = np.where(picked[..., None, None], information, 0.0).sum(axis=1)
        root = state.prior_root[rows]
        base = information_gain_of_information(root, picked_information)
        added = information_gain_of_information(root[:, None], picked_information[:, None] + information)
        return Decision(mask.astype(np.int8), np.where(mask, added - base[:, None], 0.0))

    def transition(self, state: RegistrationState, decision: Decision, action, acting) -> RegistrationState:
        """Pick the chosen patches; the copies with their pair's picks made register it (the step's reward terms)
        and drive on to the next pair."""
        chosen = action[:, 0]
        picking = np.flatnonzero(chosen >= 0)
        state.picked[picking, chosen[picking]] = True
        left = ((state.return_fraction > 0) & ~state.picked).any(axis=1)
        done = state.picked.sum(axis=1) >= self.config["picks_per_pair"]
        state.registered = (chosen >= 0) & (done | ~left)
        state.chosen, state.reduction, state.cost = chosen, np.zeros(len(chosen)), np.zeros(len(chosen))
        registering = np.flatnonzero(state.registered)
        for copy in registering.tolist():
            state.reduction[copy], state.cost[copy] = self._register(state, copy)
        if registering.size:
            self._next_pairs(state, registering)
        return state

    def _register(self, state: RegistrationState, copy: int) -> tuple[float, float]:
        """Run ICP on the picked patches' points of ``copy``; the pair's reward terms (error reduction, point cost)."""
        cfg, pair = self.config, state.pairs[copy]
        chosen = state.picked[copy][state.patch_of_return[copy]]
        source = state.source_points[copy][chosen]
        before = state.odometry_error[copy]
        start = time.perf_counter()
        if len(source) >= MIN_CONTROL_POINTS:
            result = icp(
                source,
                state.target_points[copy],
                pair.odometry_motion,
                max_iterations=cfg["icp_max_iterations"],
                max_correspondence_distance=cfg["max_correspondence_distance_m"],
                method=cfg["icp_method"],
                robust_kernel=self.robust_kernel,
                kernel_scale=cfg["icp_kernel_scale_m"],
                **self._gicp_covariances(state, copy, chosen),
            )
            transform, iterations = result.transform, result.iterations
        else:  # too few points to register: keep the odometry estimate
            transform, iterations = pair.odometry_motion, 0
        elapsed = time.perf_counter() - start
        after = registration_error(transform, pair.true_motion)
        state.last_registration[copy] = (before, after, iterations, elapsed, len(source), transform)
        return before - after, -cfg["point_cost"] * len(source)

    def _gicp_covariances(self, state: RegistrationState, copy: int, chosen: np.ndarray) -> dict:
        """For GICP, the covariances of the ``chosen`` returns (from the whole frame) and of the previous frame.

        Each frame's are computed once: as the current frame's, then kept for the next pair, whose target it is.
        """
        if self.config["icp_method"] != "gicp":
            return {}
        covariances = state.covariances[copy]
        for name, points in (("source", state.source_points[copy]), ("target", state.target_points[copy])):
            if covariances.get(name) is None:
                covariances[name] = gicp_covariances(points)
        return {"source_covariances": covariances["source"][chosen], "target_covariances": covariances["target"]}

    def reward(self, decision, action, state: RegistrationState) -> np.ndarray:
        """The error reduction of each copy's registration [m] plus its point cost (0 without one)."""
        return state.reduction + state.cost

    def observation(self, state: RegistrationState, decision: Decision, rows) -> np.ndarray:
        """The observations of the copies ``rows`` (n, 5 * P + 2), float32 (see the single env)."""
        picked, cfg = state.picked[rows], self.config
        patches = np.stack(
            [
                decision.action_mask,
                picked,
                state.return_fraction[rows],
                state.mean_range[rows] / self.ladar.max_range_m,
                np.minimum(state.patch_alone[rows], MAX_PATCH_INFORMATION),
            ],
            axis=-1,
        )
        progress = np.stack([picked.sum(axis=1) / cfg["picks_per_pair"], state.elapsed[rows] / cfg["horizon"]], axis=1)
        return np.concatenate([patches.reshape(len(progress), -1), progress], axis=1).astype(np.float32)

    def info(self, state: RegistrationState, decision: Decision, rows, stepped) -> dict:
        """The decision's mask and gains, both reward terms, the action taken, the last ICP run, the pair's odometry
        error and motion covariance, the true pose, the attitude and the time."""
        info = decision_info(decision, stepped, state.chosen[rows], ("error_reduction_m",), state.reduction[None, rows])
        point_cost = np.where(stepped, state.cost[rows], 0.0)
        info[reward_term_key("point_cost")] = point_cost
        last = state.last_registration[rows]
        info.update({name: last[name].copy() for name in REGISTRATION.names if name != "transform"})
        pairs = state.pairs if isinstance(rows, slice) else [state.pairs[copy] for copy in rows.tolist()]
        info.update(
            registered=state.registered[rows].copy(),
            odometry_error_m=state.odometry_error[rows].copy(),
            motion_covariance=np.array([pair.motion_covariance for pair in pairs]),
            true_pose=state.worlds.poses[rows, 0].copy(),
            attitude_rad=state.attitude[rows].copy(),
            time_s=state.elapsed[rows] * self.config["time_step_s"],
        )
        return info

    def frame(self, state: RegistrationState, decision: Decision):
        """Copy 0 drawn: its scene, the vehicle and its path, and its newest range image with the picked patches."""
        cfg, scenario, pose = self.config, state.worlds.scenario(0), state.worlds.poses[0, 0].copy()
        caption = f"t = {state.elapsed[0] * cfg['time_step_s']:.1f} s   "
        caption += f"picked {int(state.picked[0].sum())}/{cfg['picks_per_pair']} patches"
        last = state.last_registration[0]
        if last["n_control_points"] > 0:  # registered in this episode (a picked patch has returns)
            caption += f"   last ICP: error {last['error_before_m']:.3f} -> {last['error_after_m']:.3f} m"
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            robots=[RobotDrawing(true_pose=pose, true_path=state.paths[0].points())],
            sensor_wedge=(float(pose[2]), self.ladar.horizontal_fov_rad, SENSOR_WEDGE_LENGTH_M),
            inset_image=to_display_image(state.frames[0]),
            inset_title="newest LADAR range image (dark = near, white = no return); red: patches picked for ICP",
            inset_grid=(cfg["patch_rows"], cfg["patch_columns"]),
            inset_highlights=np.flatnonzero(state.picked[0]).tolist(),
            caption=caption,
        )


class RangeRegistrationVectorEnv(Driver, scenario=RangeRegistration):
    """N copies of ``infonav/RangeRegistration-v0``, the driver bound to its scenario (``gym.make_vec``).

    Observations (N, 5 * P + 2); scans, frame pairs and ICP run copy by copy.
    """

    @property
    def odometry_std(self) -> np.ndarray:
        """The odometry's motion error std per axis (x, y, z [m], roll, pitch, yaw [rad])."""
        return self.env_scenario.odometry_std


class RangeRegistrationEnv(SingleEnvView, vector_env=RangeRegistrationVectorEnv):
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
    Valid while it has returns and was not chosen for this pair (``info["action_mask"]``; ``action_masks()``
    is all ``True`` when no patch can be picked: every action is then the no-op).

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
    ``gym.make("infonav/RangeRegistration-v0", render_mode=None, **config)`` with any key of ``default_config()``.

    ## Version History
    * v0: initial version.
    """
