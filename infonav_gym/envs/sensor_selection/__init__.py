"""``infonav/SensorSelection-v0``: which image to acquire each step (``scenario.py``; sensors: ``acquisition.py``)."""

from infonav_gym.envs.sensor_selection.acquisition import IDLE_ACTION, MAX_IMAGE_ENTROPY, SENSORS
from infonav_gym.envs.sensor_selection.scenario import SensorSelection, SensorSelectionEnv, SensorSelectionVectorEnv

__all__ = [
    "IDLE_ACTION",
    "MAX_IMAGE_ENTROPY",
    "SENSORS",
    "SensorSelection",
    "SensorSelectionEnv",
    "SensorSelectionVectorEnv",
]
