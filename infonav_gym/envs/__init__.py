"""Single-agent environments."""

from infonav_gym.envs.base import InfoNavEnv
from infonav_gym.envs.landmark_selection import LandmarkSelectionEnv
from infonav_gym.envs.sensor_selection import SensorSelectionEnv

__all__ = ["InfoNavEnv", "LandmarkSelectionEnv", "SensorSelectionEnv"]
