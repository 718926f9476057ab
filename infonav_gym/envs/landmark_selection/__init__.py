"""``infonav/LandmarkSelection-v0``: which landmark to observe each step (``scenario.py``)."""

from infonav_gym.envs.landmark_selection.scenario import (
    LandmarkSelection,
    LandmarkSelectionEnv,
    LandmarkSelectionVectorEnv,
    start_episode,
)

__all__ = ["LandmarkSelection", "LandmarkSelectionEnv", "LandmarkSelectionVectorEnv", "start_episode"]
