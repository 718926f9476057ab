"""Time-ordered replay of a dataset through the batched EKF: a pose filter per robot (landmark map) or one joint
filter over all robots (cooperative).

Noise: the hand-picked stds of the dataset README (``ReplayConfig.noise = None``: independent errors, a chi-square
gate), or a calibrated ``NoiseModel``: each robot's filter then holds the slow biases in its state
(``_CalibratedFilters``), the joint filter takes the whole error as white, and every update passing the gate is
Huber-weighted (``estimation.robust``). Greedy's expected gains use the filter's covariance, Jacobians and noise.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from tqdm.auto import tqdm

from infonav_gym.datasets.mrclam import MRCLAMDataset
from infonav_gym.datasets.noise_model import NoiseModel
from infonav_gym.datasets.timeline import LANDMARK, ROBOT, Timeline, dead_reckoning
from infonav_gym.estimation import batched
from infonav_gym.estimation.models import range_bearing_residual
from infonav_gym.estimation.robust import huber_noise
from infonav_gym.estimation.state import POSE_DIM, block_diagonal
from infonav_gym.experiments.replay.policies import POLICIES, select_greedy, select_nearest, select_random
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
    cooperative: bool = False  # one joint filter with robot-to-robot range-bearing
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


class _IndependentFilters:
    """One pose filter per robot with the known landmark map (a copy of the batched EKF per robot); robot-to-robot
    measurements are not used."""

    counted = None  # the state entries whose information greedy counts (None: the whole state)

    def __init__(self, poses, covariances, dataset, config):
        self.x, self.P = np.array(poses, dtype=float), np.array(covariances, dtype=float)
        self.landmarks = dataset.landmarks
        self.R = config.R

    def predict(self, controls, dt, control_covariances):
        self.x, self.P = batched.predict_pose(self.x, self.P, controls, dt, control_covariances, check_input=False)

    def covariance(self, robot):
        return self.P[robot]

    def model(self, robot, kind, target):
        predicted, H = batched.landmark_measurement_model(self.x[[robot]], self.landmarks[[target]], check_input=False)
        return predicted[0, 0], H[0, 0]

    def noise(self, robot, kind, predicted):
        return self.R

    def update(self, robot, kind, target, z, predicted, H, R):
        one = [robot]
        self.x[one], self.P[one] = batched.range_bearing_update(
            self.x[one], self.P[one], z[None], predicted[None], H[None], R[None], check_input=False
        )

    def poses(self):
        return self.x[:, :3].copy()

    def covariances(self):
        return self.P[:, :3, :3].copy()


class _CalibratedFilters(_IndependentFilters):
    """Per robot, the pose filter with the slow biases of colored measurement noise in its state (greedy counts the
    information on the pose only: the biases are nuisance parameters).

    The state is ``[x, y, heading, b_range, b_bearing, b_range_1, b_bearing_1, ..., b_range_L, b_bearing_L]``: a range
    and a bearing bias shared by every landmark, then each landmark's own; a measurement of landmark ``j`` is
    ``h(pose, j) + b_shared + b_j`` plus white noise (growing with range). This is colored noise by state augmentation
    (Gelb 1974, "Applied Optimal Estimation", Sec. 4.5; Bar-Shalom, Li and Kirubarajan 2001, Sec. 8.3): on MRCLAM
    Dataset 6 consecutive range errors to a landmark correlate above 0.9, and bearing errors to different landmarks
    seen within 0.3 s by 0.2-0.5 (the camera's yaw against the robot's frame drifts). Each bias is a first-order
    Gauss-Markov process in the distance travelled (a parked robot keeps its error): ``b(s + ds) = a b(s) + w``,
    ``a = exp(-ds / l)``, stationary variance ``sigma_b^2``. The wheels drive along ``heading +
    travel_heading_offset_rad`` (on Dataset 6, -0.017 to +0.008 rad).
    """

    counted = np.arange(POSE_DIM)  # the biases are nuisance: information about them does not localize

    def __init__(self, poses, covariances, dataset, config):
        self.landmarks = dataset.landmarks
        self.models = [config.noise.for_robot(robot) for robot in dataset.robots]
        n_landmarks = len(self.landmarks)
        self.bias_variance = np.square(
            [
                [m.range_shared_std_m, m.bearing_shared_std_rad]
                + [m.range_bias_std_m, m.bearing_bias_std_rad] * n_landmarks
                for m in self.models
            ]
        )
        self.correlation_distance_m = np.array(
            [
                [m.range_shared_correlation_distance_m, m.bearing_shared_correlation_distance_m]
                + [m.range_correlation_distance_m, m.bearing_correlation_distance_m] * n_landmarks
                for m in self.models
            ]
        )
        self.travel_offset = np.array([m.travel_heading_offset_rad for m in self.models])
        self.x = np.hstack([poses, np.zeros(self.bias_variance.shape)])
        self.P = np.array(
            [np.diag(variances) for variances in np.hstack([np.zeros((len(poses), 3)), self.bias_variance])]
        )
        self.P[:, :POSE_DIM, :POSE_DIM] = covariances

    def predict(self, controls, dt, control_covariances):
        """The unicycle step along the direction of travel; each bias decays over the distance driven."""
        self.x[:, 2] += self.travel_offset
        super().predict(controls, dt, control_covariances)
        self.x[:, 2] = wrap_angle(self.x[:, 2] - self.travel_offset)
        decay = np.exp(-np.abs(controls[:, :1]) * dt / self.correlation_distance_m)
        scale = np.hstack([np.ones((len(decay), POSE_DIM)), decay])
        self.x *= scale
        self.P *= scale[:, :, None]
        self.P *= scale[:, None, :]
        biases = np.arange(POSE_DIM, self.x.shape[1])
        self.P[:, biases, biases] += (1.0 - decay**2) * self.bias_variance

    def model(self, robot, kind, target):
        predicted, H = super().model(robot, kind, target)
        for biases in (slice(POSE_DIM + 2 + 2 * target, POSE_DIM + 4 + 2 * target), slice(POSE_DIM, POSE_DIM + 2)):
            H[:, biases] = np.eye(2)
            predicted += self.x[robot, biases]
        predicted[1] = wrap_angle(predicted[1])
        return predicted, H

    def noise(self, robot, kind, predicted):
        return self.models[robot].white_noise(predicted[0])


class _CooperativeFilter:
    """One joint filter over all robots (the batched EKF at one copy): landmark and robot-to-robot range-bearing
    updates."""

    counted = None

    def __init__(self, poses, covariances, dataset, config):
        self.x = np.asarray(poses, dtype=float).reshape(1, -1)
        self.P = block_diagonal(covariances)[None]
        self.landmarks = dataset.landmarks
        self.n = len(poses)
        self.R = config.R
        self.models = [config.noise.for_robot(robot) for robot in dataset.robots] if config.noise else None

    def predict(self, controls, dt, control_covariances):
        self.x, self.P = batched.predict_team(
            self.x, self.P, controls[None], dt, control_covariances, check_input=False
        )

    def covariance(self, robot):
        return self.P[0]

    def model(self, robot, kind, target):
        H = np.zeros((2, 3 * self.n))
        own = slice(3 * robot, 3 * robot + 3)
        if kind == LANDMARK:
            predicted, H_pose = batched.landmark_measurement_model(
                self.x[:, own], self.landmarks[[target]], check_input=False
            )
            H[:, own] = H_pose[0, 0]
            return predicted[0, 0], H
        predicted, H_observer, H_target = batched.relative_pose_model(self.x, [[robot]], [[target]], check_input=False)
        H[:, own] = H_observer[0, 0, :2]
        H[:, 3 * target : 3 * target + 3] = H_target[0, 0, :2]
        return predicted[0, 0, :2], H

    def noise(self, robot, kind, predicted):
        return self.models[robot].total_noise(predicted[0]) if self.models else self.R

    def update(self, robot, kind, target, z, predicted, H, R):
        slot = (np.array([[robot]]), z[None, None], predicted[None, None])
        own = H[None, None, :, 3 * robot : 3 * robot + 3]
        if kind == LANDMARK:
            self.x, self.P = batched.team_landmark_update(self.x, self.P, *slot, own, R[None, None], check_input=False)
            return
        observed = H[None, None, :, 3 * target : 3 * target + 3]
        self.x, self.P = batched.relative_pose_update(
            self.x, self.P, slot[0], np.array([[target]]), *slot[1:], own, observed, R[None, None], check_input=False
        )

    def poses(self):
        return self.x.reshape(-1, 3).copy()

    def covariances(self):
        robots = np.arange(self.n)
        return batched.pose_blocks(self.P)[0, robots, robots]


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
    """Run the filter through the ``timeline`` of ``dataset`` from the robots' poses (N, 3) and covariances (N, 3, 3)
    at boundary 0: predict every tick, select (budget), gate and update at each event."""
    n_robots = len(dataset.robots)
    backend_class = (
        _CooperativeFilter if config.cooperative else _CalibratedFilters if config.noise else _IndependentFilters
    )
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
        **{name: [[] for _ in range(n_robots)] for name in ("nis", "accepted", "kinds", "choices")},
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
    end = pointer + int(np.searchsorted(rows[pointer:, 0], window_end))  # rows are sorted by boundary
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
            chosen = select_greedy(backend.covariance(robot), H, R, config.k, backend.counted)
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
