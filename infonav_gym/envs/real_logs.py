"""What the envs on real MRCLAM logs share: their config keys about the logs and the filter, the keys' bounds, the
logs loaded with one-line errors (``load_logs``) and the ranges of the readings an action fuses (``reading_ranges``)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from infonav_gym.config import Interval
from infonav_gym.datasets.mrclam_logs import env_dataset_directory
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
