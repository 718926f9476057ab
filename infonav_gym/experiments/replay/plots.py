"""Figures of a calibration (residual histograms with the fitted densities) and of a replay (NEES over time)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import stats

from infonav_gym.datasets.noise_model import NoiseModel
from infonav_gym.estimation.consistency import chi2_bounds
from infonav_gym.rendering import matplotlib_figure, save_figure


def plot_calibration(model: NoiseModel, errors: dict, path) -> Path:
    """Write ``figure_calibration(model, errors)`` to ``path``."""
    return save_figure(figure_calibration(model, errors), path, dpi=110)


def figure_calibration(model: NoiseModel, errors: dict):
    """Histograms of the range and bearing errors left after the systematic part, pooled over the robots, with the
    fitted Gaussian model (white plus bias, at each error's range) and the Student-t fit; log scale. ``errors``: robot
    subject -> ``calibration.landmark_errors`` arrays at the fitted clock offsets."""
    figure = matplotlib_figure("the calibration plot", figsize=(11, 4.4), layout="constrained")
    axes = figure.subplots(1, 2)
    channels = {"range": ("range error [m]", 0.6), "bearing": ("bearing error [rad]", 0.08)}
    for axis, (channel, (label, limit)) in zip(axes, channels.items()):
        residuals, stds = [], []
        for robot, rows in errors.items():
            noise = model.for_robot(robot)
            if channel == "range":
                residuals.append(rows["range_error"] - noise.range_bias(rows["range"], rows["bearing"]))
                stds.append(np.hypot(noise.range_white_std(rows["range"]), noise.range_bias_std_m))
            else:
                residuals.append(rows["bearing_error"] - noise.bearing_bias(rows["bearing"]))
                std = np.hypot(noise.bearing_white_std_rad, noise.bearing_bias_std_rad)  # the same at every range
                stds.append(np.full(len(rows["bearing"]), std))
        residual, std = np.concatenate(residuals), np.concatenate(stds)
        grid = np.linspace(-limit, limit, 401)
        axis.hist(residual, bins=np.linspace(-limit, limit, 121), density=True, alpha=0.5, label="errors (all robots)")
        gaussian = np.mean(stats.norm.pdf(grid[:, None], scale=std[None, :]), axis=1)
        axis.plot(grid, gaussian, label="model: white + target bias (Gaussian)")
        student = model.diagnostics.get("pooled", {}).get(channel, {})
        if student:
            scale = student["student_t_scale"] * float(np.median(std))
            axis.plot(grid, stats.t.pdf(grid, student["student_t_dof"], scale=scale), "--", label="Student-t fit")
        axis.set_yscale("log")
        axis.set_ylim(1e-3 / limit, None)
        axis.set_xlabel(label)
        axis.set_ylabel(f"density [1/{label.split('[')[1]}")
        axis.set_title(f"{channel}: systematic part removed")
        axis.legend(fontsize=8, loc="upper left")
    return figure


def figure_nees_over_time(result: dict, title: str = ""):
    """Each robot's NEES over time in an all-landmark replay ``result`` (its robots hold ``nees_over_time``), with the
    two-sided 95 % chi-square(3) band."""
    robots = {robot: metrics for robot, metrics in result["robots"].items() if "nees_over_time" in metrics}
    figure = matplotlib_figure("the NEES plot", figsize=(10, 1.6 * len(robots) + 1.0), layout="constrained")
    axes = figure.subplots(len(robots), 1, sharex=True, squeeze=False)
    low, high = chi2_bounds(3)
    for axis, (robot, metrics) in zip(axes[:, 0], robots.items()):
        series = metrics["nees_over_time"]
        axis.semilogy(series["time_s"], np.maximum(series["nees"], 1e-3), lw=0.7)
        axis.axhspan(low, high, color="green", alpha=0.15)
        axis.set_ylabel(f"robot {robot}\nNEES [-]")
        summary = f"mean {metrics['mean_nees']:.2f}, inside 95 %: {100 * metrics['nees_fraction_inside_95']:.0f} %"
        axis.text(0.01, 0.85, summary, transform=axis.transAxes, fontsize=8)
    axes[-1, 0].set_xlabel("replay time [s]")
    figure.suptitle(title or "NEES over time (band: two-sided 95 % chi-square, 3 dof)", fontsize=10)
    return figure
