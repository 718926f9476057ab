"""A dataset's asynchronous logs on one clock: fixed ticks, per-tick controls, measurement events."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from infonav_gym.datasets.mrclam import MRCLAMDataset
from infonav_gym.geometry import wrap_angle

LANDMARK, ROBOT = 0, 1  # event kinds
MAX_TICKS = 10**8  # a longer timeline is a stray timestamp, not a log (MRCLAM's: about 10^5 ticks of 0.02 s)


@dataclass
class Timeline:
    """Replay clock: boundaries ``b = 0..n_ticks`` at ``start_time + b * dt``.

    Attributes:
        start_time: absolute time of boundary 0 [s].
        dt: tick length [s].
        controls: mean ``[speed, turn_rate]`` of each robot over each tick (n_ticks, N, 2).
        events: per robot, measurement rows ``[boundary, kind, target, range, bearing, time_s]``
            sorted by boundary; ``kind`` is ``LANDMARK`` (target = row of ``dataset.landmarks``)
            or ``ROBOT`` (target = index into ``dataset.robots``); ``time_s`` counts from ``start_time``.
    """

    start_time: float
    dt: float
    controls: np.ndarray
    events: list[np.ndarray]

    @property
    def n_ticks(self) -> int:
        return len(self.controls)

    def boundary_times(self) -> np.ndarray:
        """Replay times of the boundaries [s] (n_ticks + 1,)."""
        return self.dt * np.arange(self.n_ticks + 1)


def running_sums(increments) -> np.ndarray:
    """Sums of ``increments`` (T, ...) along the first axis from zero: (T + 1, ...), the first row 0."""
    increments = np.asarray(increments)
    return np.concatenate([np.zeros((1, *increments.shape[1:])), np.cumsum(increments, axis=0)])


def held_integral(times: np.ndarray, values: np.ndarray, at) -> np.ndarray:
    """The integral of ``values`` (T,), each held from its time to the next (zero-order), at each of ``at`` (0 before
    the first of ``times``)."""
    return np.interp(at, times, running_sums(values[:-1] * np.diff(times)))


def _tick_means(odometry: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Mean of the held (zero-order) odometry readings over each interval between ``edges``; 0 before the first."""
    integrals = [held_integral(odometry[:, 0], odometry[:, column], edges) for column in (1, 2)]
    return np.column_stack([np.diff(integral) / np.diff(edges) for integral in integrals])


def make_timeline(dataset: MRCLAMDataset, dt: float = 0.02, duration_s: float | None = None) -> Timeline:
    """Resample the logs of ``dataset`` onto ticks of ``dt`` seconds from its first odometry time, for ``duration_s``
    seconds (None: to the last odometry time)."""
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt}")
    start = dataset.start_time
    span = dataset.end_time - start if duration_s is None else min(float(duration_s), dataset.end_time - start)
    if not span > 0:
        raise ValueError(f"nothing to replay: duration {span} s")
    n_ticks = int(np.ceil(span / dt))
    if n_ticks > MAX_TICKS:
        raise ValueError(
            f"the logs span {span:.6g} s, {n_ticks} ticks of {dt} s (at most {MAX_TICKS}): a stray timestamp?"
        )
    edges = start + dt * np.arange(n_ticks + 1)
    controls = np.stack([_tick_means(dataset.odometry[robot], edges) for robot in dataset.robots], axis=1)
    events = []
    for robot in dataset.robots:
        landmark_rows, robot_rows = dataset.landmark_measurements[robot], dataset.robot_measurements[robot]
        robot_targets = [dataset.robots.index(int(subject)) for subject in robot_rows[:, 1]]
        table = np.concatenate(
            [
                _events(landmark_rows, LANDMARK, dataset.landmark_index(landmark_rows[:, 1]), start, dt),
                _events(robot_rows, ROBOT, robot_targets, start, dt),
            ]
        )
        table = table[(table[:, 0] >= 0) & (table[:, 0] <= n_ticks)]
        events.append(table[np.argsort(table[:, 0], kind="stable")])
    return Timeline(start_time=start, dt=dt, controls=controls, events=events)


def _events(rows: np.ndarray, kind: int, targets: np.ndarray, start: float, dt: float) -> np.ndarray:
    time_s = rows[:, 0] - start
    boundaries = np.round(time_s / dt)
    return np.column_stack([boundaries, np.full(len(rows), kind), targets, rows[:, 2], wrap_angle(rows[:, 3]), time_s])


def dead_reckoning(initial_poses: np.ndarray, timeline: Timeline) -> np.ndarray:
    """Odometry-only poses at every boundary (n_ticks + 1, N, 3), the filters' Euler steps without updates."""
    speed, turn_rate = timeline.controls[..., 0], timeline.controls[..., 1]
    headings = initial_poses[:, 2] + running_sums(turn_rate * timeline.dt)
    steps = speed * timeline.dt
    x = initial_poses[:, 0] + running_sums(steps * np.cos(headings[:-1]))
    y = initial_poses[:, 1] + running_sums(steps * np.sin(headings[:-1]))
    return np.stack([x, y, wrap_angle(headings)], axis=-1)
