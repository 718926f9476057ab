"""One replay of an MRCLAM dataset: the suite's MRCLAM envs played over the whole log under a policy (the envs'
filter, no second one), summarized per robot against the ground truth.

A robot's replay is one episode of ``infonav/MRCLAMLocalization-v0`` over its longest stretch of measurement times
with ground truth; the cooperative replay one episode of ``mrclam_cooperative_localization_v0`` over the longest
stretch of steps with every robot's ground truth. ``all`` is the envs' ``fuse_every_reading``; the other policies
are the suite's agents choosing one reading a step.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from infonav_gym import make_env
from infonav_gym.datasets.mrclam_logs import robot_logs
from infonav_gym.datasets.timeline import Timeline, dead_reckoning
from infonav_gym.envs.mrclam_cooperative_localization.windows import team_windows
from infonav_gym.experiments.episodes import episode_infos, make_agent, make_team_agents, parallel_episode_infos
from infonav_gym.experiments.replay.metrics import fraction_inside_95, pose_rmse

SINGLE_ID, TEAM_ID = "infonav/MRCLAMLocalization-v0", "mrclam_cooperative_localization_v0"
POLICIES = ("all", "greedy", "nearest", "random")  # all: every reading; the others pick one a step
TICK_S = 0.02  # [s] the envs' odometry tick
NEES_PLOT_STEP_S = 1.0  # [s] spacing of the NEES-over-time samples an all-landmark replay keeps
SUMMARY_KEYS = (
    "position_rmse_m",
    "heading_rmse_rad",
    "mean_nees",
    "nees_fraction_inside_95",
    "dead_reckoning_position_rmse_m",
    "dead_reckoning_heading_rmse_rad",
    "updates_used",
    "updates_gated",
    "mean_entropy_nats",
)


@dataclass(frozen=True)
class ReplayConfig:
    """A replay's policy, noise and outage: ``noise`` ``"picked"`` (the raw logs, the dataset README's stds),
    ``"shipped"`` (the logs corrected by the calibration fitted on Dataset 6) or a calibration JSON's path (the envs'
    ``log_correction``; the filter takes the calibration's noise too, ``calibrated_noise``); the outage robot (a
    subject number) has no landmarks in ``[outage_start_s, outage_end_s)`` of the log (cooperative replays only)."""

    policy: str = "all"
    noise: str = "shipped"
    cooperative: bool = False
    time_step_s: float = 0.5  # [s] a cooperative replay's step
    outage_robot: int | None = None
    outage_start_s: float = 0.0
    outage_end_s: float = math.inf
    seed: int = 0
    start_s: float = 0.0  # [s] replay the log from here ...
    duration_s: float | None = None  # [s] ... to here (None: its end)

    def __post_init__(self):
        if self.policy not in POLICIES:
            raise ValueError(f"unknown policy {self.policy!r}: expected one of {', '.join(POLICIES)}")
        if not self.outage_end_s > self.outage_start_s:
            raise ValueError(f"outage must end after it starts, got {self.outage_start_s}..{self.outage_end_s} s")
        if self.outage_robot is not None and not self.cooperative:
            raise ValueError("an outage needs the cooperative replay: only teammates carry a robot through it")

    @property
    def log_correction(self) -> str:
        return "" if self.noise == "picked" else self.noise

    def as_dict(self) -> dict:
        """The settings as JSON-ready values (an open-ended outage ends at None, not infinity)."""
        settings = dataclasses.asdict(self)
        settings["outage_end_s"] = None if math.isinf(self.outage_end_s) else self.outage_end_s
        return settings


def longest_run(usable: np.ndarray) -> tuple[int, int]:
    """The first index and the length of the longest run of True in ``usable`` (the first of equal ones)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], usable.astype(int), [0]])))
    starts, ends = edges[::2], edges[1::2]
    if not len(starts):
        return 0, 0
    best = int(np.argmax(ends - starts))
    return int(starts[best]), int(ends[best] - starts[best])


def replay(dataset_dir, config: ReplayConfig | None = None) -> dict:
    """Replay the MRCLAM directory ``dataset_dir`` under ``config``: per robot (subject) its metrics, their means
    over the robots and, with an outage, the outage robot's RMSE over it against dead reckoning."""
    config = config or ReplayConfig()
    directory = Path(dataset_dir)
    robots, outage = (
        _team_replay(directory, config) if config.cooperative else (_robot_replays(directory, config), None)
    )
    result = {"dataset": str(directory), "config": config.as_dict(), "robots": robots, "mean": {}}
    for key in SUMMARY_KEYS:
        values = [metrics[key] for metrics in robots.values() if metrics.get(key) is not None]
        result["mean"][key] = float(np.mean(values)) if values else None
    if outage is not None:
        result["outage"] = outage
    return result


def _env_config(directory: Path, config: ReplayConfig) -> dict:
    span = {"time_from_s": float(config.start_s)} | (
        {} if config.duration_s is None else {"time_to_s": config.duration_s}
    )
    noise = {"log_correction": config.log_correction, "calibrated_noise": bool(config.log_correction)}
    return {"dataset_dir": str(directory), "fuse_every_reading": config.policy == "all", **noise, **span}


def _inside(times: np.ndarray, config: ReplayConfig) -> np.ndarray:
    """Which of the log's ``times`` [s] the replay's span holds."""
    return (times >= config.start_s) & (times <= (math.inf if config.duration_s is None else config.duration_s))


def _robot_replays(directory: Path, config: ReplayConfig) -> dict:
    """Each robot's episode of the single-robot env over its longest stretch with ground truth."""
    logs = robot_logs(directory.resolve(), TICK_S, config.log_correction)
    robots = {}
    for log in logs.robots:
        first, length = longest_run(np.isfinite(log.truth).all(axis=1) & _inside(logs.times_s(log), config))
        if length < 2:
            robots[str(log.subject)] = dict.fromkeys(SUMMARY_KEYS) | {"steps": 0}
            continue
        env = make_env(SINGLE_ID, **_env_config(directory, config), robots=str(log.subject), horizon=length - 1)
        agent = make_agent("greedy" if config.policy == "all" else config.policy, env.action_space.n, 0, env)
        steps = list(episode_infos(env, agent, config.seed))[1:]
        ticks = log.ticks[first : first + length]
        reckoned = _dead_reckoned(log.truth[first], log.controls, ticks, logs.tick_s)
        robots[str(log.subject)] = _metrics(steps, log.truth[first + 1 : first + length], reckoned, config)
    return robots


def _team_replay(directory: Path, config: ReplayConfig) -> tuple[dict, dict | None]:
    """The team's episode of the cooperative env over its longest stretch with every robot's ground truth."""
    windows = team_windows(directory.resolve(), TICK_S, config.time_step_s, config.log_correction)
    times = windows.window_s * np.arange(len(windows.truth))
    first, length = longest_run(np.isfinite(windows.truth).all(axis=(1, 2)) & _inside(times, config))
    if length < 2:
        raise ValueError(f"{directory}: no two steps of {windows.window_s} s with every robot's ground truth")
    outage, start_s = {}, times[first]
    if config.outage_robot is not None:
        if config.outage_robot not in windows.subjects:
            raise ValueError(f"outage robot {config.outage_robot} is not one of the robots {list(windows.subjects)}")
        span = [max(0.0, config.outage_start_s - start_s), max(0.0, min(config.outage_end_s, 1e6) - start_s)]
        outage = {"outage_robot": windows.subjects.index(config.outage_robot), "outage_from_s": span[0]}
        outage["outage_to_s"] = max(span)
    else:
        outage = {"outage_from_s": 0.0, "outage_to_s": 0.0}
    env = make_env(
        TEAM_ID, **_env_config(directory, config), max_cycles=length - 1, time_step_s=config.time_step_s, **outage
    )
    agents = make_team_agents("greedy" if config.policy == "all" else config.policy, env)
    steps = list(parallel_episode_infos(env, agents, config.seed))[1:]
    ticks = (first + np.arange(length)) * windows.window_ticks
    robots = {}
    for k, (agent, subject) in enumerate(zip(env.possible_agents, windows.subjects)):
        truth = windows.truth[first : first + length, k]
        reckoned = _dead_reckoned(truth[0], windows.controls[:, k], ticks, windows.tick_s)
        robots[str(subject)] = _metrics([step[agent] for step in steps], truth[1:], reckoned, config)
    if config.outage_robot is None:
        return robots, None
    return robots, _outage(robots, steps, windows, first, length, config)


def _outage(robots, steps, windows, first, length, config) -> dict:
    """The outage robot's position RMSE over its outage in the cooperative replay, against dead reckoning from its
    true pose at the outage's start."""
    k = windows.subjects.index(config.outage_robot)
    agent = f"robot_{k}"
    log_times = np.array([step[agent]["log_time_s"] for step in steps])
    inside = (log_times >= config.outage_start_s) & (log_times < config.outage_end_s)
    outage = {"robot": config.outage_robot, "start_s": config.outage_start_s}
    if not inside.any():
        return outage | {"end_s": None, "position_rmse_m": None, "dead_reckoning_from_start_position_rmse_m": None}
    outage["end_s"] = float(log_times[inside][-1])
    errors = np.array([step[agent]["position_error_m"] for step in steps])[inside]
    spanned = first + 1 + np.flatnonzero(inside)  # the windows of the steps inside, after the one before them
    ticks = np.concatenate([[spanned[0] - 1], spanned]) * windows.window_ticks
    reckoned = _dead_reckoned(windows.truth[spanned[0] - 1, k], windows.controls[:, k], ticks, windows.tick_s)
    position = float(np.sqrt(np.mean(errors**2)))
    dead = pose_rmse(windows.truth[spanned, k], reckoned)[0]
    return outage | {
        "position_rmse_m": position,
        "dead_reckoning_from_start_position_rmse_m": dead,
        "ratio": position / dead if dead > 0 else None,
    }


def _dead_reckoned(start_pose, controls, ticks, tick_s) -> np.ndarray:
    """Odometry-only poses at ``ticks[1:]`` from ``start_pose`` at ``ticks[0]`` (the filters' Euler steps)."""
    window = Timeline(0.0, tick_s, controls[ticks[0] : ticks[-1], None, :], [])
    return dead_reckoning(np.asarray(start_pose)[None], window)[ticks[1:] - ticks[0], 0]


def _metrics(steps: list[dict], truth: np.ndarray, reckoned: np.ndarray, config: ReplayConfig) -> dict:
    """One robot's replay metrics from its infos after each step, its ground truth and dead reckoning then."""
    nees = np.array([step["pose_nees"] for step in steps])
    errors = np.array([[step["position_error_m"], step["heading_error_rad"]] for step in steps])
    dead_position, dead_heading = pose_rmse(truth, reckoned)
    times = np.array([step.get("log_time_s", step["time_s"]) for step in steps])
    metrics = {
        "steps": len(steps),
        "position_rmse_m": float(np.sqrt(np.mean(errors[:, 0] ** 2))),
        "heading_rmse_rad": float(np.sqrt(np.mean(errors[:, 1] ** 2))),
        "mean_nees": float(nees.mean()),
        "nees_fraction_inside_95": fraction_inside_95(nees, 3),
        "dead_reckoning_position_rmse_m": dead_position,
        "dead_reckoning_heading_rmse_rad": dead_heading,
        "updates_used": int(sum(step["fused_readings"] for step in steps)),
        "updates_gated": int(sum(step["gated"] for step in steps)),
        "mean_entropy_nats": float(np.mean([step["pose_entropy"] for step in steps])),
        "evaluated_s": float(times[-1] - times[0]),
    }
    if config.policy == "all":
        kept = np.flatnonzero(np.diff(np.floor(times / NEES_PLOT_STEP_S), prepend=-1) > 0)
        metrics["nees_over_time"] = {"time_s": times[kept].tolist(), "nees": nees[kept].tolist()}
    return metrics
