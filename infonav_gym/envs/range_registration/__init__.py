"""``infonav/RangeRegistration-v0``: which patches of a LADAR frame feed ICP (``scenario.py``)."""

from infonav_gym.envs.range_registration.scenario import (
    RangeRegistration,
    RangeRegistrationEnv,
    RangeRegistrationVectorEnv,
)

__all__ = ["RangeRegistration", "RangeRegistrationEnv", "RangeRegistrationVectorEnv"]
