"""Time-ordered replay of a dataset through PoseEKF (per robot, landmark map) or JointEKF (cooperative).

Two noise models: the hand-picked one of the dataset README (``ReplayConfig.noise = None``: fixed range
and bearing std, independent errors, a chi-square gate), or a calibrated ``NoiseModel``. With a
calibrated model each robot's filter is a ``TargetBiasPoseEKF`` (the slow per-landmark range and
bearing biases in its state, white noise growing with range in R), the cooperative JointEKF takes the
whole error as white, and every update is Huber-weighted (``estimation.robust``: the standard update
for innovations inside ``huber_threshold_nis``, inflated noise beyond) after the gate. The expected
information gains of the greedy policy use the same covariance, Jacobians and noise, and count the
information on the pose only (the biases are nuisance parameters).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from tqdm.auto import tqdm

from infonav_gym.datasets.mrclam import MRCLAMDataset
from infonav_gym.estimation.bias_ekf import TargetBiasPoseEKF
from infonav_gym.estimation.ekf import JointEKF, PoseEKF
from infonav_gym.estimation.models import range_bearing_residual
from infonav_gym.estimation.robust import huber_noise
from infonav_gym.experiments.replay.noise_model import NoiseModel
from infonav_gym.experiments.replay.policies import POLICIES, select_greedy, select_nearest, select_random
from infonav_gym.experiments.replay.timeline import LANDMARK, ROBOT, Timeline, dead_reckoning
from infonav_gym.geometry import wrap_angle


@dataclass
class ReplayConfig:
    """Noise model, gate and selection settings of a replay (defaults: the dataset README's reference filter)."""

    range_std_m: float = 0.3  # [m] range noise, landmarks and robots
    bearing_std_rad: float = math.radians(8.0)  # [rad]
    # Odometry noise of readings averaged over 1 s. On Dataset 6 the 1 s odometry error against motion
    # capture has robust (1.4826 MAD) standard deviations of about 0.008 m/s and 0.016 rad/s (plain
    # standard deviations 0.012 m/s and 0.035-0.06 rad/s: heavy tails); these defaults lie in that range.
    speed_std: float = 0.01  # [m/s]
    turn_rate_std: float = 0.02  # [rad/s]
    gate_nis: float = 25.0  # reject updates with normalized innovation squared above this (chi-square, 2 dof)
    noise: NoiseModel | None = None  # a calibrated model (None: the hand-picked stds above)
    huber_threshold_nis: float = 5.99  # calibrated filters: Huber weights beyond this NIS (chi-square 2 dof, 95 %)
    initial_position_std_m: float = 0.05  # [m] around the ground-truth start
    initial_heading_std_rad: float = 0.05  # [rad]
    policy: str = "all"
    k: int = 1  # observations per robot per window
    window_s: float = 1.0  # [s]
    seed: int = 0
    cooperative: bool = False  # JointEKF with robot-to-robot range-bearing
    outage_robot: int | None = None  # subject number whose landmark observations are withheld ...
    outage_start_s: float = 0.0  # [s] ... from here
    outage_end_s: float = math.inf  # [s] ... to here (replay time)

    def __post_init__(self):
        if self.policy not in POLICIES:
            raise ValueError(f"unknown policy {self.policy!r}: expected one of {', '.join(POLICIES)}")
        if self.policy != "all" and (self.k < 1 or not self.window_s > 0):
            raise ValueError(f"a budget needs k >= 1 and window_s > 0, got k={self.k}, window_s={self.window_s}")
        if not self.outage_end_s > self.outage_start_s:
            raise ValueError(f"outage must end after it starts, got {self.outage_start_s}..{self.outage_end_s} s")

    def as_dict(self) -> dict:
        """The settings as JSON-ready values (an open-ended outage ends at None, not infinity)."""
        settings = dataclasses.asdict(dataclasses.replace(self, noise=None))
        settings["noise"] = self.noise.source if self.noise else "picked"
        if math.isinf(settings["outage_end_s"]):
            settings["outage_end_s"] = None
        return settings

    @property
    def R(self) -> np.ndarray:
        return np.diag([self.range_std_m**2, self.bearing_std_rad**2])


@dataclass
class ReplayTrace:
    """What a replay recorded at every boundary, and every measurement it gated."""

    poses: np.ndarray  # (n_ticks + 1, N, 3)
    covariances: np.ndarray  # (n_ticks + 1, N, 3, 3)
    dead_reckoning: np.ndarray  # (n_ticks + 1, N, 3)
    nis: list[list[float]] = field(default_factory=list)  # per robot, of every update tried
    accepted: list[list[bool]] = field(default_factory=list)
    kinds: list[list[int]] = field(default_factory=list)
    choices: list[list[tuple[int, int]]] = field(default_factory=list)  # per robot, (window, target) picked


POSE_ENTRIES = np.arange(3)


class _IndependentFilters:
    """One PoseEKF per robot with the known landmark map; robot-to-robot measurements are not used."""

    def __init__(self, poses, covariances, dataset, config):
        self.filters = [PoseEKF(pose, covariance) for pose, covariance in zip(poses, covariances)]
        self.landmarks = dataset.landmarks
        self.R = config.R

    def predict(self, controls, dt, control_covariances):
        for ekf, control, covariance in zip(self.filters, controls, control_covariances):
            ekf.predict(control, dt, covariance)

    def covariance(self, robot):
        return self.filters[robot].P

    def model(self, robot, kind, target):
        predicted, H = self.filters[robot].landmark_measurement_model(self.landmarks[target][None])
        return predicted[0], H[0]

    def noise(self, robot, kind, predicted):
        return self.R

    def information_of(self, robot):
        """The state entries whose information greedy counts: the robot's pose (None: the whole state)."""
        return None

    def update(self, robot, kind, target, z, predicted, H, R):
        self.filters[robot].update_range_bearing(z, predicted, H, R)

    def poses(self):
        return np.array([ekf.x[:3] for ekf in self.filters])

    def covariances(self):
        return np.array([ekf.P[:3, :3] for ekf in self.filters])


class _CalibratedFilters(_IndependentFilters):
    """One TargetBiasPoseEKF per robot: the landmark map plus each landmark's slow range and bearing biases
    and the robot's own, shared by every landmark."""

    def __init__(self, poses, covariances, dataset, config):
        landmarks = self.landmarks = dataset.landmarks
        self.models = [config.noise.for_robot(robot) for robot in dataset.robots]
        self.filters = [
            TargetBiasPoseEKF(
                pose,
                covariance,
                np.tile([model.range_bias_std_m, model.bearing_bias_std_rad], (len(landmarks), 1)),
                [model.range_correlation_distance_m, model.bearing_correlation_distance_m],
                [model.range_shared_std_m, model.bearing_shared_std_rad],
                [model.range_shared_correlation_distance_m, model.bearing_shared_correlation_distance_m],
                model.travel_heading_offset_rad,
            )
            for pose, covariance, model in zip(poses, covariances, self.models)
        ]

    def model(self, robot, kind, target):
        return self.filters[robot].measurement_model(target, self.landmarks[target])

    def noise(self, robot, kind, predicted):
        return self.models[robot].white_noise(predicted[0])

    def information_of(self, robot):
        return POSE_ENTRIES  # the biases are nuisance: information about them does not localize

    def update(self, robot, kind, target, z, predicted, H, R):
        self.filters[robot].update_range_bearing(z, range_bearing_residual(z, predicted), H, R)


class _CooperativeFilter:
    """One JointEKF over all robots: landmark and robot-to-robot range-bearing updates."""

    def __init__(self, poses, covariances, dataset, config):
        self.ekf = JointEKF(poses, covariances)
        self.landmarks = dataset.landmarks
        self.n = len(poses)
        self.R = config.R
        self.models = [config.noise.for_robot(robot) for robot in dataset.robots] if config.noise else None

    def predict(self, controls, dt, control_covariances):
        self.ekf.predict(controls, dt, control_covariances)

    def covariance(self, robot):
        return self.ekf.P

    def model(self, robot, kind, target):
        H = np.zeros((2, 3 * self.n))
        own = slice(3 * robot, 3 * robot + 3)
        if kind == LANDMARK:
            dx, dy = self.landmarks[target] - self.ekf.x[own][:2]
            squared_range = dx * dx + dy * dy
            distance = math.sqrt(squared_range)
            predicted = np.array([distance, wrap_angle(math.atan2(dy, dx) - self.ekf.x[own][2])])
            H[:, own] = [[-dx / distance, -dy / distance, 0.0], [dy / squared_range, -dx / squared_range, -1.0]]
            return predicted, H
        predicted, H_observer, H_target = self.ekf.relative_pose_model([robot], [target])
        H[:, own] = H_observer[0, :2]
        H[:, 3 * target : 3 * target + 3] = H_target[0, :2]
        return predicted[0, :2], H

    def noise(self, robot, kind, predicted):
        return self.models[robot].total_noise(predicted[0]) if self.models else self.R

    def information_of(self, robot):
        return None

    def update(self, robot, kind, target, z, predicted, H, R):
        if kind == ROBOT:
            _, H_observer, H_target = self.ekf.relative_pose_model([robot], [target])
            self.ekf.relative_pose_update(
                [robot], [target], z[None], predicted[None], H_observer[:, :2], H_target[:, :2], R[None]
            )
            return
        self.ekf.update(z, lambda _: H, lambda _: predicted, R=R, residual=range_bearing_residual)
        self.ekf.x[2::3] = wrap_angle(self.ekf.x[2::3])
        self.ekf.P = 0.5 * (self.ekf.P + self.ekf.P.T)

    def poses(self):
        return self.ekf.x.reshape(-1, 3)

    def covariances(self):
        return self.ekf.pose_covariances()


def usable_events(dataset: MRCLAMDataset, timeline: Timeline, config: ReplayConfig) -> list[np.ndarray]:
    """Each robot's events that the replay may use: landmarks (and robots if cooperative), minus the outage."""
    usable = []
    for robot, events in zip(dataset.robots, timeline.events):
        keep = (events[:, 1] == LANDMARK) | (config.cooperative & (events[:, 1] == ROBOT))
        if config.outage_robot == robot:
            in_outage = (events[:, 5] >= config.outage_start_s) & (events[:, 5] < config.outage_end_s)
            keep &= ~(in_outage & (events[:, 1] == LANDMARK))
        usable.append(events[keep])
    return usable


def replay_filter(
    dataset: MRCLAMDataset,
    timeline: Timeline,
    initial_poses: np.ndarray,
    initial_covariances: np.ndarray,
    config: ReplayConfig,
    progress: bool = False,
) -> ReplayTrace:
    """Run the filter through the timeline: predict every tick, select (budget), gate and update at each event.

    Args:
        dataset: the loaded dataset (robots, landmark map).
        timeline: its logs on the replay clock.
        initial_poses, initial_covariances: the robots' poses at boundary 0 (N, 3) and their covariances (N, 3, 3).
        config: noise model, gate, policy, outage.
        progress: show a tqdm bar.
    """
    n_robots = len(dataset.robots)
    if config.cooperative:
        backend_class = _CooperativeFilter
    else:
        backend_class = _CalibratedFilters if config.noise else _IndependentFilters
    backend = backend_class(initial_poses, initial_covariances, dataset, config)
    control_covariances = np.array(
        [
            config.noise.for_robot(robot).control_covariance(timeline.dt)
            if config.noise
            else np.diag([config.speed_std**2, config.turn_rate_std**2]) / timeline.dt
            for robot in dataset.robots
        ]
    )
    events = usable_events(dataset, timeline, config)
    selected = [np.full(len(rows), config.policy == "all") for rows in events]
    pointers = [0] * n_robots
    window_ticks = max(1, round(config.window_s / timeline.dt))
    rng = np.random.default_rng(config.seed)
    trace = ReplayTrace(
        poses=np.empty((timeline.n_ticks + 1, n_robots, 3)),
        covariances=np.empty((timeline.n_ticks + 1, n_robots, 3, 3)),
        dead_reckoning=dead_reckoning(initial_poses, timeline),
        nis=[[] for _ in range(n_robots)],
        accepted=[[] for _ in range(n_robots)],
        kinds=[[] for _ in range(n_robots)],
        choices=[[] for _ in range(n_robots)],
    )
    boundaries = range(timeline.n_ticks + 1)
    for b in tqdm(boundaries, desc=f"replay {config.policy}", unit="tick", disable=not progress, leave=False):
        if config.policy != "all" and b % window_ticks == 0:
            for robot in range(n_robots):
                chosen = _select_window(
                    backend, robot, events[robot], selected[robot], pointers[robot], b + window_ticks, config, rng
                )
                trace.choices[robot].extend((b // window_ticks, int(target)) for target in chosen)
        for robot in range(n_robots):
            rows, pointer = events[robot], pointers[robot]
            while pointer < len(rows) and rows[pointer, 0] <= b:
                if selected[robot][pointer]:
                    _gated_update(backend, robot, rows[pointer], config, trace)
                pointer += 1
            pointers[robot] = pointer
        trace.poses[b] = backend.poses()
        trace.covariances[b] = backend.covariances()
        if b < timeline.n_ticks:
            backend.predict(timeline.controls[b], timeline.dt, control_covariances)
    return trace


def _select_window(backend, robot, rows, selected, pointer, window_end, config, rng) -> np.ndarray:
    """Mark the measurements of ``robot`` to use among those of the window starting now; return their targets."""
    end = pointer
    while end < len(rows) and rows[end, 0] < window_end:
        end += 1
    if end == pointer:
        return rows[:0, 2]
    candidates = rows[pointer:end]
    if len(candidates) <= config.k:
        selected[pointer:end] = True
        return candidates[:, 2]
    if config.policy == "random":
        chosen = select_random(len(candidates), config.k, rng)
    else:
        kinds_targets = candidates[:, 1:3].astype(int)
        models = [backend.model(robot, kind, target) for kind, target in kinds_targets]
        if config.policy == "greedy":
            H = np.array([H for _, H in models])
            R = np.array(
                [backend.noise(robot, kind, predicted) for (kind, _), (predicted, _) in zip(kinds_targets, models)]
            )
            chosen = select_greedy(backend.covariance(robot), H, R, config.k, backend.information_of(robot))
        else:
            chosen = select_nearest(np.array([predicted[0] for predicted, _ in models]), config.k)
    chosen = np.asarray(chosen, dtype=int)
    selected[pointer + chosen] = True
    return candidates[chosen, 2]


def _gated_update(backend, robot, row, config, trace) -> None:
    """Gate the measurement on its NIS; update (Huber-weighted with a calibrated model) if it passes."""
    kind, target = int(row[1]), int(row[2])
    z = row[3:5].copy()
    predicted, H = backend.model(robot, kind, target)
    R = backend.noise(robot, kind, predicted)
    residual = range_bearing_residual(z, predicted)
    P = backend.covariance(robot)
    if config.noise:
        R, _, nis = huber_noise(residual, H, P, R, config.huber_threshold_nis)
    else:
        nis = float(residual @ np.linalg.solve(H @ P @ H.T + R, residual))
    accepted = nis <= config.gate_nis
    trace.nis[robot].append(nis)
    trace.accepted[robot].append(accepted)
    trace.kinds[robot].append(kind)
    if accepted:
        backend.update(robot, kind, target, z, predicted, H, R)
