"""Single-agent environments."""

from infonav_gym.envs.base import InfoNavEnv
from infonav_gym.envs.landmark_selection import LandmarkSelectionEnv

__all__ = ["InfoNavEnv", "LandmarkSelectionEnv"]
