"""Sensor models, each drawing its noise from the ``np_random`` it is handed; names imported when first asked for."""

from infonav_gym.lazy import lazy_exports

__all__, __getattr__ = lazy_exports(
    __name__,
    {
        "camera": ("Camera", "ground_texture"),
        "gps": ("GPSSensor",),
        "ladar": ("Ladar", "LadarScan", "point_cloud", "to_display_image"),
        "odometry": ("OdometrySensor",),
        "range_bearing": ("RangeBearingSensor",),
        "relative_pose": ("RELATIVE_POSE_SENSORS", "RelativePoseSensor"),
    },
)
