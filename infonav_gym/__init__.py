"""infonav-gym: Gymnasium / PettingZoo environments for information-driven navigation.

Importing the package registers its environments with Gymnasium.
"""

import gymnasium as gym

__version__ = "0.1.0"

ENVIRONMENTS = {
    "infonav/LandmarkSelection-v0": "infonav_gym.envs.landmark_selection:LandmarkSelectionEnv",
    "infonav/ActiveLocalization-v0": "infonav_gym.envs.active_localization:ActiveLocalizationEnv",
    "infonav/SensorSelection-v0": "infonav_gym.envs.sensor_selection:SensorSelectionEnv",
    "infonav/RangeRegistration-v0": "infonav_gym.envs.range_registration:RangeRegistrationEnv",
}


def register_envs() -> None:
    """Register every infonav environment with Gymnasium; calling it again does nothing."""
    for env_id, entry_point in ENVIRONMENTS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry_point)


register_envs()
