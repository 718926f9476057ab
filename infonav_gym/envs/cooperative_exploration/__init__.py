"""``cooperative_exploration_v0``: a team maps a field, choosing where to go and what to see (``scenario.py``)."""

from infonav_gym.envs.cooperative_exploration.exploration_planning import N_MOTIONS, NOOP_ACTION
from infonav_gym.envs.cooperative_exploration.scenario import (
    CooperativeExploration,
    CooperativeExplorationEnv,
    CooperativeExplorationVectorEnv,
)

__all__ = [
    "N_MOTIONS",
    "NOOP_ACTION",
    "CooperativeExploration",
    "CooperativeExplorationEnv",
    "CooperativeExplorationVectorEnv",
]
