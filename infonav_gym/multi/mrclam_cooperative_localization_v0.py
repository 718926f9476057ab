"""``mrclam_cooperative_localization_v0``: PettingZoo entry points ``parallel_env``, ``raw_env`` (AEC), ``env``."""

from __future__ import annotations

from infonav_gym.envs.mrclam_cooperative_localization import MRCLAMCooperativeLocalizationEnv
from infonav_gym.envs.parallel_view import pettingzoo_entry_points

__all__ = ["env", "parallel_env", "raw_env"]

parallel_env, raw_env, env = pettingzoo_entry_points(MRCLAMCooperativeLocalizationEnv)
