"""Deprecated: ``ranges_and_bearings`` lives in ``infonav_gym.envs.active_transition``.

Kept for the team envs that import it from here until they are written once; import it from there.
"""

from infonav_gym.envs.active_transition import ranges_and_bearings

__all__ = ["ranges_and_bearings"]
