"""Registration of 3D point sets and range images (the paper's Section V)."""

from infonav_gym.registration.control_points import CONTROL_POINT_STRATEGIES, select_control_points
from infonav_gym.registration.gicp import gicp_covariances
from infonav_gym.registration.icp import METHODS, RegistrationResult, icp
from infonav_gym.registration.points import range_image_to_points
from infonav_gym.registration.robust_kernels import ROBUST_KERNELS

__all__ = [
    "CONTROL_POINT_STRATEGIES",
    "METHODS",
    "ROBUST_KERNELS",
    "RegistrationResult",
    "gicp_covariances",
    "icp",
    "range_image_to_points",
    "select_control_points",
]
