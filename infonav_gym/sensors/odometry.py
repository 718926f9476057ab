"""Wheel odometry: the executed speed and turn rate with additive Gaussian noise."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class OdometrySensor:
    """Measures ``[speed, turn_rate]`` with independent Gaussian noise.

    Attributes:
        speed_std_mps: standard deviation of the speed reading [m/s].
        turn_rate_std_rps: standard deviation of the turn-rate reading [rad/s].
    """

    speed_std_mps: float = 0.05
    turn_rate_std_rps: float = 0.02

    def __post_init__(self):
        if not (self.speed_std_mps > 0 and self.turn_rate_std_rps > 0):
            raise ValueError(f"odometry noise standard deviations must be positive, got {self}")

    def noise_covariance(self) -> np.ndarray:
        """Covariance of the reading's noise (2, 2)."""
        return np.diag([self.speed_std_mps**2, self.turn_rate_std_rps**2])

    def measure(self, control, np_random: np.random.Generator) -> np.ndarray:
        """A noisy reading of the executed ``control``: (2,) -> (2,), or one per robot (N, 2) -> (N, 2)."""
        control = np.asarray(control, dtype=float)
        return control + np_random.standard_normal(control.shape) * (self.speed_std_mps, self.turn_rate_std_rps)
