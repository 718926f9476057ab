"""A real MRCLAM dataset as a team's steps: fixed windows of the shared odometry clock, in each what every robot
measured (landmarks and teammates), the first reading of each and its tick, and the ground truth at the windows'
starts (``team_windows``, prepared once per dataset, tick, window and correction)."""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from infonav_gym.datasets import mrclam
from infonav_gym.datasets.mrclam_logs import corrected_dataset, truth_at
from infonav_gym.datasets.timeline import LANDMARK, make_timeline


@dataclass(frozen=True)
class TeamWindows:
    """A dataset's S windows of ``window_ticks`` ticks for its R robots and T = L + R targets (L landmarks, then the
    robots).

    Attributes:
        path: where the dataset was read from.
        subjects: the robots' subject numbers (R,).
        landmarks: the landmark map (L, 2) [m].
        tick_s: the odometry tick [s].
        window_ticks: the ticks of a window.
        measured: which targets each robot measured in each window (S, R, T) bool (never itself).
        readings: the first such reading ``[range [m], bearing [rad]]`` (S, R, T, 2), 0 where none.
        offsets: its tick within the window (S, R, T) int.
        truth: every robot's ground-truth pose at each window's start and at the last one's end (S + 1, R, 3) (NaN
            outside the ground truth's span).
        controls: every robot's mean odometry ``[speed, turn_rate]`` on each tick (S * window_ticks, R, 2).
    """

    path: Path
    subjects: tuple[int, ...]
    landmarks: np.ndarray
    tick_s: float
    window_ticks: int
    measured: np.ndarray
    readings: np.ndarray
    offsets: np.ndarray
    truth: np.ndarray
    controls: np.ndarray

    @property
    def window_s(self) -> float:
        return self.window_ticks * self.tick_s


@functools.cache
def team_windows(path: Path, tick_s: float, window_s: float, correction: str = "") -> TeamWindows:
    """The ``TeamWindows`` of the MRCLAM directory ``path`` (``mrclam.load``'s errors) on ticks of ``tick_s`` and
    windows of ``window_s`` (rounded to whole ticks, at least one), its logs corrected as ``robot_logs`` does."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unknown barcodes and missing files: the loader's notes, not the env's
        dataset = corrected_dataset(mrclam.load(path), correction)
    timeline = make_timeline(dataset, dt=tick_s)
    width = max(1, round(window_s / tick_s))
    n_windows, n_robots, n_landmarks = timeline.n_ticks // width, len(dataset.robots), len(dataset.landmarks)
    n_targets = n_landmarks + n_robots
    measured = np.zeros((n_windows, n_robots, n_targets), dtype=bool)
    readings = np.zeros((n_windows, n_robots, n_targets, 2))
    offsets = np.zeros((n_windows, n_robots, n_targets), dtype=int)
    for robot, events in enumerate(timeline.events):
        ticks = events[:, 0].astype(int)
        targets = events[:, 2].astype(int) + np.where(events[:, 1] == LANDMARK, 0, n_landmarks)
        keep = (ticks < n_windows * width) & (targets != n_landmarks + robot)
        windows = ticks // width
        _, first = np.unique(windows[keep] * n_targets + targets[keep], return_index=True)  # events are time-sorted
        rows = np.flatnonzero(keep)[first]
        where = windows[rows], robot, targets[rows]
        measured[where], readings[where], offsets[where] = True, events[rows, 3:5], ticks[rows] % width
    times = timeline.start_time + tick_s * width * np.arange(n_windows + 1)
    truth = np.stack([truth_at(dataset.groundtruth.get(subject), times) for subject in dataset.robots], axis=1)
    controls = np.ascontiguousarray(timeline.controls[: n_windows * width])
    return TeamWindows(
        Path(path),
        tuple(dataset.robots),
        dataset.landmarks.copy(),
        float(tick_s),
        width,
        measured,
        readings,
        offsets,
        truth,
        controls,
    )
