"""ICP time and accuracy on LADAR frame pairs, ours against small_gicp's and, when it imports, Open3D's: two
``scan``s of a rough terrain (``PAIR_LADARS``: ~5k and ~40k points) 1 m apart, the true motion known, every
registration from the same perturbed warm start, correspondence distance and iteration cap; small_gicp's
preprocessing timed as ours. ``*_time_ratio``: our median time over the peer's, timed in turn round by round."""

from __future__ import annotations

import contextlib
import importlib
import math
import statistics
import time
from functools import partial

import numpy as np

from agents import GreedyEntropyAgent
from infonav_gym.envs.traits import traits_of
from infonav_gym.geometry import transform_error
from infonav_gym.registration import icp
from infonav_gym.registration.frame_pairs import motion_between, perturbed_motion
from infonav_gym.registration.gicp import GICP_NEIGHBOURS
from infonav_gym.registry import make_env
from infonav_gym.sensors.ladar import Ladar, sensor_points
from infonav_gym.world.terrain_generation import make_terrain

POSES = ((0.0, 0.0, 0.0), (1.0, 0.0, math.radians(2.0)))  # vehicle [x, y, heading] [m, m, rad]
WARM_START_ERROR_M = 0.05
WARM_START_ERROR_DEG = 0.5
MAX_CORRESPONDENCE_DISTANCE_M = 1.0
MAX_ITERATIONS = 30
TOLERANCE = 1e-6  # icp's default convergence threshold [rad] and [m], also given to small_gicp
REPEATS_PER_SECOND = 40  # timed registrations of a frame pair per second of benchmark round, at least MIN_REPEATS
MIN_REPEATS = 3  # also the timed registrations of the 40k-point pair
PAIR_LADARS = {"frame_pair": Ladar(), "scan_40k": Ladar(rows=128, columns=360)}
PEER_OF = {"open3d_icp": "icp", "small_gicp": "gicp"}  # a peer's registration -> ours it is timed against


def frame_pair(seed: int = 0, ladar: Ladar | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(source, target, true_motion, warm_start)``: the second frame, the first, and (4, 4) transforms."""
    ladar = Ladar() if ladar is None else ladar
    rng = np.random.default_rng(seed)
    terrain = make_terrain(np.random.default_rng(seed), roughness=1.0)
    previous, current = (ladar.scan(terrain, pose, rng) for pose in POSES)
    truth = motion_between(previous, current)
    axis, direction = (vector / np.linalg.norm(vector) for vector in rng.standard_normal((2, 3)))
    error = np.concatenate([WARM_START_ERROR_M * direction, math.radians(WARM_START_ERROR_DEG) * axis])
    return sensor_points(current), sensor_points(previous), truth, perturbed_motion(truth, error)


def registration_peers_missing() -> str | None:
    """Why the Open3D rows are absent (it does not import), or None when it imports."""
    try:
        importlib.import_module("open3d")
    except ImportError as error:
        return f"ICP peer figures absent: open3d ({error}) does not import; pip install 'infonav-gym[bench]'"
    return None


def _ours(source, target, truth, warm_start, method: str):
    def register() -> np.ndarray:
        return icp(
            source,
            target,
            warm_start,
            max_iterations=MAX_ITERATIONS,
            tolerance=TOLERANCE,
            max_correspondence_distance=MAX_CORRESPONDENCE_DISTANCE_M,
            method=method,
        ).transform

    return register


def _open3d(source, target, truth, warm_start):
    o3d = importlib.import_module("open3d")
    clouds = [o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points)) for points in (source, target)]
    criteria = o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=MAX_ITERATIONS)
    estimation = o3d.pipelines.registration.TransformationEstimationPointToPoint()

    def register() -> np.ndarray:
        return np.asarray(
            o3d.pipelines.registration.registration_icp(
                *clouds, MAX_CORRESPONDENCE_DISTANCE_M, warm_start, estimation, criteria
            ).transformation
        )

    return register


def _small_gicp(source, target, truth, warm_start):
    small_gicp = importlib.import_module("small_gicp")

    def register() -> np.ndarray:
        clouds = [small_gicp.PointCloud(points) for points in (source, target)]
        trees = [small_gicp.KdTree(cloud, num_threads=1) for cloud in clouds]
        for cloud, tree in zip(clouds, trees):
            small_gicp.estimate_covariances(cloud, tree, num_neighbors=GICP_NEIGHBOURS, num_threads=1)
        return small_gicp.align(
            clouds[1],
            clouds[0],
            trees[1],
            warm_start,
            registration_type="GICP",
            max_correspondence_distance=MAX_CORRESPONDENCE_DISTANCE_M,
            num_threads=1,
            max_iterations=MAX_ITERATIONS,
            rotation_epsilon=TOLERANCE,
            translation_epsilon=TOLERANCE,
        ).T_target_source

    return register


def alternating_times_ms(calls: dict, repeats: int) -> dict[str, tuple[object, list[float]]]:
    """Per name of ``calls``: one untimed warm-up call's result and the milliseconds of ``repeats`` calls, taken in
    turn so that the machine's load weighs on each alike."""
    results = {name: (call(), []) for name, call in calls.items()}
    for _ in range(repeats):
        for name, call in calls.items():
            begin = time.perf_counter()
            call()
            results[name][1].append((time.perf_counter() - begin) * 1e3)
    return results


def icp_figures(seconds_per_round: float = 1.0, seed: int = 0) -> dict[str, float]:
    """ICP figures on each pair of ``PAIR_LADARS``: ``icp_<pair>_ms`` / ``gicp_<pair>_ms``, their rotation and
    translation errors, ``icp_<pair>_points``, and with a peer its ``open3d_*`` / ``small_gicp_*`` figures and the
    ``*_time_ratio``; ``seconds_per_round`` scales the repeats on the frame pair."""
    registrations = {
        "icp": partial(_ours, method="point_to_point"),
        "gicp": partial(_ours, method="gicp"),
        "open3d_icp": _open3d,
        "small_gicp": _small_gicp,
    }
    figures = {}
    for pair, ladar in PAIR_LADARS.items():
        clouds = frame_pair(seed, ladar)
        source, _, truth, _ = clouds
        repeats = max(MIN_REPEATS, round(REPEATS_PER_SECOND * seconds_per_round)) if pair == "frame_pair" else 3
        figures[f"icp_{pair}_points"] = float(source.shape[0])
        registers = {}
        for name, make in registrations.items():
            with contextlib.suppress(ImportError):  # a peer that does not import has no figures
                registers[name] = make(*clouds)
        for name, (transform, times) in alternating_times_ms(registers, repeats).items():
            figures[f"{name}_{pair}_ms"] = statistics.median(times)
            translation, rotation = transform_error(transform, truth)
            figures[f"{name}_{pair}_rotation_error_deg"] = math.degrees(rotation)
            figures[f"{name}_{pair}_translation_error_m"] = translation
            if name in PEER_OF:
                ours = figures[f"{PEER_OF[name]}_{pair}_ms"]
                figures[f"{PEER_OF[name]}_vs_{name}_{pair}_time_ratio"] = ours / figures[f"{name}_{pair}_ms"]
    return figures


MAP_ENV, FRAME_PAIR_ENV = "infonav/MapRegistration-v0", "infonav/RangeRegistration-v0"
MAP_TIME_RATIO = "map_registration_step_vs_range_registration_registering_step_time_ratio"


def registering_step_ms(env_id: str, seconds: float, seed: int) -> float:
    """The mean wall time [ms] of ``env_id``'s steps that register (``info["registered"]`` or ``info["fused"]`` or
    ``info["refused"]``) over about ``seconds`` of greedy steps (the everything action where the env has one)."""
    env = make_env(env_id)
    everything, greedy = traits_of(env).everything_action, GreedyEntropyAgent()
    _, info = env.reset(seed=seed)
    times, deadline = [], time.perf_counter() + seconds
    while time.perf_counter() < deadline or not times:
        action = greedy.act(None, info) if everything is None else everything
        start = time.perf_counter()
        _, _, terminated, truncated, info = env.step(action)
        elapsed = time.perf_counter() - start
        if info.get("registered", False) or info.get("fused", False) or info.get("refused", False):
            times.append(elapsed)
        if terminated or truncated:
            _, info = env.reset()
    env.close()
    return 1e3 * statistics.fmean(times)


def map_step_figures(rounds: int, seconds_per_round: float, seed: int) -> dict:
    """A ``MapRegistration-v0`` step with one registration (every return) against a ``RangeRegistration-v0`` step
    that registers (its pair's last pick), timed in turn each round: both times [ms] (medians) and the median of
    their ratios."""
    map_ms, pair_ms = [], []
    for _ in range(rounds):
        map_ms.append(registering_step_ms(MAP_ENV, seconds_per_round, seed))
        pair_ms.append(registering_step_ms(FRAME_PAIR_ENV, seconds_per_round, seed))
    return {
        "map_registration_step_ms": statistics.median(map_ms),
        "range_registration_registering_step_ms": statistics.median(pair_ms),
        MAP_TIME_RATIO: statistics.median(ours / theirs for ours, theirs in zip(map_ms, pair_ms)),
    }
