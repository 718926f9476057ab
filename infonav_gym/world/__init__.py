"""The simulated 2D world (Pymunk) and its scenarios; each name is imported from its module when first asked for."""

from infonav_gym.lazy import lazy_exports

__all__, __getattr__ = lazy_exports(
    __name__,
    {
        "scenarios": (
            "SCENARIOS",
            "CircleObstacle",
            "Route",
            "Scenario",
            "build_scenario",
            "register_scenario",
            "scenario_names",
        ),
        "terrain": ("MATERIALS", "Box", "Cylinder", "RayHits", "Terrain"),
        "terrain_generation": ("flat_terrain", "make_terrain"),
        "visibility": ("StaticGeometry",),
        "world": ("World",),
    },
)
