"""What the envs on real MRCLAM logs share: their config keys about the logs and the filter, the keys' bounds, the
logs loaded with one-line errors (``load_logs``) and the ranges of the readings an action fuses (``reading_ranges``)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from infonav_gym.compiled import stacked
from infonav_gym.config import Interval
from infonav_gym.datasets.mrclam_logs import correction_model, env_dataset_directory
from infonav_gym.estimation.state import INITIAL_POSE_STD

END_OF_LOG_S = 1e6  # [s] beyond any log: ``time_to_s``'s default, to the end
LOG_CONFIG_INTERVALS = {
    "odometry_tick_s": Interval(1e-3, 1.0, unit="s"),
    "range_std_m": Interval(1e-4, 10.0, unit="m"),
    "bearing_std_rad": Interval(1e-5, math.pi, unit="rad"),
    "odometry_speed_std_mps": Interval(1e-6, 10.0, unit="m/s"),
    "odometry_turn_rate_std_rps": Interval(1e-6, 10.0, unit="rad/s"),
    "gate_nis": Interval(0.0, 1e6, open_low=True),
    "time_from_s": Interval(0.0, END_OF_LOG_S, unit="s"),
    "time_to_s": Interval(0.0, END_OF_LOG_S, unit="s"),
    **INITIAL_POSE_STD,
}


def log_config() -> dict:
    """A fresh dict of the config keys about the logs and the filter, with their defaults."""
    return {
        "dataset_dir": "",  # "": $INFONAV_MRCLAM_DATASET, else ../shared/datasets/MRCLAM_Dataset6
        "time_from_s": 0.0,  # episodes lie in [time_from_s, time_to_s] of the log [s]: hold a time range out
        "time_to_s": END_OF_LOG_S,  # [s] (the default: to the end)
        "odometry_tick_s": 0.02,  # [s] the odometry's mean over each tick predicts the pose
        "range_std_m": 0.3,  # [m] (the dataset README's reference filter)
        "bearing_std_rad": math.radians(8.0),  # [rad]
        "odometry_speed_std_mps": 0.01,  # [m/s] of readings averaged over 1 s
        "odometry_turn_rate_std_rps": 0.02,  # [rad/s] of readings averaged over 1 s
        "gate_nis": 25.0,  # a measurement whose normalized innovation squared exceeds this is not fused
        "log_correction": "",  # "": the raw logs; "shipped" or a calibration JSON's path: logs corrected by it
        "calibrated_noise": False,  # True: the filter's noise is log_correction's calibration, not the stds above
        "initial_position_std_m": 0.05,  # [m] the prior around the ground truth at the episode's start
        "initial_heading_std_rad": 0.05,  # [rad]
    }


def load_logs(loader: Callable, config: dict, owner: str, *arguments):
    """``loader(directory, odometry_tick_s, *arguments, log_correction)`` of the config's dataset directory
    (``DatasetNotFound`` where there is none); its ``OSError`` or ``ValueError`` as a one-line ``ValueError`` naming
    ``owner`` and the config keys."""
    directory = env_dataset_directory(config["dataset_dir"], owner)
    try:
        return loader(directory, float(config["odometry_tick_s"]), *arguments, config["log_correction"])
    except (OSError, ValueError) as error:
        raise ValueError(f"{owner}: {error} (config keys 'dataset_dir' and 'log_correction')") from None


def reading_ranges(mask: np.ndarray, readings: np.ndarray) -> np.ndarray:
    """Each action's measured range [m] (..., 1 + T): 0 for fusing nothing and where nothing was measured, from the
    ``mask`` (..., 1 + T) and ``readings`` (..., T, 2)."""
    ranges = np.zeros(mask.shape)
    ranges[..., 1:] = np.where(mask[..., 1:] == 1, readings[..., 0], 0.0)
    return ranges


def filter_noise(config: dict, owner: str, measured, readings, n_robots: int, tick_s: float) -> tuple:
    """The noise covariance of each reading (..., T, 2, 2) of the logs' ``measured`` (..., T) targets and their
    ``readings`` (..., T, 2), or one for all (1, ..., T, 2, 2), and of each robot's odometry on a tick (robots, 2, 2):
    the config's stds, or with ``calibrated_noise`` the pooled model of its ``log_correction``'s calibration (every
    robot's errors together, which carries over to data it was not fitted on better than each robot's own): the whole
    range-bearing error at the reading's range, the odometry's white noise whose integral matches its fitted error
    over minutes (``NoiseModel``)."""
    if not config["calibrated_noise"]:
        reading = np.diag([config["range_std_m"] ** 2, config["bearing_std_rad"] ** 2])
        odometry = np.diag([config["odometry_speed_std_mps"] ** 2, config["odometry_turn_rate_std_rps"] ** 2])
        return stacked(reading, (1, *measured.shape[1:], 2, 2)), stacked(odometry / tick_s, (n_robots, 2, 2))
    if not config["log_correction"]:
        raise ValueError(f"config key 'calibrated_noise' of {owner} takes the noise of 'log_correction': set it too")
    model = correction_model(config["log_correction"]).pooled
    reading = model.total_noise(np.where(measured, readings[..., 0], 1.0))
    return reading, stacked(np.diag(model.odometry_density() ** 2) / tick_s, (n_robots, 2, 2))
