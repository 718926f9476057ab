"""Sensor models: each draws its noise from the ``np_random`` it is handed."""

from infonav_gym.sensors.camera import Camera, ground_texture
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.ladar import Ladar, LadarScan, point_cloud, to_display_image
from infonav_gym.sensors.odometry import OdometrySensor
from infonav_gym.sensors.range_bearing import RangeBearingSensor
from infonav_gym.sensors.relative_pose import RELATIVE_POSE_SENSORS, RelativePoseSensor

__all__ = [
    "RELATIVE_POSE_SENSORS",
    "Camera",
    "GPSSensor",
    "Ladar",
    "LadarScan",
    "OdometrySensor",
    "RangeBearingSensor",
    "RelativePoseSensor",
    "ground_texture",
    "point_cloud",
    "to_display_image",
]
