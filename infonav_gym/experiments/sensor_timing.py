"""Frame times of the LADAR and the camera, against a pure-Pymunk 2D ray loop (``segment_query_first`` per pixel)
over the same rays on a default ``make_terrain``: a ratio below 1 means the 3D sensor beats even that loop."""

from __future__ import annotations

import math
import statistics
import time
from functools import partial

import numpy as np
import pymunk

from infonav_gym.experiments.registration_timing import alternating_times_ms
from infonav_gym.sensors import Camera, Ladar
from infonav_gym.world.terrain import Terrain
from infonav_gym.world.terrain_generation import make_terrain

POSES = ((0.0, 0.0, 0.0), (1.0, -0.5, 2.1), (-0.5, 1.0, -2.1))  # vehicle [x, y, heading] [m, m, rad]
FRAMES_PER_POSE_SECOND = 10  # timed frames per pose per second of benchmark round


def footprint_space(terrain: Terrain) -> pymunk.Space:
    """A ``pymunk.Space`` whose static body holds the footprints of ``terrain``'s obstacles."""
    space = pymunk.Space()
    body = space.static_body
    shapes = [pymunk.Circle(body, cylinder.radius_m, cylinder.center_m) for cylinder in terrain.cylinders]
    for box in terrain.boxes:
        (x0, y0, _), (x1, y1, _) = box.min_corner_m, box.max_corner_m
        shapes.append(pymunk.Poly(body, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]))
    space.add(*shapes)
    return space


def pymunk_rays_ms(space: pymunk.Space, sensor: Ladar | Camera, vehicle_pose) -> float:
    """Milliseconds of one ``segment_query_first`` per pixel along its ray's horizontal track, ``max_range_m`` long."""
    azimuth, elevation = sensor.pixel_angles()
    start = (float(vehicle_pose[0]), float(vehicle_pose[1]))
    ends = [
        (start[0] + sensor.max_range_m * math.cos(angle), start[1] + sensor.max_range_m * math.sin(angle))
        for angle in vehicle_pose[2] + azimuth
    ]
    shape_filter = pymunk.ShapeFilter()
    begin = time.perf_counter()
    for _ in range(elevation.size):
        for end in ends:
            space.segment_query_first(start, end, 0, shape_filter)
    return (time.perf_counter() - begin) * 1e3


def sensor_figures(seconds_per_round: float = 1.0, seed: int = 0) -> dict[str, float]:
    """Median frame time [ms] of the default LADAR and camera and of the Pymunk loop, and their ratio, per sensor;
    ``seconds_per_round`` scales the number of frames."""
    terrain = make_terrain(np.random.default_rng(seed))
    space = footprint_space(terrain)
    rng = np.random.default_rng(seed)
    frames = max(1, round(FRAMES_PER_POSE_SECOND * seconds_per_round))
    ladar, camera = Ladar(), Camera()
    sensors = {
        "ladar": (ladar, lambda pose: ladar.scan(terrain, pose, rng)),
        "camera": (camera, lambda pose: camera.capture(terrain, pose, rng)),
    }
    figures = {}
    for name, (sensor, take_frame) in sensors.items():
        ours, reference = [], []
        for pose in POSES:  # alternate with the reference, so a busy machine slows both alike
            ours += alternating_times_ms({name: partial(take_frame, pose)}, frames)[name][1]
            reference.append(pymunk_rays_ms(space, sensor, pose))
        figures[f"{name}_frame_ms"] = statistics.median(ours)
        figures[f"pymunk_{name}_rays_ms"] = statistics.median(reference)
        figures[f"{name}_vs_pymunk_ratio"] = figures[f"{name}_frame_ms"] / figures[f"pymunk_{name}_rays_ms"]
    return figures
