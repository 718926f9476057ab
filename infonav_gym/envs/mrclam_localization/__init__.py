"""``infonav/MRCLAMLocalization-v0``: which real measurement of the MRCLAM logs to fuse (``scenario.py``)."""

from infonav_gym.envs.mrclam_localization.scenario import (
    MRCLAMLocalization,
    MRCLAMLocalizationEnv,
    MRCLAMLocalizationVectorEnv,
)

__all__ = ["MRCLAMLocalization", "MRCLAMLocalizationEnv", "MRCLAMLocalizationVectorEnv"]
