"""A real MRCLAM dataset as episodes: each robot's landmark measurement times (the steps), what it measured then, its
odometry on a fixed tick between them and its ground truth, prepared once per dataset and tick (``robot_logs``)."""

from __future__ import annotations

import functools
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from infonav_gym.datasets import DatasetNotFound, mrclam
from infonav_gym.datasets.noise_model import NoiseModel, corrected_logs, load_noise_model, shipped_noise_model
from infonav_gym.datasets.timeline import LANDMARK, make_timeline
from infonav_gym.geometry import wrap_angle

DATASET_VARIABLE = "INFONAV_MRCLAM_DATASET"  # the environment variable naming the default dataset directory
DEFAULT_DATASET = Path("..") / "shared" / "datasets" / "MRCLAM_Dataset6"  # from the working directory
SHIPPED = "shipped"  # the config key ``log_correction``'s name of the shipped Dataset 6 calibration


def dataset_directory(configured: str) -> Path:
    """The dataset directory: ``configured``, else ``$INFONAV_MRCLAM_DATASET``, else ``DEFAULT_DATASET``."""
    return Path(configured or os.environ.get(DATASET_VARIABLE) or DEFAULT_DATASET).expanduser().resolve()


@dataclass(frozen=True)
class RobotLog:
    """One robot's log on the steps of its episodes (S landmark measurement times, L landmarks).

    Attributes:
        subject: the robot's subject number.
        ticks: each step's tick on the odometry clock (S,) int, ascending.
        measured: which landmarks it measured at each step (S, L) bool.
        readings: their ``[range [m], bearing [rad]]`` (S, L, 2), 0 where not measured (the first of a tick's).
        truth: the ground-truth pose at each step (S, 3) (NaN outside the ground truth's span).
        controls: the mean odometry ``[speed, turn_rate]`` of each tick (T, 2).
    """

    subject: int
    ticks: np.ndarray
    measured: np.ndarray
    readings: np.ndarray
    truth: np.ndarray
    controls: np.ndarray


@dataclass(frozen=True)
class DatasetLogs:
    """A dataset's landmark map (L, 2) [m], its ``RobotLog``s, the tick [s] and where it was read from."""

    path: Path
    landmarks: np.ndarray
    robots: tuple[RobotLog, ...]
    tick_s: float

    def times_s(self, log: RobotLog) -> np.ndarray:
        """Each step's time [s] from the dataset's first odometry reading."""
        return log.ticks * self.tick_s


@functools.cache
def robot_logs(path: Path, tick_s: float, correction: str = "") -> DatasetLogs:
    """The ``DatasetLogs`` of the MRCLAM directory ``path`` (``mrclam.load``'s errors) on ticks of ``tick_s``, its
    logs corrected by ``corrected_dataset(..., correction)`` (the sensors' clocks, the odometry's scales, the
    measurements' mean errors)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unknown barcodes and missing files: the loader's notes, not the env's
        dataset = corrected_dataset(mrclam.load(path), correction)
    timeline = make_timeline(dataset, dt=tick_s)
    times = timeline.boundary_times() + dataset.start_time
    logs = []
    for column, subject in enumerate(dataset.robots):
        events = timeline.events[column]
        events = events[events[:, 1] == LANDMARK]
        ticks, step_of_event = np.unique(events[:, 0].astype(int), return_inverse=True)
        measured = np.zeros((len(ticks), len(dataset.landmarks)), dtype=bool)
        readings = np.zeros((len(ticks), len(dataset.landmarks), 2))
        for event in range(len(events) - 1, -1, -1):  # backwards: the first reading of a tick is the one kept
            step, target = step_of_event[event], int(events[event, 2])
            measured[step, target], readings[step, target] = True, events[event, 3:5]
        truth = truth_at(dataset.groundtruth.get(subject), times[ticks])
        logs.append(RobotLog(subject, ticks, measured, readings, truth, timeline.controls[:, column].copy()))
    return DatasetLogs(Path(path), dataset.landmarks.copy(), tuple(logs), float(tick_s))


def corrected_dataset(dataset: mrclam.MRCLAMDataset, correction: str) -> mrclam.MRCLAMDataset:
    """``dataset`` with its logs corrected by a calibrated noise model (``noise_model.corrected_logs``): ``correction``
    ``""`` none, ``"shipped"`` the Dataset 6 calibration the package ships, else the path of a calibration JSON
    (``load_noise_model``'s errors)."""
    return corrected_logs(dataset, correction_model(correction)) if correction else dataset


def correction_model(correction: str) -> NoiseModel:
    """The calibrated noise model a ``log_correction`` names: ``"shipped"`` (Dataset 6's) or a calibration JSON."""
    return shipped_noise_model() if correction == SHIPPED else load_noise_model(Path(correction).expanduser())


def env_dataset_directory(configured: str, owner: str) -> Path:
    """The dataset directory of an env's config key ``dataset_dir`` (``dataset_directory``); ``DatasetNotFound``
    naming ``owner`` and where to set it if there is none."""
    directory = dataset_directory(configured)
    if not directory.is_dir():
        where = f"set config key 'dataset_dir' or ${DATASET_VARIABLE}"
        raise DatasetNotFound(f"{owner}: no MRCLAM dataset directory at {directory} ({where})")
    return directory


def truth_at(groundtruth: np.ndarray | None, times: np.ndarray) -> np.ndarray:
    """Ground-truth poses (n, 3) interpolated at ``times`` (heading unwrapped first); NaN outside its span."""
    if groundtruth is None or not len(groundtruth):
        return np.full((len(times), 3), np.nan)
    stamps = groundtruth[:, 0]
    columns = [groundtruth[:, 1], groundtruth[:, 2], np.unwrap(groundtruth[:, 3])]
    truth = np.column_stack([np.interp(times, stamps, column) for column in columns])
    truth[:, 2] = wrap_angle(truth[:, 2])
    truth[(times < stamps[0]) | (times > stamps[-1])] = np.nan
    return truth
