"""State estimation: motion / measurement models, Kalman filters, consistency checks."""

from infonav_gym.estimation.consistency import chi2_bounds, nees, nis, pose_error
from infonav_gym.estimation.ekf import JointEKF, PoseEKF
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
