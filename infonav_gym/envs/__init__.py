"""Single-agent environments; each name is imported from its module when first asked for."""

from infonav_gym.lazy import lazy_exports

__all__, __getattr__ = lazy_exports(
    __name__,
    {
        "base": ("InfoNavEnv",),
        "landmark_selection": ("LandmarkSelectionEnv",),
        "sensor_selection": ("SensorSelectionEnv",),
    },
)
