"""Fig. 5 as a picture: per view, the camera image, its histogram, the LADAR image (dark = near), its histogram."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from infonav_gym.rendering import require_extra
from infonav_gym.sensors.camera import Camera
from infonav_gym.sensors.ladar import Ladar

_SENSORS = (("camera", "camera", "tab:blue"), ("ladar", "LADAR", "tab:red"))
_LETTERS = "abcdefghijklmnopqrstuvwxyz"


def _extent_deg(sensor) -> tuple[float, float, float, float]:
    """``(left, right, bottom, top)`` of a sensor's image [deg]: azimuth from the heading (left +), elevation."""
    half_width = math.degrees(sensor.horizontal_fov_rad) / 2
    top = math.degrees(sensor.vertical_fov_rad / 2 - sensor.tilt_rad)
    return half_width, -half_width, top - math.degrees(sensor.vertical_fov_rad), top


def _draw_image(axes, image: np.ndarray, sensor, title: str) -> None:
    axes.imshow(image, cmap="gray", vmin=0, vmax=255, extent=_extent_deg(sensor), interpolation="nearest")
    axes.set_title(title, fontsize="medium")
    axes.set_xlabel("azimuth, left + [deg]", fontsize="small")
    axes.set_ylabel("elevation [deg]", fontsize="small")
    axes.tick_params(labelsize="small")


def _draw_histogram(axes, sensor_record: dict, colour: str, title: str) -> None:
    counts = np.asarray(sensor_record["histogram"])
    axes.stairs(counts, np.arange(257), fill=True, color=colour)
    axes.set_xlim(0, 256)
    axes.set_ylim(0, 1.25 * counts.max())
    axes.text(
        0.5,
        0.95,
        f"H = {sensor_record['entropy_nats']:.2f} nats",
        transform=axes.transAxes,
        ha="center",
        va="top",
        fontsize="large",
        fontweight="bold",
    )
    axes.set_title(title, fontsize="medium")
    axes.set_xlabel("gray level (brightness)", fontsize="small")
    axes.set_ylabel("pixels", fontsize="small")
    axes.tick_params(labelsize="small")


def plot_fig5(fig5: dict, images: list[dict], path: Path) -> Path:
    """Draw ``run_fig5``'s views like the paper's Fig. 5, one row per view, and save it as a PNG at ``path``."""
    require_extra("matplotlib", "the Fig. 5 plot")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sensors = {"camera": Camera(), "ladar": Ladar()}
    rows = len(fig5["views"])
    figure, axes = plt.subplots(
        rows, 4, figsize=(18, 3.6 * rows), width_ratios=(1.1, 1, 1.7, 1), layout="constrained", squeeze=False
    )
    letters = iter(_LETTERS)
    for row, (view, pair) in enumerate(zip(fig5["views"], images, strict=True)):
        for column, (key, name, colour) in enumerate(_SENSORS):
            record = view[key]
            rows_px, columns_px = record["shape"]
            image_axes, histogram_axes = axes[row, 2 * column], axes[row, 2 * column + 1]
            _draw_image(
                image_axes,
                pair[key],
                sensors[key],
                f"({next(letters)}) {name}, {view['label']} ({rows_px} x {columns_px})",
            )
            _draw_histogram(histogram_axes, record, colour, f"({next(letters)}) {name} histogram, {view['label']}")
    figure.suptitle(
        f"Fig. 5: camera and LADAR images (LADAR: dark = near) with their 256-bin gray-level histograms and "
        f"entropies, seed {fig5['seed']}.\nRows 1-2: two similar views of vegetated, rugged terrain (LADAR more "
        f"informative); row 3: a building {fig5['building']['distance_m']:.1f} m ahead (camera more informative)."
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)
    return path
