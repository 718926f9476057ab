"""infonav-gym: Gymnasium / PettingZoo environments for information-driven navigation.

Importing the package registers its environments (``register_envs``) in ``infonav_gym.registry``,
the Gymnasium ones with Gymnasium as well. ``make_env(env_id, **config)`` makes either kind.
"""

from infonav_gym.registry import GYMNASIUM, PARALLEL, make_env, make_vector_env, register, registered_envs, unregister

__version__ = "0.1.0"
__all__ = ["make_env", "make_vector_env", "register", "register_envs", "registered_envs", "unregister"]

BUILTIN_ENVS = tuple(  # (id, entry point, api, vector entry point): each env's package exports Env and VectorEnv
    (env_id, f"infonav_gym.envs.{package}:{name}Env", api, f"infonav_gym.envs.{package}:{name}VectorEnv")
    for env_id, package, name, api in (
        ("infonav/LandmarkSelection-v0", "landmark_selection", "LandmarkSelection", GYMNASIUM),
        ("infonav/ActiveLocalization-v0", "active_localization", "ActiveLocalization", GYMNASIUM),
        ("infonav/SensorSelection-v0", "sensor_selection", "SensorSelection", GYMNASIUM),
        ("infonav/RangeRegistration-v0", "range_registration", "RangeRegistration", GYMNASIUM),
        ("cooperative_localization_v0", "cooperative_localization", "CooperativeLocalization", PARALLEL),
        ("cooperative_exploration_v0", "cooperative_exploration", "CooperativeExploration", PARALLEL),
        ("infonav/MRCLAMLocalization-v0", "mrclam_localization", "MRCLAMLocalization", GYMNASIUM),
        (
            "mrclam_cooperative_localization_v0",
            "mrclam_cooperative_localization",
            "MRCLAMCooperativeLocalization",
            PARALLEL,
        ),
        ("infonav/MapRegistration-v0", "map_registration", "MapRegistration", GYMNASIUM),
    )
)


def register_envs() -> None:
    """Register every infonav environment (``BUILTIN_ENVS``, with a native vector env where one follows the API)."""
    for env_id, entry_point, api, *vector_entry_point in BUILTIN_ENVS:
        register(env_id, entry_point, api, *vector_entry_point)


register_envs()
