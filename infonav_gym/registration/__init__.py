"""Registration of 3D point sets and range images (the paper's Section V)."""

from infonav_gym.registration.control_points import CONTROL_POINT_STRATEGIES, select_control_points
from infonav_gym.registration.icp import RegistrationResult, icp
from infonav_gym.registration.points import range_image_to_points

__all__ = [
    "CONTROL_POINT_STRATEGIES",
    "RegistrationResult",
    "icp",
    "range_image_to_points",
    "select_control_points",
]
