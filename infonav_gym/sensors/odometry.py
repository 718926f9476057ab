"""Wheel odometry: the executed speed and turn rate with additive Gaussian noise."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from infonav_gym.config import check_number, from_config

MAX_ODOMETRY_STD = 10.0  # largest speed [m/s] and turn-rate [rad/s] noise standard deviation


@dataclass(frozen=True)
class OdometrySensor:
    """Measures ``[speed, turn_rate]`` with independent Gaussian noise of these standard deviations (in (0, 10])."""

    speed_std_mps: float = 0.05
    turn_rate_std_rps: float = 0.02

    def __post_init__(self):
        owner = type(self).__name__
        check_number(owner, "speed_std_mps", self.speed_std_mps, 0.0, MAX_ODOMETRY_STD, open_low=True, unit="m/s")
        check_number(
            owner, "turn_rate_std_rps", self.turn_rate_std_rps, 0.0, MAX_ODOMETRY_STD, open_low=True, unit="rad/s"
        )

    def noise_covariance(self) -> np.ndarray:
        """Covariance of the reading's noise (2, 2)."""
        return np.diag([self.speed_std_mps**2, self.turn_rate_std_rps**2])

    def measure(self, control, np_random: np.random.Generator) -> np.ndarray:
        """A noisy reading of the executed ``control``: (2,) -> (2,), or one per robot (N, 2) -> (N, 2)."""
        control = np.asarray(control, dtype=float)
        return self.measure_with_noise(control, np_random.standard_normal(control.shape))

    def measure_with_noise(self, controls, noise) -> np.ndarray:
        """``measure`` given its standard normals ``noise`` (the shape of ``controls``, (..., 2))."""
        return controls + noise * (self.speed_std_mps, self.turn_rate_std_rps)


CONFIG_KEYS = {"speed_std_mps": "odometry_speed_std_mps", "turn_rate_std_rps": "odometry_turn_rate_std_rps"}


def odometry_sensor_from_config(config: dict, owner: str) -> OdometrySensor:
    """The odometry described by an env config's ``CONFIG_KEYS``; a bad value's ``ValueError`` names its key."""
    return from_config(OdometrySensor, config, CONFIG_KEYS, owner)
