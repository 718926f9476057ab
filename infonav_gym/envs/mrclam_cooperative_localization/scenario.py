"""``mrclam_cooperative_localization_v0``: a real team (UTIAS MRCLAM logs) localizes through the landmarks and the
teammates each robot measured, one robot losing its landmarks for a while (the paper's Fig. 3 outage, on real data).
``MRCLAMCooperativeLocalizationVectorEnv`` is its driver, ``MRCLAMCooperativeLocalizationEnv`` its PettingZoo view."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from infonav_gym.compiled import contiguous, inner_kernel, kernel, stacked
from infonav_gym.config import Interval, check_config
from infonav_gym.envs.base import shared_config
from infonav_gym.envs.driver import Driver
from infonav_gym.envs.metrics import TEAM_LOCALIZATION_METRICS, EpisodeMetric, team_mean_final_value
from infonav_gym.envs.mrclam_cooperative_localization.windows import TeamWindows, team_windows
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
from infonav_gym.envs.parallel_view import ParallelEnvView, TeamCycles, team_metadata
from infonav_gym.envs.protocol import EnvScenario, State
from infonav_gym.envs.real_logs import (
    END_OF_LOG_S,
    LOG_CONFIG_INTERVALS,
    filter_noise,
    load_logs,
    log_config,
    reading_ranges,
)
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.envs.vector_infos import reward_term_key
from infonav_gym.estimation.kernels import kalman_updates, pose_block_log_det, predict_poses, range_bearing_of_offset
from infonav_gym.estimation.state import POSE_DIM, block_diagonal
from infonav_gym.geometry import wrap_angle
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.information import (
    gaussian_entropy_from_log_det,
    gaussian_entropy_kernel,
    log_det_of,
    mutual_information_kernel,
)
from infonav_gym.multi.team_paths import FirstCopyPaths
from infonav_gym.scene import SceneFrame

NONE = 0  # the action that fuses nothing; action k >= 1 fuses target k - 1's reading (landmarks, then robots)
CONFIG_INTERVALS = {
    **LOG_CONFIG_INTERVALS,
    "time_step_s": Interval(1e-3, 60.0, unit="s"),
    "outage_robot": Interval(0, 1000, integer=True),
    "team_reward": Interval(0.0, 1.0),
    "outage_from_s": Interval(0.0, END_OF_LOG_S, unit="s"),
    "outage_to_s": Interval(0.0, END_OF_LOG_S, unit="s"),
}


@dataclass
class MRCLAMTeamState(State):
    """Each copy's window of the logs (N,), its joint EKF ``x`` (N, 3R) and ``P`` (N, 3R, 3R), each robot's last
    action (``NONE`` for a masked one), whether it was masked, the target it fused (-1: none) and whether that
    reading was gated out (N, R); the MI [nats] the step
    brought to each robot's pose (N, R) and to the joint state (N,); copy 0's paths (when drawing)."""

    window: np.ndarray
    x: np.ndarray
    P: np.ndarray
    action: np.ndarray
    invalid: np.ndarray
    chosen: np.ndarray
    gated: np.ndarray
    fused: np.ndarray
    own_mi: np.ndarray
    team_mi: np.ndarray
    paths: FirstCopyPaths | None = None


class MRCLAMTeamDecision(NamedTuple):
    """Every copy's choice at its prior: each robot's mask and expected gain of fusing nothing or each target's reading
    (n, R, 1 + T), the readings (n, R, T, 2), their ticks in the window (n, R, T) and noise covariances (n, R, T, 2,
    2), whether each robot's landmarks
    are available (n, R), each robot's pose ``ln det`` (n, R) and ground truth at the window's start (n, R, 3)."""

    action_mask: np.ndarray
    action_information_gain: np.ndarray
    readings: np.ndarray
    offsets: np.ndarray
    noise: np.ndarray
    landmarks_available: np.ndarray
    pose_log_det: np.ndarray
    true_pose: np.ndarray


class MRCLAMCooperativeLocalization(EnvScenario):
    """``mrclam_cooperative_localization_v0`` as a scenario (spaces, rewards, config: its PettingZoo env)."""

    team = True
    horizon_key = "max_cycles"
    team_info_keys = frozenset({"time_s", "log_time_s"})
    metadata = team_metadata("mrclam_cooperative_localization_v0")
    episode_metrics = (
        *TEAM_LOCALIZATION_METRICS,
        EpisodeMetric("mean_pose_nees", "mean pose NEES [-]", team_mean_final_value("mean_pose_nees")),
    )
    traits = EnvTraits(
        kb_per_copy=3,  # [kB] at the defaults: the logs are shared by the copies
        idle_actions=frozenset({NONE}),
        reward_terms=("own_mutual_information", "team_mutual_information"),
        info_keys=frozenset(
            {"pose_nees", "mean_pose_nees", "gated", "landmarks_available", "position_error_m", "heading_error_rad"}
            | {"log_time_s", "action_range_m", "fused_readings"}
            | {"pose_entropy", "estimated_pose"}
        ),
        reward_config_keys=("team_reward",),
        noop_action=NONE,
        main_metric="cumulative_mi",
    )

    @classmethod
    def default_config(cls) -> dict:
        return {
            **{key: value for key, value in shared_config().items() if key != "horizon"},  # max_cycles is it
            "max_cycles": 100,  # episode length [steps]
            "time_step_s": 0.5,  # [s] a step: what each robot measured in this much of the log (whole ticks)
            "team_reward": 0.0,  # weight of the team's MI in each robot's reward, in [0, 1]
            "fuse_every_reading": False,  # True: every reading measured is fused, whatever the actions (reference)
            "outage_robot": 0,  # the robot (robot_k: k) whose landmark readings drop out ...
            "outage_from_s": 10.0,  # [s] ... from this time of the episode ...
            "outage_to_s": 40.0,  # [s] ... to this one (outage_from_s: no outage)
            **log_config(),
        }

    def __init__(self, config: dict, copies: int, owner: str, render_mode: str | None):
        super().__init__(config, copies, owner, render_mode)
        check_config(config, owner, CONFIG_INTERVALS)
        self.windows = load_logs(team_windows, config, owner, float(config["time_step_s"]))
        windows, n_landmarks = self.windows, len(self.windows.landmarks)
        n_robots = len(windows.subjects)
        self.agents = [f"robot_{k}" for k in range(n_robots)]
        self.outage_robot = outage_index(config, n_robots, owner)
        self.starts = team_episode_starts(windows, config, owner)
        n_targets = n_landmarks + n_robots
        self.action_space = spaces.Discrete(1 + n_targets)
        low = POSE_LOW + [0] + READING_LOW * n_targets
        high = POSE_HIGH + [1] + READING_HIGH * n_targets
        self.observation_space = spaces.Box(np.float32(low), np.float32(high), dtype=np.float32)
        self.bounds = np.array(low, dtype=float), np.array(high, dtype=float)
        self.reading_noise, odometry = filter_noise(
            config, owner, windows.measured, windows.readings, n_robots, windows.tick_s
        )
        self.control_covariance = contiguous(odometry[None])
        if len(self.reading_noise) == 1:  # the same noise for every reading: every copy's rows, once
            self.reading_noise = stacked(self.reading_noise[0], (copies, n_robots, n_targets, 2, 2))

    def allocate(self, copies: int) -> MRCLAMTeamState:
        shape, dim = (copies, len(self.agents)), POSE_DIM * len(self.agents)
        return MRCLAMTeamState(
            elapsed=np.zeros(copies, dtype=int),
            window=np.zeros(copies, dtype=int),
            x=np.zeros((copies, dim)),
            P=np.tile(np.eye(dim), (copies, 1, 1)),
            action=np.full(shape, NONE),
            invalid=np.zeros(shape, dtype=bool),
            chosen=np.full(shape, -1),
            gated=np.zeros(shape, dtype=bool),
            fused=np.zeros(shape, dtype=int),
            own_mi=np.zeros(shape),
            team_mi=np.zeros(copies),
        )

    def initial(self, state: MRCLAMTeamState, rows: np.ndarray, rngs: list) -> MRCLAMTeamState:
        """Each copy draws its episode's first window, then every robot's prior around the ground truth there."""
        cfg, n_robots = self.config, len(self.agents)
        stds = np.array([cfg["initial_position_std_m"]] * 2 + [cfg["initial_heading_std_rad"]])
        for copy, rng in zip(rows.tolist(), rngs):
            window = int(self.starts[rng.integers(len(self.starts))])
            poses = self.windows.truth[window] + stds * rng.standard_normal((n_robots, POSE_DIM))
            poses[:, 2] = wrap_angle(poses[:, 2])
            state.window[copy], state.x[copy] = window, poses.ravel()
            state.P[copy] = block_diagonal(np.repeat(np.diag(stds**2)[None], n_robots, axis=0))
        state.action[rows], state.invalid[rows], state.chosen[rows], state.gated[rows] = NONE, False, -1, False
        state.fused[rows] = 0
        state.own_mi[rows], state.team_mi[rows] = 0.0, 0.0
        if rows[0] == 0 and self.drawing:
            state.paths = FirstCopyPaths(self.windows.truth[state.window[0]], state.x[0].reshape(-1, POSE_DIM))
        return state

    def decision(self, state: MRCLAMTeamState, rows) -> MRCLAMTeamDecision:
        """What each robot measured in its copy's window (a robot in its outage: its teammates only), and the expected
        MI of fusing each reading alone at the window's start."""
        windows, window = self.windows, state.window[rows]
        available = self.landmarks_available(state.elapsed[rows])
        measured = windows.measured[window]
        measured[:, :, : len(windows.landmarks)] &= available[:, :, None]
        x, P = contiguous(state.x[rows]), contiguous(state.P[rows])
        noise = self.reading_noise[window] if self.config["calibrated_noise"] else self.reading_noise[: len(window)]
        mask, gains, log_dets = team_reading_gains(
            x, P, measured, windows.landmarks, noise, float(self.config["team_reward"])
        )
        readings, offsets, truth = windows.readings[window], windows.offsets[window], windows.truth[window]
        return MRCLAMTeamDecision(mask, gains, readings, offsets, noise, available, log_dets, truth)

    def landmarks_available(self, elapsed: np.ndarray) -> np.ndarray:
        """Whether each robot may use its landmark readings after ``elapsed`` (n,) steps (n, R): not the outage
        robot's inside ``[outage_from_s, outage_to_s)`` of its episode."""
        available = np.ones((len(elapsed), len(self.agents)), dtype=bool)
        if self.outage_robot is not None:
            time_s = elapsed * self.windows.window_s
            available[:, self.outage_robot] = ~(
                (time_s >= self.config["outage_from_s"]) & (time_s < self.config["outage_to_s"])
            )
        return available

    def transition(self, state: MRCLAMTeamState, decision, action, acting) -> MRCLAMTeamState:
        """Through each ``acting`` copy's window tick by tick: fuse every robot's chosen reading at its tick (unless its
        NIS exceeds ``gate_nis``), predict every robot through its odometry."""
        chosen = np.where(action >= 1, action - 1, -1)
        if self.config["fuse_every_reading"]:
            tried = decision.action_mask[..., 1:] == 1
        else:
            tried = np.zeros(decision.readings.shape[:3], dtype=bool)
            copy, robot = np.nonzero(chosen >= 0)
            tried[copy, robot, chosen[copy, robot]] = True
        copies = np.flatnonzero(acting)
        state.own_mi[:], state.team_mi[:], state.gated[:], state.fused[:] = 0.0, 0.0, False, 0
        if copies.size:
            windows = self.windows
            x, P, own, team, gated, fused = fused_windows(
                contiguous(state.x[copies]),
                contiguous(state.P[copies]),
                windows.controls,
                state.window[copies] * windows.window_ticks,
                windows.window_ticks,
                windows.tick_s,
                self.control_covariance,
                contiguous(tried[copies]),
                contiguous(decision.readings[copies]),
                contiguous(decision.offsets[copies]),
                windows.landmarks,
                contiguous(decision.noise[copies]),
                float(self.config["gate_nis"]),
            )
            state.x[copies], state.P[copies], state.own_mi[copies], state.team_mi[copies] = x, P, own, team
            state.gated[copies], state.fused[copies] = gated, fused
            state.window[copies] += 1
        state.action, state.invalid = np.where(action >= 0, action, NONE), acting[:, None] & (action < 0)
        state.chosen = np.where(state.gated, -1, chosen)
        if acting[0] and state.paths is not None:
            state.paths.extend(self.windows.truth[state.window[0]], state.x[0].reshape(-1, POSE_DIM))
        return state

    def reward(self, decision, action, state: MRCLAMTeamState) -> np.ndarray:
        """Each robot's own-pose MI of the step's updates mixed with the team's by ``team_reward`` [nats]."""
        weight = self.config["team_reward"]
        return (1.0 - weight) * state.own_mi + weight * state.team_mi[:, None]

    def observation(self, state: MRCLAMTeamState, decision: MRCLAMTeamDecision, rows) -> np.ndarray:
        fraction = state.elapsed[rows] / self.config["max_cycles"]
        return team_log_observations(
            contiguous(state.x[rows]),
            contiguous(state.P[rows]),
            decision.action_mask,
            decision.readings,
            decision.landmarks_available,
            fraction,
            *self.bounds,
        )

    def info(self, state: MRCLAMTeamState, decision: MRCLAMTeamDecision, rows, stepped) -> dict:
        """Each robot's mask and gains, reward terms, action, pose error and NEES against the ground truth, whether its
        reading was gated out and its landmarks available; the time in the log [s]."""
        n_robots = len(self.agents)
        estimates = state.x[rows].reshape(-1, n_robots, POSE_DIM)
        errors = decision.true_pose - estimates
        errors[..., 2] = wrap_angle(errors[..., 2])
        P = state.P[rows]
        blocks = np.stack([P[:, 3 * k : 3 * k + 3, 3 * k : 3 * k + 3] for k in range(n_robots)], axis=1)
        nees = np.einsum("nri,nrij,nrj->nr", errors, np.linalg.inv(blocks), errors)
        terms = {
            "own_mutual_information": np.where(stepped[:, None], state.own_mi[rows], 0.0),
            "team_mutual_information": np.repeat(np.where(stepped, state.team_mi[rows], 0.0)[:, None], n_robots, 1),
        }
        stepped_robots = np.repeat(stepped[:, None], n_robots, axis=1)
        return {
            "action_mask": decision.action_mask.copy(),
            "action_information_gain": decision.action_information_gain.copy(),
            **{reward_term_key(key): value for key, value in terms.items()},
            "chosen_action": np.where(stepped_robots, state.action[rows], NONE),
            "invalid_action": state.invalid[rows] & stepped_robots,
            "true_pose": decision.true_pose.copy(),
            "estimated_pose": estimates.copy(),
            "position_error_m": np.hypot(errors[..., 0], errors[..., 1]),
            "heading_error_rad": np.abs(errors[..., 2]),
            "pose_entropy": gaussian_entropy_from_log_det(decision.pose_log_det, POSE_DIM),
            "pose_nees": nees,
            "mean_pose_nees": nees,  # the episode metric averages it over the steps
            "gated": state.gated[rows] & stepped_robots,
            "fused_readings": np.where(stepped_robots, state.fused[rows], 0),
            "landmarks_available": decision.landmarks_available.copy(),
            "action_range_m": reading_ranges(decision.action_mask, decision.readings),
            "time_s": (state.elapsed[rows] * self.windows.window_s).astype(float),
            "log_time_s": (state.window[rows] * self.windows.window_s).astype(float),
        }

    def frame(self, state: MRCLAMTeamState, decision: MRCLAMTeamDecision) -> SceneFrame:
        """Copy 0: the landmark map, every robot (truth, estimate, covariance, paths; "no GPS" in its outage) and the
        teammates observed this step."""
        landmarks, n_landmarks = self.windows.landmarks, len(self.windows.landmarks)
        low, high = landmarks.min(axis=0) - 1.0, landmarks.max(axis=0) + 1.0
        true_poses = decision.true_pose[0]
        robots = state.paths.drawings(true_poses, state.x[0], state.P[0], self.agents, decision.landmarks_available[0])
        observed = [(r, int(k) - n_landmarks) for r, k in enumerate(state.chosen[0]) if k >= n_landmarks]
        time_s = state.window[0] * self.windows.window_s
        return SceneFrame(
            bounds=(*low, *high),
            landmarks=landmarks,
            robots=robots,
            observations=observed,
            caption=f"MRCLAM team, t = {time_s:.1f} s   team MI {state.team_mi[0]:.2f} nats",
        )


def outage_index(config: dict, n_robots: int, owner: str) -> int | None:
    """The robot of the config key ``outage_robot`` (None: no outage, ``outage_to_s == outage_from_s``)."""
    if not config["outage_to_s"] >= config["outage_from_s"]:
        raise ValueError(f"config key 'outage_to_s' of {owner} must not precede 'outage_from_s'")
    if config["outage_robot"] >= n_robots:
        raise ValueError(
            f"config key 'outage_robot' of {owner}: no robot_{config['outage_robot']} in a team of {n_robots}"
        )
    return None if config["outage_to_s"] == config["outage_from_s"] else config["outage_robot"]


def team_episode_starts(windows: TeamWindows, config: dict, owner: str) -> np.ndarray:
    """The first windows of an episode: ``max_cycles`` windows inside ``[time_from_s, time_to_s]`` with every robot's
    ground truth at their starts and the last one's end; ``ValueError`` when there is none."""
    horizon = config["max_cycles"]
    times = windows.window_s * np.arange(len(windows.truth))
    usable = (times >= config["time_from_s"]) & (times <= config["time_to_s"]) & np.isfinite(windows.truth).all((1, 2))
    runs = np.convolve(usable, np.ones(horizon + 1, dtype=int), mode="valid") == horizon + 1
    if not runs.any():
        raise ValueError(
            f"{owner}: {windows.path} has no {horizon + 1} windows of {windows.window_s} s with every robot's ground "
            f"truth between time_from_s={config['time_from_s']} and time_to_s={config['time_to_s']} s: shorten "
            "max_cycles or time_step_s, or widen the range"
        )
    return np.flatnonzero(runs)


@kernel
def reading_model(x, robot, target, landmarks, predicted, H) -> bool:
    """The range-bearing model of robot ``robot``'s reading of ``target`` (a landmark of ``landmarks`` (L, 2), or
    robot ``target - L``) at the joint state ``x`` (3R,): ``predicted`` (2,), ``H`` (2, 3R) (zeroed first); False if
    the target lies on the robot."""
    for row in range(2):
        for k in range(H.shape[1]):
            H[row, k] = 0.0
    i, n_landmarks = POSE_DIM * robot, len(landmarks)
    if target < n_landmarks:
        tx, ty, j = landmarks[target, 0], landmarks[target, 1], -1
    else:
        j = POSE_DIM * (target - n_landmarks)
        tx, ty = x[j], x[j + 1]
    J = np.zeros((2, POSE_DIM))
    if not range_bearing_of_offset(tx - x[i], ty - x[i + 1], x[i + 2], predicted, J):
        return False
    for row in range(2):
        for k in range(POSE_DIM):
            H[row, i + k] = J[row, k]
        if j >= 0:
            H[row, j], H[row, j + 1] = -J[row, 0], -J[row, 1]
    return True


@inner_kernel
def innovation(P, H, R, HP, S_inverse) -> float:
    """One reading's ``H P`` into ``HP`` (2, n) and ``S^-1`` into ``S_inverse`` (2, 2), ``S = H P H^T + R``, at ``P``
    (n, n); returns ``ln det S`` (NaN where it is not > 0)."""
    n = len(P)
    for a in range(2):
        for j in range(n):
            total = 0.0
            for k in range(n):
                total += H[a, k] * P[k, j]
            HP[a, j] = total
    s = np.empty((2, 2))
    for a in range(2):
        for b in range(2):
            total = R[a, b]
            for k in range(n):
                total += HP[a, k] * H[b, k]
            s[a, b] = total
    det = s[0, 0] * s[1, 1] - s[0, 1] * s[1, 0]
    S_inverse[0, 0], S_inverse[1, 1] = s[1, 1] / det, s[0, 0] / det
    S_inverse[0, 1], S_inverse[1, 0] = -s[0, 1] / det, -s[1, 0] / det
    return math.log(det) if det > 0.0 else math.nan


@inner_kernel
def reading_gains(P, H, R, robot, HP, S_inverse, block) -> tuple:
    """The MI of one reading (``H`` (2, n), noise ``R`` (2, 2)) at ``P`` (n, n) on robot ``robot``'s pose and on the
    joint state [nats]: ``0.5 ln(det P_rr / det P_rr,post)`` and ``0.5 ln(det S / det R)``."""
    log_det_S = innovation(P, H, R, HP, S_inverse)
    i = POSE_DIM * robot
    prior = pose_block_log_det(P, i, block)
    for a in range(POSE_DIM):
        for b in range(POSE_DIM):
            correction = 0.0
            for p in range(2):
                for q in range(2):
                    correction += HP[p, i + a] * S_inverse[p, q] * HP[q, i + b]
            block[a, b] = P[i + a, i + b] - correction
    return mutual_information_kernel(prior, log_det_of(block)), mutual_information_kernel(log_det_S, log_det_of(R))


@kernel
def team_reading_gains(x, P, measured, landmarks, R, team_reward):
    """Each robot's mask (n, R, 1 + T) int8 (nothing, always; each target it ``measured`` (n, R, T)) and expected gain
    of each (``reading_gains`` at its noise ``R`` (n, R, T, 2, 2), mixed by ``team_reward``, 0 where masked), and each
    robot's pose ``ln det`` (n, R)."""
    n_copies, n_robots, n_targets = measured.shape
    mask, gains = np.zeros((n_copies, n_robots, 1 + n_targets), np.int8), np.zeros((n_copies, n_robots, 1 + n_targets))
    log_dets = np.empty((n_copies, n_robots))
    predicted, H, block = np.empty(2), np.empty((2, x.shape[1])), np.empty((POSE_DIM, POSE_DIM))
    HP, S_inverse = np.empty((2, x.shape[1])), np.empty((2, 2))
    for c in range(n_copies):
        for robot in range(n_robots):
            mask[c, robot, 0] = 1
            log_dets[c, robot] = pose_block_log_det(P[c], POSE_DIM * robot, block)
            for target in range(n_targets):
                if measured[c, robot, target] and reading_model(x[c], robot, target, landmarks, predicted, H):
                    own, joint = reading_gains(P[c], H, R[c, robot, target], robot, HP, S_inverse, block)
                    mask[c, robot, 1 + target] = 1
                    gains[c, robot, 1 + target] = (1.0 - team_reward) * own + team_reward * joint
    return mask, gains, log_dets


@kernel
def fused_windows(
    x, P, controls, first_tick, width, dt, control_covariance, tried, readings, offsets, landmarks, R, gate
):
    """Each copy's joint EKF (``x`` (n, 3R), ``P``) through its window of ``width`` ticks from ``first_tick`` (n,): at
    each tick, the readings ``tried`` (n, R, T) of that tick (``readings`` (n, R, T, 2) at ``offsets`` (n, R, T))
    fused one by one in robot, then target order (noise ``R`` (n, R, T, 2, 2)) unless its NIS exceeds ``gate``, then
    every robot predicted through
    its odometry ``controls`` (ticks, R, 2). Returns ``(x, P, own MI (n, R), joint MI (n,), gated (n, R), fused (n,
    R))``: the MI [nats] summed over the window's updates, whether a robot's reading was gated out, how many fused."""
    n_copies, n = x.shape
    n_robots, n_targets = tried.shape[1], tried.shape[2]
    x_new, P_new = np.empty(x.shape), np.empty(P.shape)
    own, joint, gated = np.zeros((n_copies, n_robots)), np.zeros(n_copies), np.zeros((n_copies, n_robots), np.bool_)
    fused = np.zeros((n_copies, n_robots), np.int64)
    predicted, H, block = np.empty(2), np.empty((2, n)), np.empty((POSE_DIM, POSE_DIM))
    HP, S_inverse, priors = np.empty((2, n)), np.empty((2, 2)), np.empty(n_robots)
    residual, rows = np.zeros((1, 1, 2)), np.zeros((1, 1, 2, n))
    noise, used, reading = np.zeros((1, 1, 2, 2)), np.ones((1, 1), np.bool_), np.empty((1, n_robots, 2))
    for c in range(n_copies):
        one_x, one_P = x[c : c + 1].copy(), P[c : c + 1].copy()
        for offset in range(width):
            for slot in range(n_robots * n_targets):
                robot, target = slot // n_targets, slot % n_targets
                if not tried[c, robot, target] or offsets[c, robot, target] != offset:
                    continue
                if not reading_model(one_x[0], robot, target, landmarks, predicted, H):
                    continue
                residual[0, 0, 0] = readings[c, robot, target, 0] - predicted[0]
                residual[0, 0, 1] = wrap(readings[c, robot, target, 1] - predicted[1])
                for a in range(2):
                    for b in range(2):
                        noise[0, 0, a, b] = R[c, robot, target, a, b]
                innovation(one_P[0], H, noise[0, 0], HP, S_inverse)
                nis = 0.0
                for a in range(2):
                    for b in range(2):
                        nis += residual[0, 0, a] * S_inverse[a, b] * residual[0, 0, b]
                if not nis <= gate:
                    gated[c, robot] = True
                    continue
                for a in range(2):
                    for j in range(n):
                        rows[0, 0, a, j] = H[a, j]
                for k in range(n_robots):
                    priors[k] = pose_block_log_det(one_P[0], POSE_DIM * k, block)
                prior_joint = log_det_of(one_P[0])
                one_x, one_P = kalman_updates(one_x, one_P, residual, rows, noise, used, n_robots, True)
                joint[c] += mutual_information_kernel(prior_joint, log_det_of(one_P[0]))
                fused[c, robot] += 1
                for k in range(n_robots):
                    own[c, k] += mutual_information_kernel(priors[k], pose_block_log_det(one_P[0], POSE_DIM * k, block))
            for robot in range(n_robots):
                reading[0, robot, 0] = controls[first_tick[c] + offset, robot, 0]
                reading[0, robot, 1] = controls[first_tick[c] + offset, robot, 1]
            one_x, one_P = predict_poses(one_x, one_P, reading, dt, control_covariance)
        x_new[c], P_new[c] = one_x[0], one_P[0]
    return x_new, P_new, own, joint, gated, fused


@kernel
def team_log_observations(x, P, mask, readings, available, elapsed_fraction, low, high):
    """Each robot's observation (n, R, 11 + 4T) float32: its ``pose_features``, whether its landmarks are available,
    then per target whether it was measured and its measured range and bearing (``range_bearing_features``; zeros
    where not), clipped to ``low``, ``high``."""
    n_copies, n_robots = readings.shape[0], readings.shape[1]
    observation = np.empty((n_copies, n_robots, len(low)), dtype=np.float32)
    values, block = np.empty(len(low)), np.empty((POSE_DIM, POSE_DIM))
    pose = np.empty(POSE_DIM)
    for c in range(n_copies):
        for robot in range(n_robots):
            values[:] = 0.0
            i = POSE_DIM * robot
            for a in range(POSE_DIM):
                pose[a] = x[c, i + a]
            entropy = gaussian_entropy_kernel(pose_block_log_det(P[c], i, block), POSE_DIM)
            pose_features(values, pose, block, entropy, elapsed_fraction[c])
            values[POSE_FEATURES] = 1.0 if available[c, robot] else 0.0
            reading_features(values, POSE_FEATURES + 1, mask[c, robot, 1:], readings[c, robot])
            clip_into(observation[c, robot], values, low, high)
    return observation


class MRCLAMCooperativeLocalizationVectorEnv(TeamCycles, Driver, scenario=MRCLAMCooperativeLocalization):
    """N copies of ``mrclam_cooperative_localization_v0``: each copy an episode of the team at its own time of the
    log. Observations (N, R, 11 + 4T); rewards, ``terminated``, ``truncated`` (N, R); infos (N, R, ...) (``time_s``,
    ``log_time_s`` (N,)); ``info["action_mask"]`` (N, R, 1 + T)."""


class MRCLAMCooperativeLocalizationEnv(ParallelEnvView, vector_env=MRCLAMCooperativeLocalizationVectorEnv):
    """A real team's logs (UTIAS MRCLAM): at each step each robot chooses which of its landmark or teammate readings
    to fuse into the team's joint EKF.

    ## Description
    The paper's Section III-C on real data. The robots' own odometry (tick means of ``odometry_tick_s``) predicts a
    joint EKF over every robot's pose; a step is ``time_step_s`` of the log, in which each robot measured some landmarks
    and teammates with its camera (the first reading of each target in the step counts). Each robot picks one reading
    (or none); the joint EKF fuses it at its own tick, a teammate's range and bearing updating both robots' poses and
    correlating them, unless its normalized innovation squared exceeds ``gate_nis`` (real logs hold outliers). Robot
    ``outage_robot`` loses its landmark readings from ``outage_from_s`` to ``outage_to_s`` of each episode (as the
    paper's robot loses DGPS) and must rely on its teammates then. The Vicon ground truth scores the estimates. The
    seed picks the episode's time (inside ``[time_from_s, time_to_s]`` of the log, so that training and evaluation can
    use disjoint times); ``log_correction`` replays logs corrected by a calibrated noise model, as in
    ``infonav/MRCLAMLocalization-v0``, whose dataset lookup (``dataset_dir``) and one-line errors this env shares.

    ## Agents
    ``robot_0 .. robot_{R-1}``, the dataset's robots in the order of their subject numbers (``robot_0`` is MRCLAM's
    robot 1; five in Dataset 6).

    ## Action Space
    ``Discrete(1 + L + R)`` per agent: 0 fuses nothing, ``1 + k`` fuses landmark ``k``'s reading, ``1 + L + j``
    robot ``j``'s (in the agents' order); valid where the robot measured it in this step (never itself; no landmark in
    its outage) (``infos[agent]["action_mask"]``).

    ## Observation Space
    ``Box(float32, (11 + 4 (L + R),))`` per agent: the robot's estimated ``x, y`` [m], ``cos, sin`` of its heading,
    the standard deviations of ``x, y`` [m] and heading [rad], the ``x-y`` correlation, the pose entropy [nats], the
    elapsed fraction of ``max_cycles``, whether its landmarks are available; then per target (landmarks, then robots):
    measured flag, measured range [m], ``cos, sin`` of the measured bearing (zeros where not measured).

    ## Rewards
    The realized mutual information of the step's updates on the robot's own pose, each update's ``0.5 ln(det
    P_rr,prior / det P_rr,post)`` summed [nats], mixed with the team's (the MI on the joint state) by ``team_reward``:
    ``(1 - team_reward) * own + team_reward * team``. A robot's reward also counts what its teammates' readings
    brought it. ``action_information_gain[a]`` is the MI action ``a`` alone would bring at the step's prior.

    ## Info
    ``infos[agent]``: ``action_mask``, ``action_information_gain``, ``reward_own_mutual_information`` and
    ``reward_team_mutual_information`` (the reward's terms),
    ``chosen_action``, ``invalid_action``, ``true_pose``, ``estimated_pose``, ``position_error_m``,
    ``heading_error_rad``, ``pose_entropy``, ``pose_nees`` (against the ground truth), ``gated``,
    ``landmarks_available``, ``time_s`` (in the episode), ``log_time_s`` (in the log).

    ## Starting State
    Every robot's ground-truth pose at the episode's start plus a draw from ``N(0, diag(initial_position_std_m^2,
    ..., initial_heading_std_rad^2))``, uncorrelated.

    ## Episode End
    All agents are truncated after ``max_cycles`` steps; never terminated.

    ## Arguments
    ``parallel_env(render_mode=None, **config)`` with any key of ``default_config()``; an unknown key raises
    ``ValueError`` naming it.

    ## Version History
    * v0: initial version.
    """
