"""Learning curves of training runs: ``curve.csv`` appended to as training goes, ``curve.png`` drawn from it.

A row per window with ended episodes: env steps, mean return, mean main metric (put into an episode's last info
as ``METRIC_KEY`` by the wrappers here or a team's ``RobotSlots``) and count; rows are flushed, so Ctrl-C keeps them.
"""

from __future__ import annotations

import csv
import json
import math
import textwrap
from collections.abc import Mapping
from pathlib import Path

import gymnasium as gym
import numpy as np
from gymnasium.vector import VectorWrapper
from stable_baselines3.common.callbacks import BaseCallback

from infonav_gym.envs.traits import main_metric_of, traits_of
from infonav_gym.registry import make_env
from infonav_gym.rendering import matplotlib_figure, save_figure

CURVE_CSV, CURVE_PNG = "curve.csv", "curve.png"
CURVE_LABELS = "curve_labels.json"  # the axis titles of curve.png with their units: {"return": ..., "metric": ...}
VALIDATION_CSV = "validation.csv"  # steps, mean main metric, episodes, kept (0/1): ``agents.validation``'s rows
METRIC_KEY = "curve_main_metric"  # the main metric of the episode ending in this step, in its last info
VECTOR_ONLY_KEYS = ("final_obs", "final_info")  # a vector env's info keys that are not one sub-env's info


class SubEnvInfo(Mapping):
    """Sub-env ``index``'s info read on demand from a vector env's batched ``info`` (by its ``_key`` masks); in a team
    vector env ``robot`` picks its column (but not of ``team_keys``)."""

    def __init__(self, info: dict, index: int, robot: int | None = None, team_keys=frozenset()):
        self.info, self.index, self.robot, self.team_keys = info, index, robot, team_keys

    def _has(self, key: str) -> bool:
        present = self.info.get(f"_{key}")
        return not key.startswith("_") and key not in VECTOR_ONLY_KEYS and (present is None or present[self.index])

    def __getitem__(self, key: str):
        if key not in self.info or not self._has(key):
            raise KeyError(key)
        value = self.info[key]
        if isinstance(value, dict):
            return SubEnvInfo(value, self.index, self.robot)  # nested keys are per robot
        value = value[self.index]
        return value if self.robot is None or key in self.team_keys else value[self.robot]

    def __iter__(self):
        return (key for key in self.info if self._has(key))

    def __len__(self) -> int:
        return sum(1 for _ in self)


def team_view(agents, team_keys):
    """How a team vector env's batched info is one copy's ``{agent: info}``, as a PettingZoo env's metrics read it."""
    return lambda info, index: {agent: SubEnvInfo(info, index, k, team_keys) for k, agent in enumerate(agents)}


class EndedEpisodeMetrics:
    """The main metric of each episode of a vector env of ``num_envs`` copies, as it ends.

    Keeps the batched infos since the oldest running episode began and reads an ended copy's rows through
    ``view(info, index)``. ``same_step``: SAME_STEP autoreset (last info in ``final_info``), else NEXT_STEP.
    """

    def __init__(self, metric, num_envs: int, view=SubEnvInfo, same_step: bool = True):
        self.metric, self.num_envs, self.view, self.same_step = metric, num_envs, view, same_step
        self.reset()

    def reset(self) -> None:
        """Forget the steps kept (every episode starts again)."""
        self.infos, self.first, self.dropped = [], np.zeros(self.num_envs, dtype=int), 0

    def step(self, info: dict, ended: np.ndarray) -> np.ndarray | None:
        """Keep this step's ``info``; each copy's metric (NaN where its episode goes on) when ``ended`` has one."""
        self.infos.append(info)
        if not ended.any():
            return None
        metrics, last = np.full(self.num_envs, np.nan), info["final_info"] if self.same_step else info
        for index in np.flatnonzero(ended).tolist():
            before_last = self.infos[self.first[index] - self.dropped : -1]
            steps = [self.view(step, index) for step in before_last] + [self.view(last, index)]
            metrics[index] = self.metric.compute(steps)
        self.first[ended] = self.dropped + len(self.infos) + (0 if self.same_step else 1)
        unread = min(int(self.first.min()) - self.dropped, len(self.infos))  # NEXT_STEP: the reset steps come later
        del self.infos[:unread]
        self.dropped += unread
        return metrics


class MetricVectorWrapper(VectorWrapper):
    """A ``SAME_STEP`` vector env whose ``info["final_info"]`` holds ended episodes' main metric (``METRIC_KEY``)."""

    def __init__(self, env):
        super().__init__(env)
        self.metrics = EndedEpisodeMetrics(main_metric_of(env), self.num_envs)

    def reset(self, **kwargs):
        self.metrics.reset()
        return self.env.reset(**kwargs)

    def step(self, actions):
        observations, rewards, terminated, truncated, info = self.env.step(actions)
        ended = np.logical_or(terminated, truncated)
        metrics = self.metrics.step(info, ended)
        if metrics is not None:
            info["final_info"] = {**info["final_info"], METRIC_KEY: metrics, f"_{METRIC_KEY}": ended}
        return observations, rewards, terminated, truncated, info


class MetricWrapper(gym.Wrapper):
    """A single env whose last info of an episode holds the episode's main metric (``METRIC_KEY``)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self.metric, self.infos = main_metric_of(env), []

    def reset(self, **kwargs):
        self.infos = []
        return self.env.reset(**kwargs)

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        self.infos.append(info)
        if terminated or truncated:
            info = {**info, METRIC_KEY: float(self.metric.compute(self.infos))}
            self.infos = []
        return observation, reward, terminated, truncated, info


def start_curve(directory: Path, env_id: str, env_kwargs: dict | None) -> Path:
    """A fresh ``directory/curve.csv`` (its header names the env's main metric) and ``CURVE_LABELS``; the CSV's path."""
    env = make_env(env_id, **(env_kwargs or {}))
    try:
        metric, reward_unit = main_metric_of(env), traits_of(env).reward_unit
    finally:
        env.close()
    metric_name, path = metric.name, Path(directory) / CURVE_CSV
    path.parent.mkdir(parents=True, exist_ok=True)
    labels = {"return": f"mean episode return [{reward_unit}]", "metric": metric.title}
    (path.parent / CURVE_LABELS).write_text(json.dumps(labels, indent=2) + "\n")
    with path.open("w", newline="") as file:
        csv.writer(file).writerow(["steps", "mean_return", metric_name, "episodes"])
    return path


def append_row(path: Path, steps: int, mean_return: float, mean_metric: float, episodes: int) -> None:
    """A row of ``path`` for the episodes that ended in one window, written at once."""
    with path.open("a", newline="") as file:
        csv.writer(file).writerow([int(steps), repr(float(mean_return)), repr(float(mean_metric)), int(episodes)])


class CurveCallback(BaseCallback):
    """Appends a row of ``curve.csv`` after every rollout in which episodes ended, from the infos SB3's monitor
    completes (``episode``, and ``METRIC_KEY`` where a wrapper computed it, else NaN)."""

    def __init__(self, path: Path):
        super().__init__()
        self.path, self.returns, self.metrics = path, [], []

    def _on_step(self) -> bool:
        for index in np.flatnonzero(self.locals["dones"]):
            info = self.locals["infos"][index]
            self.returns.append(info["episode"]["r"])
            self.metrics.append(info.get(METRIC_KEY, math.nan))
        return True

    def _on_rollout_end(self) -> None:
        if self.returns:
            append_row(self.path, self.num_timesteps, np.mean(self.returns), np.mean(self.metrics), len(self.returns))
        self.returns, self.metrics = [], []


def read_curve(path: Path) -> tuple[str, np.ndarray]:
    """The metric's name and the rows (steps, mean return, mean metric, episodes) of a ``curve.csv``."""
    with Path(path).open(newline="") as file:
        header, *rows = list(csv.reader(file))
    return header[2], np.array(rows, dtype=float).reshape(-1, 4)


def read_validations(path: Path) -> np.ndarray:
    """The rows (steps, mean metric, episodes, kept) of a ``validation.csv``; none when the run did not validate."""
    return read_curve(path)[1] if path.is_file() else np.empty((0, 4))


def draw_curve(directory: Path, title: str, references: dict | None) -> Path:
    """``directory/curve.png``; ``ImportError`` without matplotlib, ``ValueError`` with nothing to draw."""
    return save_figure(figure_curve(directory, title, references), Path(directory) / CURVE_PNG, dpi=100)


def figure_curve(directory: Path, title: str, references: dict | None):
    """The learning curve of ``directory``'s ``curve.csv``: return and main metric against env steps, ``references``
    (agent: metric) as lines, and the validations of ``validation.csv`` if any."""
    metric_name, rows = read_curve(Path(directory) / CURVE_CSV)
    labels_path = Path(directory) / CURVE_LABELS  # absent in runs older than it: the bare names
    labels = {"return": "mean episode return", "metric": metric_name}
    labels = json.loads(labels_path.read_text()) if labels_path.is_file() else labels
    validations = read_validations(Path(directory) / VALIDATION_CSV)
    if not rows.size and not validations.size:
        raise ValueError(f"no episode ended in training, so no {CURVE_PNG}: nothing to draw")
    has_metric = (rows.size > 0 and not np.isnan(rows[:, 2]).all()) or validations.size > 0
    figure = matplotlib_figure("curve.png", figsize=(7, 6 if has_metric else 3.5), layout="constrained")
    axes = figure.subplots(2 if has_metric else 1, 1, sharex=True, squeeze=False)[:, 0]
    axes[0].plot(rows[:, 0], rows[:, 1], marker=".")
    axes[0].set_ylabel(labels["return"])
    if has_metric:
        axes[1].plot(rows[:, 0], rows[:, 2], marker=".", label="training episodes (sampled actions)")
        if validations.size:
            best = np.flatnonzero(validations[:, 3])[-1]  # the last policy kept as the best
            label = f"deterministic, {int(validations[0, 2])} validation seeds"
            axes[1].plot(validations[:, 0], validations[:, 1], marker="s", linestyle="-", label=label)
            axes[1].plot(*validations[best, :2], marker="*", markersize=14, linestyle="", label="best: kept")
        known = references or {}
        for style, (agent, value) in zip(("--", ":"), known.items(), strict=False):
            axes[1].axhline(value, linestyle=style, color="grey", label=agent)
        if not known:
            axes[1].plot([], [], " ", label="greedy / planner: unknown (not in the leaderboard)")
        axes[1].set_ylabel(labels["metric"])
        axes[1].legend(fontsize="small")
    else:
        title += f"\n({labels['metric']} not recorded in training: return only)"
    axes[-1].set_xlabel("environment steps [steps]")
    lines = [line for part in title.split("\n") for line in textwrap.wrap(part, 70)]  # long titles: several lines
    figure.suptitle("\n".join(lines), fontsize="medium")
    return figure


def drawn_curve(directory: Path, title: str, references: dict | None) -> str:
    """``draw_curve``'s path, or one line saying why there is no PNG (nothing to draw, or no matplotlib)."""
    try:
        return str(draw_curve(directory, title, references))
    except (ImportError, ValueError) as error:
        return f"{CURVE_CSV} written; {error}"
