"""Fig. 3 as a picture: (a) estimated paths of robots #1 and #2, (b) robot #2's pose standard deviations."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from infonav_gym.experiments.reproduce import paper_label
from infonav_gym.rendering import require_extra

_PATH_STYLES = {"robot_0": (":", "tab:blue"), "robot_1": ("-", "tab:red")}  # the paper: #1 dotted, #2 solid
_STD_CURVES = (
    ("x std [m]", "tab:blue", "-"),
    ("y std [m]", "tab:orange", "-"),
    ("heading std [rad]", "tab:green", "--"),
)
_HEADROOM = 1.45  # position-std axis top, as a multiple of the highest x or y std: room for the arrow labels


def _sawtooth(steps: list[dict], component: int) -> tuple[np.ndarray, np.ndarray]:
    """Times and values that draw each step's prior std, then its drop to the after-update std."""
    times = np.repeat([step["time_s"] for step in steps], 2)
    values = np.array([[step["pose_std"][component], step["pose_std_after_update"][component]] for step in steps])
    return times, values.ravel()


def _draw_paths(axes, fig3: dict) -> None:
    """Panel (a): the hedges, the estimated paths with their S/E marks, and where robot #2 loses DGPS."""
    for (x0, y0), (x1, y1) in fig3["walls"]:
        axes.plot([x0, x1], [y0, y1], color="0.8", linewidth=2, solid_capstyle="butt")
    for robot, path in fig3["paths"]["greedy"].items():
        linestyle, colour = _PATH_STYLES[robot]
        number = paper_label(robot)[1:]
        xy = np.array(path["estimated_xy_m"])
        axes.plot(*xy.T, linestyle=linestyle, color=colour, linewidth=2, label=f"robot #{number}")
        for point, mark, text in ((xy[0], "o", f"S{number}"), (xy[-1], "s", f"E{number}")):
            axes.plot(*point, marker=mark, color=colour)
            axes.annotate(text, point, xytext=(0, 7), textcoords="offset points", ha="center", color=colour)
    observer = fig3["observer"]
    loss_xy = fig3["paths"]["greedy"][observer]["estimated_xy_m"][fig3["time_s"].index(fig3["dgps_loss_s"])]
    axes.plot(*loss_xy, "kx", markersize=8, label=f"{paper_label(observer)} loses DGPS")
    axes.set_aspect("equal")
    axes.set_xlabel("x [m]")
    axes.set_ylabel("y [m]")
    axes.set_title("(a) EKF estimated paths (hedges in grey)")
    axes.legend(loc="lower right", fontsize="small")


def _mark_events(axes, fig3: dict, label_y: float) -> None:
    """The DGPS loss as a vertical line, and an arrow naming the observed teammate at each correction burst."""
    loss_s = fig3["dgps_loss_s"]
    axes.axvline(loss_s, color="black", linestyle=":", linewidth=1)
    axes.annotate(
        f"DGPS lost at {loss_s:g} s",
        (loss_s, label_y),
        xytext=(-3, 0),
        textcoords="offset points",
        rotation=90,
        ha="right",
        va="top",
    )
    prior_by_time = {step["time_s"]: max(step["pose_std"][:2]) for step in fig3["steps"]}
    for burst in fig3["correction_bursts"]:
        teammates = ", ".join(paper_label(name) for name in burst["teammates"])
        tip = (burst["start_s"], prior_by_time[burst["start_s"]])
        axes.annotate(teammates, tip, xytext=(burst["start_s"], label_y), ha="center", arrowprops={"arrowstyle": "->"})


def _draw_standard_deviations(axes, fig3: dict) -> None:
    """Panel (b): robot #2's x, y (left axis) and heading (right axis) std as sawtooths, with the events."""
    steps = fig3["steps"]
    heading_axes = axes.twinx()
    for component, (label, colour, linestyle) in enumerate(_STD_CURVES):
        target = heading_axes if component == 2 else axes
        target.plot(*_sawtooth(steps, component), color=colour, linestyle=linestyle, label=label)
    top = max(max(step["pose_std"][:2]) for step in steps)
    axes.set_ylim(0, _HEADROOM * top)
    heading_axes.set_ylim(0, 1.6 * max(step["pose_std"][2] for step in steps))
    _mark_events(axes, fig3, label_y=0.9 * _HEADROOM * top)
    lines = axes.get_lines()[:2] + heading_axes.get_lines()
    axes.legend(lines, [line.get_label() for line in lines], loc="upper left", fontsize="small")
    axes.set_xlim(0, steps[-1]["time_s"] + 0.5)
    axes.set_xlabel("time [s]")
    axes.set_ylabel("position std [m]")
    heading_axes.set_ylabel("heading std [rad]")
    axes.set_title("(b) robot #2's pose standard deviations; arrows: relative corrections (observed teammate)")


def plot_fig3(fig3: dict, path: Path) -> Path:
    """Draw ``run_fig3``'s result like the paper's Fig. 3 and save it as a PNG at ``path``."""
    require_extra("matplotlib", "the Fig. 3 plot")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (paths_axes, std_axes) = plt.subplots(2, 1, figsize=(10, 7.5), height_ratios=(1, 1.4), layout="constrained")
    _draw_paths(paths_axes, fig3)
    _draw_standard_deviations(std_axes, fig3)
    figure.suptitle(f"Fig. 3: laser-based cooperative localization on the convoy, seed {fig3['seed']}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(figure)
    return path
