"""``infonav/MapRegistration-v0``: which returns of a LADAR scan to register to an a-priori map (``scenario.py``)."""

from infonav_gym.envs.map_registration.scenario import MapRegistration, MapRegistrationEnv, MapRegistrationVectorEnv

__all__ = ["MapRegistration", "MapRegistrationEnv", "MapRegistrationVectorEnv"]
