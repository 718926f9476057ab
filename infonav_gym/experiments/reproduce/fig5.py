"""The paper's Fig. 5: how much information the default camera and LADAR images carry, by ``histogram_entropy``
[nats], on ``make_terrain`` scenes ``paper_like`` (rugged, vegetated: LADAR > camera) and ``building_ahead`` (a
facade fills the LADAR's narrow field at one range: camera > LADAR); the seed statistics count how often each holds."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from infonav_gym.information import histogram_entropy
from infonav_gym.rendering import matplotlib_figure, save_figure
from infonav_gym.sensors.camera import Camera
from infonav_gym.sensors.ladar import Ladar, to_display_image
from infonav_gym.world.terrain import Box, Terrain
from infonav_gym.world.terrain_generation import make_terrain

SEEDS_COUNT = "how many random scenes the statistics count"  # what ``n_seeds`` counts, for its error
PAPER_LIKE_TERRAIN = {
    "size_m": 120.0,
    "cell_m": 0.5,
    "roughness": 0.8,
    "n_trees": 150,
    "n_rocks": 100,
    "n_buildings": 0,
    "clear_radius_m": 3.0,
}
SECOND_VIEW_ADVANCE_M = 1.5  # the similar scene: the vehicle this much further along its heading [m]
SECOND_VIEW_TURN_RAD = math.radians(4.0)  # ... and turned this much to the left [rad]
LEVEL_LOOKAHEAD_M = (2.0, 25.0)  # stretch of ground ahead whose levelness picks the heading [m]
HEADING_CANDIDATES_DEG = 5.0  # spacing of the candidate headings [deg]

BUILDING_AHEAD_TERRAIN = {**PAPER_LIKE_TERRAIN, "roughness": 0.3, "n_trees": 0, "n_rocks": 0}
BUILDING_DISTANCE_M = (3.0, 8.0)  # from the vehicle to the building's facade [m]
BUILDING_WIDTH_M = (10.0, 30.0)  # facade width, centred on the vehicle's line [m]
BUILDING_HEIGHT_M = (3.0, 8.0)  # above the ground in front of it [m]
BUILDING_DEPTH_M = 8.0  # [m]
BUILDING_HEADING_DEG = 15.0  # the vehicle faces the facade within +- this [deg]

CASES = ("paper_like", "building_ahead")
_SENSOR_NAMES = {"camera": "camera", "ladar": "LADAR"}


def level_heading(terrain: Terrain, position_m) -> float:
    """The heading [rad] from ``position_m`` whose ground over ``LEVEL_LOOKAHEAD_M`` stays most level."""
    position = np.asarray(position_m, dtype=float)
    headings = np.radians(np.arange(0.0, 360.0, HEADING_CANDIDATES_DEG))
    distances = np.linspace(*LEVEL_LOOKAHEAD_M, 24)
    directions = np.stack([np.cos(headings), np.sin(headings)], axis=-1)
    track = position + distances[None, :, None] * directions[:, None, :]  # (headings, distances, 2)
    rise = np.abs(terrain.height_at(track) - terrain.height_at(position)).mean(axis=1)
    return float(headings[np.argmin(rise)])


def paper_like_scene(np_random: np.random.Generator) -> tuple[Terrain, list[list[float]]]:
    """Vegetated, rugged terrain and two similar vehicle poses ``[x, y, heading]`` [m, m, rad] in it."""
    terrain = make_terrain(np_random, **PAPER_LIKE_TERRAIN)
    heading = level_heading(terrain, (0.0, 0.0))
    ahead = SECOND_VIEW_ADVANCE_M * np.array([math.cos(heading), math.sin(heading)])
    return terrain, [[0.0, 0.0, heading], [float(ahead[0]), float(ahead[1]), heading + SECOND_VIEW_TURN_RAD]]


def building_ahead_scene(np_random: np.random.Generator) -> tuple[Terrain, list[float], dict]:
    """Gently rolling ground with a building close ahead; the pose ``[x, y, heading]`` and the building's size."""
    terrain = make_terrain(np_random, **BUILDING_AHEAD_TERRAIN)
    distance, width, height = (
        np_random.uniform(*bounds) for bounds in (BUILDING_DISTANCE_M, BUILDING_WIDTH_M, BUILDING_HEIGHT_M)
    )
    heading = np_random.uniform(-1.0, 1.0) * math.radians(BUILDING_HEADING_DEG)
    back = distance + BUILDING_DEPTH_M
    footprint = np.array(
        [[distance, 0.0], [distance, -width / 2], [distance, width / 2], [back, -width / 2], [back, width / 2]]
    )
    ground_m = terrain.height_at(footprint)
    building = Box((distance, -width / 2, float(ground_m.min())), (back, width / 2, float(ground_m[0]) + height))
    building_record = {"distance_m": distance, "width_m": width, "height_m": height, "depth_m": BUILDING_DEPTH_M}
    return terrain.with_obstacles(boxes=[building]), [0.0, 0.0, heading], building_record


def capture_views(terrain: Terrain, vehicle_pose, np_random: np.random.Generator) -> dict:
    """The default camera's image and the default LADAR's display image (dark = near), both uint8."""
    return {
        "camera": Camera().capture(terrain, vehicle_pose, np_random),
        "ladar": to_display_image(Ladar().scan(terrain, vehicle_pose, np_random)),
    }


def _view_record(case: str, label: str, pose, images: dict) -> dict:
    """What the figure shows of one view: the pose, each image's 256-bin histogram and entropy [nats]."""
    record = {"case": case, "label": label, "vehicle_pose": [float(value) for value in pose]}
    for sensor, image in images.items():
        record[sensor] = {
            "shape": list(image.shape),
            "entropy_nats": histogram_entropy(image),
            "histogram": np.bincount(image.ravel(), minlength=256).tolist(),
        }
    return record


def _seed_views(seed: int) -> tuple[list[tuple[str, str, list[float], dict]], dict]:
    """Each view of ``seed``'s scenes as ``(label, case, vehicle_pose, images)``, and the building's size."""
    rng = np.random.default_rng(seed)
    terrain, poses = paper_like_scene(rng)
    views = [
        (f"paper-like scene {number}", "paper_like", pose, capture_views(terrain, pose, rng))
        for number, pose in enumerate(poses, start=1)
    ]
    rng = np.random.default_rng(seed)
    terrain, pose, building = building_ahead_scene(rng)
    views.append(("building ahead", "building_ahead", pose, capture_views(terrain, pose, rng)))
    return views, building


def run_fig5(seed: int = 0) -> tuple[dict, list[dict]]:
    """Fig. 5 for one seed (two similar paper-like views, one building-ahead view): the JSON-ready dict (``seed``,
    ``building`` and per view and sensor ``shape``, 256-bin ``histogram``, ``entropy_nats``) and each view's images."""
    views, building = _seed_views(seed)
    records = [_view_record(case, label, pose, images) for label, case, pose, images in views]
    return {"seed": seed, "building": building, "views": records}, [images for *_, images in views]


def seed_statistics(seeds, progress: bool = False) -> dict:
    """How often each case's ordering holds over ``seeds`` (one scene of each case per seed; paper-like: in every view),
    with the ``per_seed`` entropies and each sensor's mean [nats]."""
    seeds = list(seeds)
    if not seeds:
        raise ValueError("seed_statistics needs at least one seed, got none")
    per_seed = []
    for seed in tqdm(seeds, desc="Fig. 5 scenes", unit="seed", disable=not progress):
        record = {"seed": seed, "paper_like": [], "building_ahead": []}
        for _, case, _, images in _seed_views(seed)[0]:
            record[case].append({sensor: histogram_entropy(image) for sensor, image in images.items()})
        per_seed.append(record)

    def summary(case: str, winner: str, loser: str) -> dict:
        views = [record[case] for record in per_seed]
        return {
            "expected": f"{_SENSOR_NAMES[winner]} > {_SENSOR_NAMES[loser]}",
            "fraction": float(
                np.mean([all(view[winner] > view[loser] for view in seed_views) for seed_views in views])
            ),
            "mean_camera_nats": float(np.mean([view["camera"] for seed_views in views for view in seed_views])),
            "mean_ladar_nats": float(np.mean([view["ladar"] for seed_views in views for view in seed_views])),
        }

    return {
        "seeds": seeds,
        "per_seed": per_seed,
        "paper_like": summary("paper_like", "ladar", "camera"),
        "building_ahead": summary("building_ahead", "camera", "ladar"),
    }


def figures(seed: int, seeds, progress: bool) -> tuple[dict, Callable[[Path], object]]:
    """Fig. 5's scenes of ``seed`` and the statistics over ``seeds`` (JSON-ready), and the function drawing them."""
    fig5, images = run_fig5(seed)
    result = {
        "scenes": {
            "paper_like": {
                "make_terrain": dict(PAPER_LIKE_TERRAIN),
                "heading": f"most level over {LEVEL_LOOKAHEAD_M[0]:g}-{LEVEL_LOOKAHEAD_M[1]:g} m ahead",
                "second_view_advance_m": SECOND_VIEW_ADVANCE_M,
                "second_view_turn_deg": math.degrees(SECOND_VIEW_TURN_RAD),
            },
            "building_ahead": {
                "make_terrain": dict(BUILDING_AHEAD_TERRAIN),
                "building_distance_m": list(BUILDING_DISTANCE_M),
                "building_width_m": list(BUILDING_WIDTH_M),
                "building_height_m": list(BUILDING_HEIGHT_M),
                "building_depth_m": BUILDING_DEPTH_M,
                "heading_within_deg": BUILDING_HEADING_DEG,
            },
            "sensors": {"camera": "Camera() defaults", "ladar": "Ladar() defaults, to_display_image (dark = near)"},
        },
        "fig5": fig5,
        "seed_statistics": seed_statistics(seeds, progress=progress),
    }
    return result, lambda path: save_figure(figure_fig5(fig5, images), path, dpi=110, bbox_inches="tight")


def table(result: dict) -> str:
    """The figures of the paper's Fig. 5 story as text: each view's entropies and the seed statistics."""
    fig5, statistics = result["fig5"], result["seed_statistics"]
    lines = [
        f"Fig. 5, seed {fig5['seed']}: gray-level histogram entropy [nats]",
        f"  {'view':24s}{'camera':>8s}{'LADAR':>8s}",
    ]
    for view in fig5["views"]:
        camera, ladar = view["camera"]["entropy_nats"], view["ladar"]["entropy_nats"]
        more = "LADAR" if ladar > camera else "camera"
        lines.append(f"  {view['label']:24s}{camera:8.3f}{ladar:8.3f}  {more} more informative")
    seeds = statistics["seeds"]
    lines.append(f"Random scenes, seeds {seeds[0]}..{seeds[-1]}:")
    for case in CASES:
        summary = statistics[case]
        lines.append(
            f"  {case:16s}{summary['expected']:16s} in {summary['fraction']:6.1%} of seeds"
            f"  (mean camera {summary['mean_camera_nats']:.3f}, LADAR {summary['mean_ladar_nats']:.3f})"
        )
    return "\n".join(lines)


_SENSORS = (("camera", "camera", "tab:blue"), ("ladar", "LADAR", "tab:red"))
_LETTERS = "abcdefghijklmnopqrstuvwxyz"


def _extent_deg(sensor) -> tuple[float, float, float, float]:
    """``(left, right, bottom, top)`` of a sensor's image [deg]: azimuth from the heading (left +), elevation."""
    half_width = math.degrees(sensor.horizontal_fov_rad) / 2
    top = math.degrees(sensor.vertical_fov_rad / 2 - sensor.tilt_rad)
    return half_width, -half_width, top - math.degrees(sensor.vertical_fov_rad), top


def _label(axes, title: str, xlabel: str, ylabel: str) -> None:
    axes.set_title(title, fontsize="medium")
    axes.set_xlabel(xlabel, fontsize="small")
    axes.set_ylabel(ylabel, fontsize="small")
    axes.tick_params(labelsize="small")


def _draw_image(axes, image: np.ndarray, sensor, title: str) -> None:
    axes.imshow(image, cmap="gray", vmin=0, vmax=255, extent=_extent_deg(sensor), interpolation="nearest")
    _label(axes, title, "azimuth, left + [deg]", "elevation [deg]")


def _draw_histogram(axes, sensor_record: dict, colour: str, title: str) -> None:
    counts = np.asarray(sensor_record["histogram"])
    axes.stairs(counts, np.arange(257), fill=True, color=colour)
    axes.set(xlim=(0, 256), ylim=(0, 1.25 * counts.max()))
    entropy = f"H = {sensor_record['entropy_nats']:.2f} nats"
    axes.text(0.5, 0.95, entropy, transform=axes.transAxes, ha="center", va="top", fontsize="large", fontweight="bold")
    _label(axes, title, "gray level (brightness) [0-255]", "pixels [count]")


def figure_fig5(fig5: dict, images: list[dict]):
    """``run_fig5``'s views drawn like the paper's Fig. 5, one row per view."""
    sensors = {"camera": Camera(), "ladar": Ladar()}
    rows = len(fig5["views"])
    figure = matplotlib_figure("the Fig. 5 plot", figsize=(18, 3.6 * rows), layout="constrained")
    axes = figure.subplots(rows, 4, width_ratios=(1.1, 1, 1.7, 1), squeeze=False)
    letters = iter(_LETTERS)
    for row, (view, pair) in enumerate(zip(fig5["views"], images, strict=True)):
        for column, (key, name, colour) in enumerate(_SENSORS):
            record = view[key]
            rows_px, columns_px = record["shape"]
            image_axes, histogram_axes = axes[row, 2 * column], axes[row, 2 * column + 1]
            title = f"({next(letters)}) {name}, {view['label']} ({rows_px} x {columns_px})"
            _draw_image(image_axes, pair[key], sensors[key], title)
            _draw_histogram(histogram_axes, record, colour, f"({next(letters)}) {name} histogram, {view['label']}")
    figure.suptitle(
        f"Fig. 5: camera and LADAR images (LADAR: dark = near) with their 256-bin gray-level histograms and "
        f"entropies, seed {fig5['seed']}.\nRows 1-2: two similar views of vegetated, rugged terrain (LADAR more "
        f"informative); row 3: a building {fig5['building']['distance_m']:.1f} m ahead (camera more informative)."
    )
    return figure
