"""``results/throughput.png``: env-steps per second against the number of sub-envs N, from the benchmark's figures."""

from __future__ import annotations

import re
from pathlib import Path

from infonav_gym.rendering import matplotlib_figure

CURVE_FIGURE = re.compile(
    r"^(?P<curve>.+)_(?P<size>\d+)_steps_per_s$"
)  # e.g. landmark_selection_vector_256_steps_per_s
SINGLE_CARTPOLE_FIGURE = "cartpole_steps_per_s"


def throughput_curves(figures: dict) -> dict[str, dict[int, float]]:
    """``{curve: {N: env-steps/s}}`` of every ``CURVE_N_steps_per_s`` figure (vector envs, CartPoleVectorEnv, VMAS)."""
    curves: dict[str, dict[int, float]] = {}
    for name, value in figures.items():
        match = CURVE_FIGURE.match(name)
        if match:
            curves.setdefault(match["curve"], {})[int(match["size"])] = value
    return curves


def plot_throughput(figures: dict, path: Path | str) -> Path:
    """Draw ``throughput_curves(figures)`` log-log, CartPole-v1's single-env rate as a horizontal line; write PNG.

    Raises:
        ValueError: when ``figures`` hold no ``CURVE_N_steps_per_s`` figure.
        ImportError: without matplotlib (the ``render`` extra).
    """
    curves = throughput_curves(figures)
    if not curves:
        raise ValueError(f"the throughput plot needs figures named CURVE_N_steps_per_s, got {sorted(figures)}")
    figure = matplotlib_figure("the throughput plot", figsize=(7.5, 4.8))
    axes = figure.add_subplot()
    for curve, rates in curves.items():
        sizes = sorted(rates)
        axes.loglog(sizes, [rates[size] for size in sizes], marker="o", label=curve)
    if SINGLE_CARTPOLE_FIGURE in figures:
        axes.axhline(figures[SINGLE_CARTPOLE_FIGURE], color="black", linestyle="--", label="CartPole-v1 (single env)")
    axes.set_xlabel("sub-envs per vector env, N")
    axes.set_ylabel("env-steps per second")
    axes.set_title("Throughput, one process (infonav benchmark)")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize="small")
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=120)
    return path
