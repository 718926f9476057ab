"""``infonav/MRCLAMLocalization-v0``: which of the landmarks a real robot measured to fuse (UTIAS MRCLAM logs)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from infonav_gym.compiled import contiguous, kernel, stacked
from infonav_gym.config import check_config
from infonav_gym.datasets.mrclam_logs import DatasetLogs, robot_logs
from infonav_gym.envs.base import shared_config
from infonav_gym.envs.driver import Driver
from infonav_gym.envs.metrics import LOCALIZATION_METRICS, EpisodeMetric, count_where, mean_where
from infonav_gym.envs.observation_kernels import (
    POSE_FEATURES,
    POSE_HIGH,
    POSE_LOW,
    READING_HIGH,
    READING_LOW,
    clip_into,
    pose_features,
    reading_features,
)
from infonav_gym.envs.protocol import EnvScenario, State
from infonav_gym.envs.real_logs import LOG_CONFIG_INTERVALS, filter_noise, load_logs, log_config, reading_ranges
from infonav_gym.envs.single_view import SingleEnvView
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.envs.vector_infos import decision_info
from infonav_gym.estimation.kernels import kalman_updates, landmark_gains, predict_poses, range_bearing_models
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.geometry import wrap_angle
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.information import (
    gaussian_entropy_from_log_det,
    gaussian_entropy_kernel,
    log_det_of,
    mutual_information_kernel,
    stacked_log_dets,
)
from infonav_gym.scene import PathHistory, RobotDrawing, SceneFrame, extended_paths

NONE = 0  # the action that fuses nothing; action k >= 1 fuses landmark k - 1's measurement


@dataclass
class MRCLAMState(State):
    """Each copy's robot (index into the logs' robots) and step in its log (N,), its EKF ``x`` (N, 3) and ``P`` (N, 3,
    3), the landmark it fused last (N,) (-1: none), whether its measurement was gated out, the realized MI [nats], and
    copy 0's true and estimated paths (when drawing)."""

    robot: np.ndarray
    step: np.ndarray
    action: np.ndarray
    x: np.ndarray
    P: np.ndarray
    chosen: np.ndarray
    gated: np.ndarray
    fused: np.ndarray
    mutual_information: np.ndarray
    paths: tuple[PathHistory, PathHistory] | None = None


class MRCLAMDecision(NamedTuple):
    """Every copy's choice at its prior: the mask and expected MI of fusing nothing or each landmark (n, 1 + L), the
    readings (n, L, 2), the range-bearing models of the prior (``predicted`` (n, L, 2), ``H`` (n, L, 2, 3), ``R`` (n, L,
    2, 2)), ``ln det P`` (n,) and the ground-truth pose (n, 3) at the step's time."""

    action_mask: np.ndarray
    action_information_gain: np.ndarray
    readings: np.ndarray
    predicted: np.ndarray
    H: np.ndarray
    R: np.ndarray
    prior_log_det: np.ndarray
    true_pose: np.ndarray


class MRCLAMLocalization(EnvScenario):
    """``infonav/MRCLAMLocalization-v0`` as a scenario (spaces, reward, config: ``MRCLAMLocalizationEnv``)."""

    episode_metrics = (
        *LOCALIZATION_METRICS,
        EpisodeMetric("mean_pose_nees", "mean pose NEES [-]", mean_where("pose_nees", lambda step: True)),
        EpisodeMetric("gated_updates", "measurements gated out [-]", count_where(lambda step: step["gated"])),
    )
    traits = EnvTraits(
        kb_per_copy=10,  # [kB] at the defaults: the logs are shared by the copies
        estimates_pose=True,
        idle_actions=frozenset({NONE}),
        reward_terms=("mutual_information",),
        info_keys=frozenset({"pose_nees", "gated", "robot", "action_range_m", "fused_readings"}),
        noop_action=NONE,
        main_metric="cumulative_mi",
    )

    @classmethod
    def default_config(cls) -> dict:
        return {
            **shared_config(),
            "horizon": 100,  # episode length [measurement times]
            "robots": "",  # the robots episodes are drawn from, subject numbers such as "1,2,3" ("": every robot)
            "fuse_every_reading": False,  # True: every reading measured is fused, whatever the action (reference)
            **log_config(),
        }

    def __init__(self, config: dict, copies: int, owner: str, render_mode: str | None):
        super().__init__(config, copies, owner, render_mode)
        check_config(config, owner, LOG_CONFIG_INTERVALS)
        self.logs = load_logs(robot_logs, config, owner)
        self.starts = episode_starts(self.logs, config, owner)
        self.flat = FlatLogs.of(self.logs)
        n_landmarks = len(self.logs.landmarks)
        self.action_space = spaces.Discrete(1 + n_landmarks)
        low, high = POSE_LOW + READING_LOW * n_landmarks, POSE_HIGH + READING_HIGH * n_landmarks
        self.observation_space = spaces.Box(np.float32(low), np.float32(high), dtype=np.float32)
        self.bounds = np.array(low, dtype=float), np.array(high, dtype=float)
        self.landmark_rows = stacked(self.logs.landmarks, (copies, n_landmarks, 2))  # every copy's map, once
        self.reading_noise, self.control_covariances = filter_noise(
            config, owner, self.flat.measured, self.flat.readings, len(self.logs.robots), self.logs.tick_s
        )
        if len(self.reading_noise) == 1:  # the same noise for every reading: every copy's rows, once
            self.reading_noise = stacked(self.reading_noise[0], (copies, n_landmarks, 2, 2))

    def allocate(self, copies: int) -> MRCLAMState:
        return MRCLAMState(
            elapsed=np.zeros(copies, dtype=int),
            robot=np.zeros(copies, dtype=int),
            step=np.zeros(copies, dtype=int),
            action=np.full(copies, -1),
            x=np.zeros((copies, POSE_DIM)),
            P=np.tile(np.eye(POSE_DIM), (copies, 1, 1)),
            chosen=np.full(copies, -1),
            gated=np.zeros(copies, dtype=bool),
            fused=np.zeros(copies, dtype=int),
            mutual_information=np.zeros(copies),
        )

    def initial(self, state: MRCLAMState, rows: np.ndarray, rngs: list) -> MRCLAMState:
        """Each copy draws a robot, then its episode's first step, then its prior around the ground truth there."""
        cfg = self.config
        stds = np.array([cfg["initial_position_std_m"]] * 2 + [cfg["initial_heading_std_rad"]])
        for copy, rng in zip(rows.tolist(), rngs):
            robot, starts = self.starts[rng.integers(len(self.starts))]
            step = int(starts[rng.integers(len(starts))])
            x = self.logs.robots[robot].truth[step] + stds * rng.standard_normal(POSE_DIM)
            state.robot[copy], state.step[copy] = robot, step
            state.x[copy], state.P[copy] = (*x[:2], wrap_angle(x[2])), np.diag(stds**2)
        state.action[rows], state.chosen[rows], state.gated[rows], state.fused[rows] = -1, -1, False, 0
        state.mutual_information[rows] = 0.0
        if rows[0] == 0:
            self._follow_first_copy(state, restarted=True)
        return state

    def decision(self, state: MRCLAMState, rows) -> MRCLAMDecision:
        """What each copy measured at its step, and the expected MI of fusing each at its prior."""
        at = self.flat.offsets[state.robot[rows]] + state.step[rows]
        measured, x, P = self.flat.measured[at], contiguous(state.x[rows]), contiguous(state.P[rows])
        n_copies, n_landmarks = measured.shape
        predicted, H, _ = range_bearing_models(x, self.landmark_rows[:n_copies], False)  # under the robot: gated out
        R = self.reading_noise[at] if self.config["calibrated_noise"] else self.reading_noise[:n_copies]
        gains = np.where(measured, landmark_gains(P, H, R), 0.0)
        mask = np.ones((n_copies, 1 + n_landmarks), dtype=np.int8)
        mask[:, 1:] = measured
        gain = np.zeros((n_copies, 1 + n_landmarks))
        gain[:, 1:] = gains
        readings, truth = self.flat.readings[at], self.flat.truth[at]
        return MRCLAMDecision(mask, gain, readings, predicted, H, R, stacked_log_dets(P), truth)

    def transition(self, state: MRCLAMState, decision: MRCLAMDecision, action, acting) -> MRCLAMState:
        """Fuse each copy's chosen reading unless its NIS exceeds ``gate_nis``, then predict it through the odometry
        to its next measurement time."""
        action = action[:, 0]
        landmark, rows = np.where(action >= 1, action - 1, -1), np.arange(len(action))
        if self.config["fuse_every_reading"]:
            tried = decision.action_mask[:, 1:] == 1
        else:
            tried = np.zeros(decision.readings.shape[:2], dtype=bool)
            tried[rows, landmark] = landmark >= 0
        gated = tried & (reading_nis(state.P, decision, tried) > self.config["gate_nis"])
        fused = tried & ~gated
        state.x, state.P, state.mutual_information = landmark_reading_updates(
            state.x,
            state.P,
            decision.readings,
            fused,
            decision.predicted,
            decision.H,
            decision.R,
            decision.prior_log_det,
        )
        state.action, state.gated, state.fused = action.copy(), gated.any(axis=1), fused.sum(axis=1)
        state.chosen = np.where((landmark >= 0) & fused[rows, landmark], landmark, -1)
        copies = np.flatnonzero(acting)
        at = self.flat.offsets[state.robot[copies]] + state.step[copies]
        state.x[copies], state.P[copies] = predicted_over_ticks(
            contiguous(state.x[copies]),
            contiguous(state.P[copies]),
            self.flat.controls,
            state.robot[copies],
            self.flat.ticks[at],
            self.flat.ticks[np.minimum(at + 1, self.flat.last[state.robot[copies]])],
            self.logs.tick_s,
            self.control_covariances,
        )
        state.step[copies] = np.minimum(
            state.step[copies] + 1, self.flat.last[state.robot[copies]] - self.flat.offsets[state.robot[copies]]
        )
        if acting[0]:
            self._follow_first_copy(state, restarted=False)
        return state

    def reward(self, decision, action, state: MRCLAMState) -> np.ndarray:
        """The realized mutual information of each copy's update [nats] (0 without one)."""
        return state.mutual_information.copy()

    def observation(self, state: MRCLAMState, decision: MRCLAMDecision, rows) -> np.ndarray:
        fraction = state.elapsed[rows] / self.config["horizon"]
        return mrclam_observations(
            contiguous(state.x[rows]),
            contiguous(state.P[rows]),
            decision.action_mask,
            decision.readings,
            fraction,
            *self.bounds,
        )

    def info(self, state: MRCLAMState, decision: MRCLAMDecision, rows, stepped) -> dict:
        """The decision's mask and gains, the reward term, the action taken, the pose error and NEES against the
        ground truth, whether the chosen reading was gated out, the robot and the time [s]."""
        rewards = state.mutual_information[rows]
        info = decision_info(decision, stepped, state.action[rows], ("mutual_information",), rewards[None])
        x, P, truth = state.x[rows], state.P[rows], decision.true_pose
        error = truth - x
        error[:, 2] = wrap_angle(error[:, 2])
        entropy = gaussian_entropy_from_log_det(decision.prior_log_det, POSE_DIM)
        at = self.flat.offsets[state.robot[rows]] + state.step[rows]
        info.update(
            true_pose=truth.copy(),
            estimated_pose=x.copy(),
            position_error_m=np.hypot(error[:, 0], error[:, 1]),
            heading_error_rad=np.abs(error[:, 2]),
            pose_nees=np.einsum("ni,nij,nj->n", error, np.linalg.inv(P), error),
            pose_entropy=entropy,
            state_entropy=entropy.copy(),
            gated=state.gated[rows] & stepped,
            fused_readings=np.where(stepped, state.fused[rows], 0),
            action_range_m=reading_ranges(decision.action_mask, decision.readings),
            robot=np.array([self.logs.robots[robot].subject for robot in state.robot[rows]]),
            time_s=self.flat.ticks[at] * self.logs.tick_s,
        )
        return info

    def frame(self, state: MRCLAMState, decision: MRCLAMDecision) -> SceneFrame:
        """Copy 0: the landmark map (those measured now marked, the fused one linked), the robot's truth and
        estimate."""
        landmarks = self.logs.landmarks
        low, high = landmarks.min(axis=0) - 1.0, landmarks.max(axis=0) + 1.0
        chosen, subject = int(state.chosen[0]), self.logs.robots[state.robot[0]].subject
        drawing = RobotDrawing(
            true_pose=decision.true_pose[0].copy(),
            estimated_pose=state.x[0].copy(),
            pose_covariance=state.P[0].copy(),
            true_path=state.paths[0].points(),
            estimated_path=state.paths[1].points(),
        )
        time_s = self.flat.ticks[self.flat.offsets[state.robot[0]] + state.step[0]] * self.logs.tick_s
        return SceneFrame(
            bounds=(*low, *high),
            landmarks=landmarks,
            landmark_visible=decision.action_mask[0, 1:].astype(bool),
            chosen_landmark=None if chosen < 0 else chosen,
            robots=[drawing],
            caption=f"MRCLAM robot {subject}, t = {time_s:.1f} s   MI {state.mutual_information[0]:.2f} nats",
        )

    def _follow_first_copy(self, state: MRCLAMState, restarted: bool) -> None:
        """When drawing: start copy 0's true and estimated paths anew (``restarted``) or extend them."""
        if not self.drawing:
            return
        at = self.flat.offsets[state.robot[0]] + state.step[0]
        state.paths = extended_paths(state.paths, (self.flat.truth[at, :2], state.x[0, :2]), restarted)


@dataclass(frozen=True)
class FlatLogs:
    """Every robot's steps one after another (``offsets[robot] + step`` indexes them, up to ``last[robot]``): their
    ticks, readings, measured flags and ground truth; the odometry of every robot on the shared clock (T, robots, 2)."""

    offsets: np.ndarray
    last: np.ndarray
    ticks: np.ndarray
    measured: np.ndarray
    readings: np.ndarray
    truth: np.ndarray
    controls: np.ndarray

    @classmethod
    def of(cls, logs: DatasetLogs) -> FlatLogs:
        robots = logs.robots
        sizes = [len(log.ticks) for log in robots]
        return cls(
            offsets=np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(int),
            last=np.cumsum(sizes) - 1,
            ticks=np.concatenate([log.ticks for log in robots]),
            measured=np.concatenate([log.measured for log in robots]),
            readings=np.concatenate([log.readings for log in robots]),
            truth=np.concatenate([log.truth for log in robots]),
            controls=np.ascontiguousarray(np.stack([log.controls for log in robots], axis=1)),
        )


def episode_starts(logs: DatasetLogs, config: dict, owner: str) -> list[tuple[int, np.ndarray]]:
    """``(robot, first steps)`` of each robot with room for an episode: ``horizon`` steps and the one after them
    inside ``[time_from_s, time_to_s]``, with ground truth at each; ``ValueError`` when no robot has one."""
    subjects = [log.subject for log in logs.robots]
    wanted = parse_robots(config["robots"], subjects, owner)
    horizon, starts = config["horizon"], []
    for robot, log in enumerate(logs.robots):
        times = logs.times_s(log)
        usable = (times >= config["time_from_s"]) & (times <= config["time_to_s"]) & np.isfinite(log.truth).all(1)
        runs = np.convolve(usable, np.ones(horizon + 1, dtype=int), mode="valid") == horizon + 1
        if log.subject in wanted and runs.any():
            starts.append((robot, np.flatnonzero(runs)))
    if not starts:
        raise ValueError(
            f"{owner}: no robot of {sorted(wanted)} has {config['horizon'] + 1} measurement times with ground truth "
            f"between time_from_s={config['time_from_s']} and time_to_s={config['time_to_s']} s of "
            f"{logs.path}: shorten the horizon or widen the range"
        )
    return starts


def parse_robots(text: str, subjects: list[int], owner: str) -> set[int]:
    """The subject numbers of the config key ``robots`` (``"1,3"``; ``""``: all of ``subjects``)."""
    if not text.strip():
        return set(subjects)
    try:
        wanted = {int(part) for part in text.split(",")}
    except ValueError:
        raise ValueError(f"config key 'robots' of {owner} must list subject numbers ('1,2'), got {text!r}") from None
    if not wanted <= set(subjects):
        raise ValueError(f"config key 'robots' of {owner}: no robot {sorted(wanted - set(subjects))}; has {subjects}")
    return wanted


def reading_nis(P: np.ndarray, decision: MRCLAMDecision, tried: np.ndarray) -> np.ndarray:
    """The normalized innovation squared of the readings ``tried`` (n, L) at each copy's prior (n, L), 0 elsewhere."""
    copies, landmarks = np.nonzero(tried)
    H, R = decision.H[copies, landmarks], decision.R[copies, landmarks]
    residual = decision.readings[copies, landmarks] - decision.predicted[copies, landmarks]
    residual[:, 1] = wrap_angle(residual[:, 1])
    S = H @ P[copies] @ H.transpose(0, 2, 1) + R
    nis = np.zeros(tried.shape)
    nis[copies, landmarks] = np.einsum("ni,ni->n", residual, np.linalg.solve(S, residual[..., None])[..., 0])
    return nis


@kernel
def landmark_reading_updates(x, P, readings, fused, predicted, H, R, prior_log_det):
    """The EKF update of each copy with its readings ``[range, bearing]`` (n, L, 2) of the landmarks ``fused`` (n, L)
    stacked in landmark order (none: unchanged), at the prior's ``predicted`` (n, L, 2), ``H`` (n, L, 2, 3), ``R`` (n,
    L, 2, 2): ``(x, P, realized MI (n,))``, MI ``0.5 (prior_log_det - ln det P_post)`` [nats] (0 without a reading)."""
    n_copies, n_landmarks = fused.shape
    residuals = np.zeros((n_copies, n_landmarks, 2))
    for c in range(n_copies):
        for k in range(n_landmarks):
            if fused[c, k]:
                residuals[c, k, 0] = readings[c, k, 0] - predicted[c, k, 0]
                residuals[c, k, 1] = wrap(readings[c, k, 1] - predicted[c, k, 1])
    x_new, P_new = kalman_updates(x, P, residuals, H, R, fused, 1, True)
    realized = np.zeros(n_copies)
    for c in range(n_copies):
        for k in range(n_landmarks):
            if fused[c, k]:
                realized[c] = mutual_information_kernel(prior_log_det[c], log_det_of(P_new[c]))
                break
    return x_new, P_new, realized


@kernel
def predicted_over_ticks(x, P, controls, robots, first, last, dt, covariances):
    """Each copy's pose ``x`` (n, 3), ``P`` (n, 3, 3) predicted tick by tick (``predict_poses``) through its robot's
    odometry ``controls[tick, robots[c]]`` (T, robots, 2) from tick ``first[c]`` to ``last[c]`` (exclusive); each
    tick's noise its robot's ``covariances[robots[c]]`` (robots, 2, 2)."""
    x_new, P_new, reading = np.empty(x.shape), np.empty(P.shape), np.empty((1, 1, 2))
    covariance = np.empty((1, 1, 2, 2))
    for c in range(len(x)):
        for i in range(2):
            for j in range(2):
                covariance[0, 0, i, j] = covariances[robots[c], i, j]
        one_x, one_P = np.empty((1, POSE_DIM)), np.empty((1, POSE_DIM, POSE_DIM))
        for i in range(POSE_DIM):
            one_x[0, i] = x[c, i]
            for j in range(POSE_DIM):
                one_P[0, i, j] = P[c, i, j]
        for tick in range(first[c], last[c]):
            reading[0, 0, 0], reading[0, 0, 1] = controls[tick, robots[c], 0], controls[tick, robots[c], 1]
            one_x, one_P = predict_poses(one_x, one_P, reading, dt, covariance)
        for i in range(POSE_DIM):
            x_new[c, i] = one_x[0, i]
            for j in range(POSE_DIM):
                P_new[c, i, j] = one_P[0, i, j]
    return x_new, P_new


@kernel
def mrclam_observations(x, P, mask, readings, elapsed_fraction, low, high):
    """The observations (n, 10 + 4L) float32: the ``pose_features``, then per landmark whether it was measured and
    its measured range and bearing (``range_bearing_features``; zeros where not measured), clipped to ``low``,
    ``high``."""
    n_copies = readings.shape[0]
    observation = np.empty((n_copies, len(low)), dtype=np.float32)
    values = np.empty(len(low))
    for c in range(n_copies):
        values[:] = 0.0
        pose_features(values, x[c], P[c], gaussian_entropy_kernel(log_det_of(P[c]), POSE_DIM), elapsed_fraction[c])
        reading_features(values, POSE_FEATURES, mask[c, 1:], readings[c])
        clip_into(observation[c], values, low, high)
    return observation


class MRCLAMLocalizationVectorEnv(Driver, scenario=MRCLAMLocalization):
    """N copies of ``infonav/MRCLAMLocalization-v0``: each copy an episode of its own robot and window of the log."""


class MRCLAMLocalizationEnv(SingleEnvView, vector_env=MRCLAMLocalizationVectorEnv):
    """A real robot's log (UTIAS MRCLAM): at each time it measured landmarks, choose which measurement to fuse.

    ## Description
    The robot's own odometry (tick means of ``odometry_tick_s``) predicts its pose through an EKF between the times
    its camera measured landmarks; at each such time the agent picks one of the landmarks actually measured then (or
    none) and the EKF fuses that real range-bearing reading, unless its normalized innovation squared exceeds
    ``gate_nis`` (real logs hold outliers). An episode is a window of ``horizon`` measurement times of one robot; the
    seed picks the robot (among ``robots``) and the window (inside ``[time_from_s, time_to_s]``, so that training and
    evaluation can use disjoint times). The Vicon ground truth scores the estimate. ``log_correction`` replays the logs
    corrected by a calibrated noise model (``"shipped"``: the one fitted on Dataset 6's ground truth; or a JSON file of
    ``infonav replay mrclam --calibrate``): the sensors' clocks aligned, the odometry's scales and the readings' mean
    errors removed.

    The dataset directory is ``dataset_dir``, else ``$INFONAV_MRCLAM_DATASET``, else
    ``../shared/datasets/MRCLAM_Dataset6`` from the working directory (Leung et al., IJRR 2011; not shipped); a
    missing or malformed directory is a one-line ``ValueError`` naming the file.

    ## Action Space
    ``Discrete(1 + L)`` (L landmarks of the map, 15 in Dataset 6): 0 fuses nothing, ``k`` fuses landmark ``k - 1``'s
    reading; valid where that landmark was measured at this time (``info["action_mask"]``).

    ## Observation Space
    ``Box(float32, (10 + 4 L,))``: the estimated ``x, y`` [m], ``cos, sin`` of the heading, the standard deviations of
    ``x, y`` [m] and heading [rad], the ``x-y`` correlation, the pose entropy [nats] and the elapsed fraction of the
    horizon; then per landmark: measured flag, measured range [m], ``cos, sin`` of the measured bearing (zeros where
    not measured).

    ## Rewards
    The realized mutual information of the update, ``0.5 ln(det P_prior / det P_post)`` [nats] (0 for none and for a
    gated reading); ``info["action_information_gain"]`` is its expectation for each action.

    ## Starting State
    The ground-truth pose at the window's first measurement time plus a draw from the prior
    ``N(0, diag(initial_position_std_m^2, ..., initial_heading_std_rad^2))``.

    ## Episode End
    Truncated after ``horizon`` measurement times; never terminated.

    ## Arguments
    ``gym.make("infonav/MRCLAMLocalization-v0", render_mode=None, **config)`` with any key of ``default_config()``.

    ## Version History
    * v0: initial version.
    """
