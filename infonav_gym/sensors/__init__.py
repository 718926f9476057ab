"""Sensor models: each draws its noise from the ``np_random`` it is handed."""

from infonav_gym.sensors.odometry import OdometrySensor
from infonav_gym.sensors.range_bearing import RangeBearingSensor

__all__ = ["OdometrySensor", "RangeBearingSensor"]
