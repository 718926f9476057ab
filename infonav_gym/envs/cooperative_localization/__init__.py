"""``cooperative_localization_v0``: a team localizes through relative-pose observations (``scenario.py``)."""

from infonav_gym.envs.cooperative_localization.scenario import (
    CooperativeLocalization,
    CooperativeLocalizationEnv,
    CooperativeLocalizationVectorEnv,
)

__all__ = ["CooperativeLocalization", "CooperativeLocalizationEnv", "CooperativeLocalizationVectorEnv"]
