"""``cooperative_localization_v0``: a team localizes through relative-pose observations (``scenario.py``)."""

from infonav_gym.envs.cooperative_localization.scenario import (
    CooperativeLocalization,
    CooperativeLocalizationEnv,
    CooperativeLocalizationVectorEnv,
)
from infonav_gym.envs.cooperative_localization.team_localization import start_episode

__all__ = ["CooperativeLocalization", "CooperativeLocalizationEnv", "CooperativeLocalizationVectorEnv", "start_episode"]
