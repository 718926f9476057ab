"""ICP time and accuracy on a LADAR frame pair, ours against Open3D's ``registration_icp`` when it imports.

The pair: two default ``Ladar().scan`` (32 x 180) frames of ``make_terrain(default_rng(seed),
roughness=1.0)``, from the vehicle pose ``[0, 0, 0]`` and from 1 m ahead turned 2 degrees left.
Each frame's points are kept in its own sensor frame (``sensor_points``), so the true motion
mapping the second frame onto the first is known exactly (``motion_between``). Both ICPs
register the second frame onto the first, point-to-point, from the same warm start (the true
motion perturbed by ``WARM_START_ERROR_M`` and ``WARM_START_ERROR_DEG`` about random
directions), with the same correspondence distance and iteration cap.
"""

from __future__ import annotations

import math
import statistics
import time

import numpy as np

from infonav_gym.geometry import transform_error
from infonav_gym.registration import icp
from infonav_gym.registration.frame_pairs import motion_between, perturbed_motion
from infonav_gym.sensors.ladar import Ladar, sensor_points
from infonav_gym.world.terrain_generation import make_terrain

POSES = ((0.0, 0.0, 0.0), (1.0, 0.0, math.radians(2.0)))  # vehicle [x, y, heading] [m, m, rad]
WARM_START_ERROR_M = 0.05
WARM_START_ERROR_DEG = 0.5
MAX_CORRESPONDENCE_DISTANCE_M = 1.0
MAX_ITERATIONS = 30
REPEATS_PER_SECOND = 40  # timed registrations per second of benchmark round, at least MIN_REPEATS
MIN_REPEATS = 3


def frame_pair(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(source, target, true_motion, warm_start)``: the second frame, the first, and (4, 4) transforms."""
    rng = np.random.default_rng(seed)
    terrain = make_terrain(np.random.default_rng(seed), roughness=1.0)
    ladar = Ladar()
    previous, current = (ladar.scan(terrain, pose, rng) for pose in POSES)
    truth = motion_between(previous, current)
    axis, direction = (vector / np.linalg.norm(vector) for vector in rng.standard_normal((2, 3)))
    error = np.concatenate([WARM_START_ERROR_M * direction, math.radians(WARM_START_ERROR_DEG) * axis])
    return sensor_points(current), sensor_points(previous), truth, perturbed_motion(truth, error)


def motion_errors(estimate: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Rotation error [deg] and translation error [m] of a (4, 4) ``estimate`` of ``truth``."""
    translation, rotation = transform_error(estimate, truth)
    return math.degrees(rotation), translation


def _median_ms(register, repeats: int) -> tuple[float, np.ndarray]:
    """Median milliseconds of ``repeats`` calls ``register() -> transform`` after a warm-up, and the transform."""
    transform = register()
    times = []
    for _ in range(repeats):
        begin = time.perf_counter()
        register()
        times.append((time.perf_counter() - begin) * 1e3)
    return statistics.median(times), transform


def icp_figures(seconds_per_round: float = 1.0, seed: int = 0) -> dict[str, float]:
    """ICP figures on the frame pair: ``icp_frame_pair_ms``, ``icp_rotation_error_deg``, ``icp_translation_error_m``.

    With Open3D importable, also ``open3d_icp_frame_pair_ms``, ``open3d_rotation_error_deg`` and
    ``open3d_translation_error_m``; ``seconds_per_round`` scales the number of timed registrations.
    """
    source, target, truth, warm_start = frame_pair(seed)
    repeats = max(MIN_REPEATS, round(REPEATS_PER_SECOND * seconds_per_round))

    def ours() -> np.ndarray:
        return icp(
            source,
            target,
            warm_start,
            max_iterations=MAX_ITERATIONS,
            max_correspondence_distance=MAX_CORRESPONDENCE_DISTANCE_M,
        ).transform

    figures = {"icp_points": float(source.shape[0])}
    figures["icp_frame_pair_ms"], transform = _median_ms(ours, repeats)
    figures["icp_rotation_error_deg"], figures["icp_translation_error_m"] = motion_errors(transform, truth)
    try:
        import open3d as o3d
    except ImportError:
        return figures
    clouds = [o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points)) for points in (source, target)]
    criteria = o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=MAX_ITERATIONS)
    estimation = o3d.pipelines.registration.TransformationEstimationPointToPoint()

    def theirs() -> np.ndarray:
        return np.asarray(
            o3d.pipelines.registration.registration_icp(
                *clouds, MAX_CORRESPONDENCE_DISTANCE_M, warm_start, estimation, criteria
            ).transformation
        )

    figures["open3d_icp_frame_pair_ms"], transform = _median_ms(theirs, repeats)
    figures["open3d_rotation_error_deg"], figures["open3d_translation_error_m"] = motion_errors(transform, truth)
    return figures
