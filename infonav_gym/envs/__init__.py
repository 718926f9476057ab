"""Single-agent environments, each its native vector env's N = 1 view; a name is imported when first asked for."""

from infonav_gym.lazy import lazy_exports

__all__, __getattr__ = lazy_exports(
    __name__,
    {
        "landmark_selection": ("LandmarkSelectionEnv",),
        "range_registration": ("RangeRegistrationEnv",),
        "sensor_selection": ("SensorSelectionEnv",),
    },
)
