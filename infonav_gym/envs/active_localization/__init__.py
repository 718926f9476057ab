"""``infonav/ActiveLocalization-v0``: drive to a goal, choosing how to move and what to observe (``scenario.py``;
its step in ``transition.py``, its planning model in ``planning.py``)."""

from infonav_gym.envs.active_localization.planning import ActivePlanningModel, Belief
from infonav_gym.envs.active_localization.scenario import (
    ActiveLocalization,
    ActiveLocalizationEnv,
    ActiveLocalizationVectorEnv,
)
from infonav_gym.envs.active_localization.transition import (
    N_PRIMITIVES,
    PRIMITIVE_NAMES,
    PRIMITIVE_OFFSETS_RAD,
    REWARD_TERMS,
    primitive_commands,
)

__all__ = [
    "N_PRIMITIVES",
    "PRIMITIVE_NAMES",
    "PRIMITIVE_OFFSETS_RAD",
    "REWARD_TERMS",
    "ActiveLocalization",
    "ActiveLocalizationEnv",
    "ActiveLocalizationVectorEnv",
    "ActivePlanningModel",
    "Belief",
    "primitive_commands",
]
