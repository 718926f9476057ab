"""infonav-gym: Gymnasium / PettingZoo environments for information-driven navigation.

Importing the package registers its environments (``register_envs``) in ``infonav_gym.registry``,
the Gymnasium ones with Gymnasium as well. ``make_env(env_id, **config)`` makes either kind.
"""

from infonav_gym.registry import GYMNASIUM, PARALLEL, make_env, make_vector_env, register, registered_envs, unregister

__version__ = "0.1.0"
__all__ = ["make_env", "make_vector_env", "register", "register_envs", "registered_envs", "unregister"]

BUILTIN_ENVS = (
    (
        "infonav/LandmarkSelection-v0",
        "infonav_gym.envs.landmark_selection:LandmarkSelectionEnv",
        GYMNASIUM,
        "infonav_gym.envs.landmark_selection:LandmarkSelectionVectorEnv",
    ),
    (
        "infonav/ActiveLocalization-v0",
        "infonav_gym.envs.active_localization:ActiveLocalizationEnv",
        GYMNASIUM,
        "infonav_gym.envs.active_localization:ActiveLocalizationVectorEnv",
    ),
    (
        "infonav/SensorSelection-v0",
        "infonav_gym.envs.sensor_selection:SensorSelectionEnv",
        GYMNASIUM,
        "infonav_gym.envs.sensor_selection:SensorSelectionVectorEnv",
    ),
    (
        "infonav/RangeRegistration-v0",
        "infonav_gym.envs.range_registration:RangeRegistrationEnv",
        GYMNASIUM,
        "infonav_gym.envs.range_registration:RangeRegistrationVectorEnv",
    ),
    (
        "cooperative_localization_v0",
        "infonav_gym.envs.cooperative_localization:CooperativeLocalizationEnv",
        PARALLEL,
        "infonav_gym.envs.cooperative_localization:CooperativeLocalizationVectorEnv",
    ),
    (
        "cooperative_exploration_v0",
        "infonav_gym.envs.cooperative_exploration:CooperativeExplorationEnv",
        PARALLEL,
        "infonav_gym.envs.cooperative_exploration:CooperativeExplorationVectorEnv",
    ),
)


def register_envs() -> None:
    """Register every infonav environment (``BUILTIN_ENVS``, with a native vector env where one follows the API)."""
    for env_id, entry_point, api, *vector_entry_point in BUILTIN_ENVS:
        register(env_id, entry_point, api, *vector_entry_point)


register_envs()
