"""State estimation: motion / measurement models, Kalman filters, consistency checks.

``PoseEKF`` / ``JointEKF`` (on filterpy, ~1 s to import) load when first asked for: the envs run the batched core.
"""

import importlib

from infonav_gym.estimation.consistency import chi2_bounds, nees, nis, pose_error
from infonav_gym.estimation.models import (
    range_bearing,
    range_bearing_linearized,
    relative_pose,
    relative_pose_linearized,
    unicycle_jacobians,
    unicycle_motion,
)
from infonav_gym.geometry import wrap_angle

__all__ = [
    "JointEKF",
    "PoseEKF",
    "chi2_bounds",
    "nees",
    "nis",
    "pose_error",
    "range_bearing",
    "range_bearing_linearized",
    "relative_pose",
    "relative_pose_linearized",
    "unicycle_jacobians",
    "unicycle_motion",
    "wrap_angle",
]


def __getattr__(name: str):
    if name in ("JointEKF", "PoseEKF"):
        return getattr(importlib.import_module("infonav_gym.estimation.ekf"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
