"""``TeamScenario`` and ``TeamState``: what the team scenarios share (DGPS fixes, relative poses, odometry, infos).

A team scenario's ``__init__`` calls ``use_team`` with its sensors; its ``allocate`` starts from ``team_fields``, its
``initial`` calls ``start_copy`` for each copy and then ``started``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from infonav_gym.compiled import contiguous, kernel, stacked
from infonav_gym.envs.noise_streams import NoiseStreams
from infonav_gym.envs.parallel_view import TeamCycles
from infonav_gym.envs.protocol import EnvScenario, State
from infonav_gym.envs.vector_infos import reward_term_key
from infonav_gym.estimation import batched
from infonav_gym.estimation.kernels import kalman_updates, pose_block_log_det, predict_poses
from infonav_gym.estimation.state import POSE_DIM, block_diagonal
from infonav_gym.geometry import wrap_angle
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.information import gaussian_entropy_from_log_det, log_det_of, mutual_information_kernel
from infonav_gym.multi.team_paths import FirstCopyPaths
from infonav_gym.multi.team_sensing import NO_OBSERVATION, gps_available, gps_schedule
from infonav_gym.scene import SceneFrame
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.relative_pose import relative_pose_measured
from infonav_gym.world.visibility import StaticGeometry
from infonav_gym.world.world_batch import WorldBatch

ODOMETRY_NOISE, GPS_NOISE, RELATIVE_NOISE = 0, 1, 2  # ``noise`` index of each sensor's streams (more may follow)


@dataclass
class TeamState(State):
    """Every copy's world, noise streams (one ``NoiseStreams`` per sensor generator, in the order ``start_episode``
    spawns them), joint EKF ``x`` (N, 3R) and ``P`` (N, 3R, 3R), which robots have a DGPS fix (N, R), its GPS-denied
    zones (``gps_denied_zones``), static geometry (``geometries``, stacked in ``geometry``), each robot's last executed
    action and whether it was masked (N, R); copy 0's paths (when drawing) and observed (observer, target) pairs."""

    worlds: WorldBatch
    noise: tuple
    x: np.ndarray
    P: np.ndarray
    gps_available: np.ndarray
    zone_centers: np.ndarray
    zone_radii_sq: np.ndarray
    geometries: list
    geometry: object = None
    paths: FirstCopyPaths | None = None
    chosen: np.ndarray = None
    invalid: np.ndarray = None
    observed_pairs: list = None


def copy_rows(copies: np.ndarray, n_copies: int):
    """The index of ``copies`` (ascending) into (N, ...) arrays: a slice (views) when they are every copy."""
    return slice(None) if len(copies) == n_copies else copies


class TeamScenario(EnvScenario):
    """A team scenario of robots with DGPS, odometry and relative-pose sensors: its constants (``use_team``) and
    shared steps. ``team_info_keys`` are the infos of the whole team, (N,); the others are (N, R, ...)."""

    team = True
    horizon_key = "max_cycles"
    team_info_keys: ClassVar[frozenset] = frozenset({"time_s"})

    def use_team(self, pairs, gps, odometry) -> None:
        """Keep the team's sensors: its (observer, target) ``pairs`` (``SensingPairs``), each robot's ``GPSSensor``
        (with its outage spans) or None without DGPS (R,), and every robot's ``odometry``."""
        n_robots = len(gps)
        self.agents = [f"robot_{k}" for k in range(n_robots)]
        self.pairs = pairs
        self.pair_index = np.full((n_robots, n_robots + 1), -1)  # robot, teammate choice -> its pair
        self.pair_index[pairs.observers, pairs.targets + 1] = np.arange(len(pairs.observers))
        self.has_gps, self.outages = gps_schedule(gps)
        self.gps = GPSSensor(self.config["gps_std_m"])  # every receiver's noise; the schedules are ``outages``
        self.gps_covariance = self.gps.noise_covariance()
        self.cross_covariances = self.config.get("estimator", "joint") == "joint"  # a team env may drop them
        self.odometry = odometry
        self.odometry_covariances = np.repeat(odometry.noise_covariance()[None], n_robots, axis=0)

    def team_fields(self, copies: int, more_noise_widths=()) -> dict:
        """The ``TeamState`` fields of ``copies`` copies before their first episode; ``more_noise_widths``: the draw
        widths of the episode's generators after odometry, DGPS and relative poses."""
        n_robots = len(self.agents)
        widths = (2 * n_robots, 2, POSE_DIM, *more_noise_widths)
        dim = POSE_DIM * n_robots
        return {
            "elapsed": np.zeros(copies, dtype=int),
            "worlds": WorldBatch(copies),
            "noise": tuple(NoiseStreams(copies, width) for width in widths),
            "x": np.zeros((copies, dim)),
            "P": np.zeros((copies, dim, dim)),
            "gps_available": np.zeros((copies, n_robots), dtype=bool),
            "zone_centers": np.zeros((copies, 0, 2)),
            "zone_radii_sq": np.zeros((copies, 0)),
            "geometries": [None] * copies,
            "chosen": np.full((copies, n_robots), self.traits.noop_action),
            "invalid": np.zeros((copies, n_robots), dtype=bool),
            "observed_pairs": [],
        }

    @staticmethod
    def start_copy(state: TeamState, copy: int, scenario, poses, covariances, *generators):
        """Copy ``copy`` starts an episode of ``scenario`` (``start_episode``'s): its world, static geometry, sensor
        streams and joint EKF prior; returns ``scenario``."""
        state.worlds.reset_copy(copy, scenario)
        state.geometries[copy] = StaticGeometry.from_scenario(scenario, state.worlds.wall_thickness_m)
        for streams, generator in zip(state.noise, generators):
            streams.restart(copy, generator)
        state.x[copy], state.P[copy] = poses.ravel(), block_diagonal(covariances)
        return scenario

    def started(self, state: TeamState, copies: np.ndarray) -> None:
        """``copies`` have started their episodes (``start_copy``): their static geometry, DGPS zones and first fixes,
        no action yet; copy 0's paths and observations start anew."""
        geometry = StaticGeometry.stack([state.geometries[copy] for copy in copies.tolist()])
        state.geometry = geometry if len(copies) == len(state.elapsed) else state.geometry.with_copies(copies, geometry)
        state.zone_centers, state.zone_radii_sq = gps_denied_zones(state.worlds)
        self.gps_fixes(state, copies, state.elapsed[copies])
        state.chosen[copies], state.invalid[copies] = self.traits.noop_action, False
        if copies[0] == 0:
            state.observed_pairs = []
        if copies[0] == 0 and self.drawing:
            state.paths = FirstCopyPaths(state.worlds.poses[0], state.x[0].reshape(-1, POSE_DIM))

    @staticmethod
    def rows_geometry(state: TeamState, rows) -> StaticGeometry:
        """The static geometry of the copies ``rows`` (a slice: every copy)."""
        return state.geometry if isinstance(rows, slice) else StaticGeometry.stack([state.geometries[r] for r in rows])

    def moved(self, state: TeamState, copies: np.ndarray) -> None:
        """``copies`` have moved: copy 0's paths (when drawing) take its robots' true and estimated positions."""
        if copies[0] == 0 and state.paths is not None:
            state.paths.extend(state.worlds.poses[0], state.x[0].reshape(-1, POSE_DIM))

    def relative_update(self, state: TeamState, copies: np.ndarray, chosen: np.ndarray, decision) -> list:
        """Fuse the teammate choices ``chosen`` (n, R) (``NO_OBSERVATION`` or ``1 + j`` for robot j) of ``copies`` (n,)
        at the ``decision``'s candidates as one stacked update per copy; the joint MI (n,), each robot's own-pose MI
        (n, R) [nats] and its x, y, heading standard deviations after (n, R, 3) (``relative_updates``: MI 0 and the
        prior's std in a copy without observations)."""
        noise = state.noise[RELATIVE_NOISE].take_many(copies, chosen != NO_OBSERVATION)
        rows = copy_rows(copies, len(state.elapsed))
        candidates = (decision.geometry, decision.predicted, decision.H_observer, decision.H_target, decision.R)
        models = [contiguous(model[rows]) for model in (*candidates, decision.pose_log_det)]
        x, P = state.x[rows], state.P[rows]
        state.x[rows], state.P[rows], *brought = relative_updates(
            x, P, chosen, self.pair_index, self.pairs.targets, self.pairs.noise, *models, noise, self.cross_covariances
        )
        if np.isnan(brought[0]).any():
            raise ValueError("the joint covariance after the relative-pose updates is not positive definite")
        return brought

    def predict(self, state: TeamState, copies: np.ndarray, controls: np.ndarray, dt: float) -> None:
        """Predict the EKFs of ``copies`` with noisy odometry of the executed ``controls`` (n, R, 2) over ``dt`` [s]."""
        noise = state.noise[ODOMETRY_NOISE].take(copies).reshape(controls.shape)
        readings = self.odometry.measure_with_noise(controls, noise)
        rows = copy_rows(copies, len(state.elapsed))
        x, P = contiguous(state.x[rows]), contiguous(state.P[rows])  # ``JointEKF.predict`` on the compiled core
        covariances = stacked(self.odometry_covariances, (*controls.shape, 2))
        state.x[rows], state.P[rows] = predict_poses(x, P, readings, float(dt), covariances)

    def gps_fixes(self, state: TeamState, copies: np.ndarray, steps: np.ndarray) -> None:
        """Which robots of ``copies`` have a DGPS fix after ``steps`` (n,) steps of their episodes (schedule, zones),
        and their update."""
        within = copy_rows(copies, len(state.elapsed))
        positions = state.worlds.poses[within, :, :2]
        available = self.gps_available(state, copies, positions, steps * self.config["time_step_s"])
        state.gps_available[within] = available
        if not available.any():
            return
        fixes = self.gps.measure_with_noise(positions, state.noise[GPS_NOISE].take_many(copies, available))
        x, P = state.x[within], state.P[within]
        state.x[within], state.P[within] = batched.gps_update(  # copies without a fix come back unchanged
            x, P, fixes, self.gps_covariance, available, cross_covariances=self.cross_covariances, check_input=False
        )

    def gps_available(self, state: TeamState, copies: np.ndarray, positions: np.ndarray, time_s) -> np.ndarray:
        """Which robots at ``positions`` (n, R, 2) [m] in ``copies`` (n,) have a DGPS fix at ``time_s`` (n,) [s]: they
        carry DGPS, are in none of their copy's GPS-denied zones and in no outage span (n, R) bool."""
        zones = state.zone_centers, state.zone_radii_sq
        return gps_available(copies, contiguous(positions), *zones, self.has_gps, self.outages, time_s)

    def team_info(self, state: TeamState, decision, rows, stepped, terms: dict, **more) -> dict:
        """The infos of the copies ``rows`` every team env gives, then ``more``: arrays (N, R, ...) (the team's
        (N,)). ``decision`` has ``action_mask``, ``action_information_gain``, ``pose_log_det`` and ``pose_std``; the
        reward ``terms`` (N, R) [nats], each at its ``reward_term_key``, are 0 in the copies that were reset (not
        ``stepped``)."""
        true_poses = state.worlds.poses[rows]
        estimates = state.x[rows].reshape(true_poses.shape)
        errors = true_poses - estimates
        terms = {key: np.where(stepped[:, None], value, 0.0) for key, value in terms.items()}
        return {
            "action_mask": decision.action_mask.copy(),
            "action_information_gain": decision.action_information_gain.copy(),
            **{reward_term_key(key): value for key, value in terms.items()},
            "chosen_action": state.chosen[rows].copy(),
            "invalid_action": state.invalid[rows].copy(),
            "gps_available": state.gps_available[rows].copy(),
            "position_error_m": np.hypot(errors[..., 0], errors[..., 1]),
            "heading_error_rad": np.abs(wrap_angle(errors[..., 2])),
            "pose_entropy": gaussian_entropy_from_log_det(decision.pose_log_det, POSE_DIM),
            "pose_std": decision.pose_std.copy(),
            "true_pose": true_poses.copy(),
            "estimated_pose": estimates.copy(),
            "time_s": np.asarray(state.elapsed[rows] * self.config["time_step_s"], dtype=float).copy(),
            **more,
        }

    def team_frame(self, state: TeamState, caption: str, **more) -> SceneFrame:
        """Copy 0 drawn: its scenario, every robot (truth, estimate, covariance, paths), its teammate observations
        (``more``) and the ``caption``."""
        scenario = state.worlds.scenario(0)
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            robots=state.paths.drawings(
                state.worlds.poses[0], state.x[0], state.P[0], self.agents, state.gps_available[0]
            ),
            gps_denied_zones=scenario.gps_denied_zones,
            caption=caption,
            **more,
        )


class TeamAccessors(TeamCycles):
    """What a team vector env (the ``Driver`` of a ``TeamScenario``) shows of its ``state``, for harnesses and tests:
    ``class MyTeamVectorEnv(TeamAccessors, Driver, scenario=MyTeamScenario)``."""

    state: TeamState

    def scenario(self, copy: int = 0):
        """The ``Scenario`` of copy ``copy``'s episode."""
        return self.state.worlds.scenario(copy)

    @property
    def true_poses(self) -> np.ndarray:
        """Every copy's true robot poses (N, R, 3) [m, m, rad] (a copy)."""
        return self.state.worlds.poses.copy()

    def joint_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Every copy's joint EKF state ``x`` (N, 3R) and covariance ``P`` (N, 3R, 3R) (copies)."""
        return self.state.x.copy(), self.state.P.copy()


def gps_denied_zones(worlds: WorldBatch) -> tuple[np.ndarray, np.ndarray]:
    """Every copy's GPS-denied zones: centres (N, Z, 2) [m] and squared radii (N, Z) [m^2] (-1: padding)."""
    zones = [worlds.scenario(copy).gps_denied_zones for copy in range(len(worlds.poses))]
    centers = np.zeros((len(zones), max(map(len, zones)), 2))
    radii_sq = np.full(centers.shape[:2], -1.0)
    for copy, copy_zones in enumerate(zones):
        for slot, zone in enumerate(copy_zones):
            centers[copy, slot], radii_sq[copy, slot] = zone.center, zone.radius**2
    return centers, radii_sq


@kernel
def relative_updates(
    x, P, chosen, pair_index, targets, parameters, geometry, predicted, H_o, H_t, R, log_det, noise, cross
):
    """``JointEKF.relative_pose_update`` of n copies: robot k of copy c observes pair ``pair_index[k, chosen[c, k]]``
    (-1: none), its true relative pose ``geometry`` plus the sensor's noise (of its ``parameters`` and standard normals
    ``noise[c, k]``), fused at the prior's models in slot order (``kalman_updates``). Returns ``(x, P, joint_mi (n,),
    own_mi (n, R), pose_std (n, R, 3))``: the MI [nats] on the joint state and each robot's pose (prior: ``log_det``),
    NaN where a determinant is not > 0, and each robot's std after; a copy without observations keeps x, P: MI 0."""
    n_copies, n = x.shape
    n_robots = chosen.shape[1]
    residuals, slot_R = np.zeros((n_copies, n_robots, POSE_DIM)), np.zeros((n_copies, n_robots, POSE_DIM, POSE_DIM))
    H, observed = np.zeros((n_copies, n_robots, POSE_DIM, n)), np.zeros((n_copies, n_robots), np.bool_)
    measured, observations = np.empty(POSE_DIM), np.zeros(n_copies, np.int64)
    for c in range(n_copies):
        for robot in range(n_robots):
            pair = pair_index[robot, chosen[c, robot]]
            if pair < 0:
                continue
            observed[c, robot] = True
            observations[c] += 1
            target = targets[pair]
            relative_pose_measured(geometry[c, pair], parameters[pair], noise[c, robot], measured)
            for i in range(POSE_DIM):
                residual = measured[i] - predicted[c, pair, i]
                residuals[c, robot, i] = wrap(residual) if i else residual
                for j in range(POSE_DIM):
                    H[c, robot, i, POSE_DIM * robot + j] = H_o[c, pair, i, j]
                    H[c, robot, i, POSE_DIM * target + j] = H_t[c, pair, i, j]
                    slot_R[c, robot, i, j] = R[c, pair, i, j]
    x_new, P_new = kalman_updates(x, P, residuals, H, slot_R, observed, n_robots, cross)
    joint_mi, own_mi, pose_std = np.empty(n_copies), np.empty((n_copies, n_robots)), np.empty(residuals.shape)
    block = np.empty((POSE_DIM, POSE_DIM))
    for c in range(n_copies):
        joint_mi[c] = mutual_information_kernel(log_det_of(P[c]), log_det_of(P_new[c])) if observations[c] else 0.0
        for robot in range(n_robots):
            own_mi[c, robot] = mutual_information_kernel(
                log_det[c, robot], pose_block_log_det(P_new[c], POSE_DIM * robot, block)
            )
            for i in range(POSE_DIM):
                pose_std[c, robot, i] = math.sqrt(P_new[c, POSE_DIM * robot + i, POSE_DIM * robot + i])
    return x_new, P_new, joint_mi, own_mi, pose_std
