"""``mrclam_cooperative_localization_v0``: a real team's landmark and teammate readings to fuse (``scenario.py``)."""

from infonav_gym.envs.mrclam_cooperative_localization.scenario import (
    MRCLAMCooperativeLocalization,
    MRCLAMCooperativeLocalizationEnv,
    MRCLAMCooperativeLocalizationVectorEnv,
)

__all__ = [
    "MRCLAMCooperativeLocalization",
    "MRCLAMCooperativeLocalizationEnv",
    "MRCLAMCooperativeLocalizationVectorEnv",
]
