"""The paper's Fig. 3: robot #2 loses DGPS at 21 s and relocalizes through laser observations of robot #1. The
convoy team runs twice on one seed, greedy on expected information gain and dead reckoning; odometry and DGPS
noise have their own streams, so the runs differ only by the choices."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from agents import Agent, GreedyEntropyAgent
from infonav_gym.experiments.episodes import parallel_episode_infos
from infonav_gym.multi import cooperative_localization_v0
from infonav_gym.multi.team import DEFAULT_OUTAGE
from infonav_gym.multi.team_sensing import NO_OBSERVATION
from infonav_gym.rendering import matplotlib_figure, save_figure

SEEDS_COUNT = "how many seeds the outage RMSE averages"  # what ``n_seeds`` counts, for its error
FIG3_ENV_CONFIG = {"scenario": "convoy", "n_robots": 3, "max_cycles": 120}
OBSERVER = "robot_1"  # the paper's robot #2, which loses DGPS
DGPS_LOSS_S = DEFAULT_OUTAGE[1]  # [s]
PATH_ROBOTS = ("robot_0", "robot_1")  # the paper's robots #1 and #2, drawn in Fig. 3(a)


def paper_label(agent: str) -> str:
    """The paper's name of a robot, numbered from 1: ``robot_0`` -> ``#1``."""
    return f"#{int(agent.rpartition('_')[2]) + 1}"


def position_std_m(pose_std) -> float:
    """``sqrt(std_x^2 + std_y^2)`` of a pose's ``(x, y, heading)`` standard deviations [m]."""
    return math.hypot(pose_std[0], pose_std[1])


class _DeadReckoning(Agent):
    """Never observes a teammate."""

    def act(self, observation, info: dict) -> int:
        return NO_OBSERVATION


def _run_episode(env, agent, seed: int) -> list[dict]:
    """The infos of every step, from ``reset`` to truncation, with ``agent`` acting for every robot."""
    return list(parallel_episode_infos(env, dict.fromkeys(env.possible_agents, agent), seed))


def _step_record(before: dict, after: dict) -> dict:
    """What robot #2 saw, chose and got at one step (``before``/``after``: its infos around the step)."""
    visible = np.flatnonzero(before["action_mask"][1:])
    chosen = after["chosen_action"]
    return {
        "time_s": before["time_s"],
        "gps_available": before["gps_available"],
        "pose_std": before["pose_std"].tolist(),
        "pose_std_after_update": after["pose_std_after_update"].tolist(),
        "gains_nats": {f"robot_{j}": float(before["action_information_gain"][1 + j]) for j in visible},
        "chosen": None if chosen == NO_OBSERVATION else f"robot_{chosen - 1}",
    }


def _correction_bursts(steps: list[dict]) -> list[dict]:
    """Runs of consecutive steps with a relative observation, with robot #2's position std around them [m]."""
    bursts = []
    for corrected, run in itertools.groupby(steps, key=lambda step: step["chosen"] is not None):
        run = list(run)
        if corrected:
            bursts.append(
                {
                    "start_s": run[0]["time_s"],
                    "end_s": run[-1]["time_s"],
                    "teammates": sorted({step["chosen"] for step in run}),
                    "position_std_before_m": position_std_m(run[0]["pose_std"]),
                    "position_std_after_first_m": position_std_m(run[0]["pose_std_after_update"]),
                    "position_std_after_last_m": position_std_m(run[-1]["pose_std_after_update"]),
                }
            )
    return bursts


def _position_std_extremes(steps: list[dict]) -> dict:
    """Robot #2's position std [m] at its last DGPS fix and at its peak during the outage, with their times [s]."""
    last_fix = [step for step in steps if step["gps_available"]][-1]
    peak = max(
        (step for step in steps if step["time_s"] >= DGPS_LOSS_S), key=lambda step: position_std_m(step["pose_std"])
    )
    return {
        "last_dgps_fix_s": last_fix["time_s"],
        "last_dgps_fix_m": position_std_m(last_fix["pose_std"]),
        "outage_peak_s": peak["time_s"],
        "outage_peak_m": position_std_m(peak["pose_std"]),
    }


def _paths(history: list[dict], robots) -> dict:
    return {
        robot: {
            "estimated_xy_m": [infos[robot]["estimated_pose"][:2].tolist() for infos in history],
            "true_xy_m": [infos[robot]["true_pose"][:2].tolist() for infos in history],
        }
        for robot in robots
    }


def _outage_rmse_m(history: list[dict]) -> float:
    errors = [infos[OBSERVER]["position_error_m"] for infos in history if infos[OBSERVER]["time_s"] >= DGPS_LOSS_S]
    return math.sqrt(np.mean(np.square(errors)))


def run_fig3(seed: int = 0) -> dict:
    """Fig. 3 for one seed, greedy team vs dead reckoning (JSON-ready): robot #2's ``steps`` (time, prior and updated
    ``pose_std``, DGPS, gains of visible teammates, the one ``chosen``), its corrections and their bursts, position std
    extremes, ``paths`` and ``position_error_m`` per policy, and the convoy's ``walls``."""
    env = cooperative_localization_v0.parallel_env(**FIG3_ENV_CONFIG)
    greedy = _run_episode(env, GreedyEntropyAgent(), seed)
    dead_reckoning = _run_episode(env, _DeadReckoning(), seed)
    walls = [[list(point) for point in wall] for wall in env.vector.scenario(0).walls]
    env.close()
    steps = [_step_record(before[OBSERVER], after[OBSERVER]) for before, after in itertools.pairwise(greedy)]
    return {
        "seed": seed,
        "env_config": dict(FIG3_ENV_CONFIG),
        "observer": OBSERVER,
        "dgps_loss_s": DGPS_LOSS_S,
        "steps": steps,
        "corrections": [{"time_s": step["time_s"], "teammate": step["chosen"]} for step in steps if step["chosen"]],
        "correction_bursts": _correction_bursts(steps),
        "position_std": _position_std_extremes(steps),
        "time_s": [infos[OBSERVER]["time_s"] for infos in greedy],
        "paths": {"greedy": _paths(greedy, PATH_ROBOTS), "dead_reckoning": _paths(dead_reckoning, [OBSERVER])},
        "position_error_m": {
            name: [infos[OBSERVER]["position_error_m"] for infos in history]
            for name, history in (("greedy", greedy), ("dead_reckoning", dead_reckoning))
        },
        "walls": walls,
    }


def outage_rmse(seeds=range(20), progress: bool = False) -> dict:
    """Robot #2's position RMSE over the outage (``t >= 21 s``) on each of ``seeds``, greedy team vs dead reckoning: the
    ``per_seed`` records, each policy's mean [m], their ``ratio`` and the ``mean_per_seed_ratio``."""
    seeds = list(seeds)
    if not seeds:
        raise ValueError("outage_rmse needs at least one seed, got none")
    env = cooperative_localization_v0.parallel_env(**FIG3_ENV_CONFIG)
    per_seed = []
    for seed in tqdm(seeds, desc="Fig. 3 outage RMSE", unit="seed", disable=not progress):
        greedy = _outage_rmse_m(_run_episode(env, GreedyEntropyAgent(), seed))
        dead_reckoning = _outage_rmse_m(_run_episode(env, _DeadReckoning(), seed))
        per_seed.append(
            {"seed": seed, "greedy_m": greedy, "dead_reckoning_m": dead_reckoning, "ratio": greedy / dead_reckoning}
        )
    env.close()
    mean_greedy = float(np.mean([record["greedy_m"] for record in per_seed]))
    mean_dead_reckoning = float(np.mean([record["dead_reckoning_m"] for record in per_seed]))
    return {
        "from_s": DGPS_LOSS_S,
        "seeds": seeds,
        "per_seed": per_seed,
        "mean_greedy_m": mean_greedy,
        "mean_dead_reckoning_m": mean_dead_reckoning,
        "ratio": mean_greedy / mean_dead_reckoning,
        "mean_per_seed_ratio": float(np.mean([record["ratio"] for record in per_seed])),
    }


def figures(seed: int, seeds, progress: bool) -> tuple[dict, Callable[[Path], object]]:
    """Fig. 3 of ``seed`` and the outage RMSE over ``seeds`` (JSON-ready), and the function drawing them into a PNG."""
    result = {"fig3": run_fig3(seed), "outage_rmse": outage_rmse(seeds, progress=progress)}
    return result, lambda path: save_figure(figure_fig3(result["fig3"]), path, dpi=120, bbox_inches="tight")


def table(result: dict) -> str:
    """The figures of the paper's Fig. 3 story as text: robot #2's position std and the outage RMSE."""
    fig3, rmse = result["fig3"], result["outage_rmse"]
    extremes = fig3["position_std"]
    lines = [f"Fig. 3, seed {fig3['seed']}: robot #2's position std sqrt(std_x^2 + std_y^2) [m]"]
    for what, key in (("last DGPS fix", "last_dgps_fix"), ("peak during the outage", "outage_peak")):
        label = f"{what} (t = {extremes[key + '_s']:.1f} s)"
        lines.append(f"  {label:38s}{extremes[key + '_m']:6.3f}")
    lines.append(f"  {'corrections [s]':17s}{'teammate':10s}{'before':>6s}{'after 1st':>11s}{'after last':>12s}")
    for burst in fig3["correction_bursts"]:
        span = f"{burst['start_s']:.1f}-{burst['end_s']:.1f}"
        teammates = ", ".join(paper_label(name) for name in burst["teammates"])
        lines.append(
            f"  {span:17s}{teammates:10s}{burst['position_std_before_m']:6.3f}"
            f"{burst['position_std_after_first_m']:11.3f}{burst['position_std_after_last_m']:12.3f}"
        )
    seeds = rmse["seeds"]
    lines += [
        f"Robot #2's position RMSE over the outage (t >= {rmse['from_s']:g} s), seeds {seeds[0]}..{seeds[-1]}:",
        f"  team greedy      {rmse['mean_greedy_m']:.3f} m",
        f"  dead reckoning   {rmse['mean_dead_reckoning_m']:.3f} m",
        f"  ratio            {rmse['ratio']:.3f}",
    ]
    return "\n".join(lines)


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
    axes.set(aspect="equal", xlabel="x [m]", ylabel="y [m]", title="(a) EKF estimated paths (hedges in grey)")
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
    axes.set(xlim=(0, steps[-1]["time_s"] + 0.5), xlabel="time [s]", ylabel="position std [m]")
    heading_axes.set_ylabel("heading std [rad]")
    axes.set_title("(b) robot #2's pose standard deviations; arrows: relative corrections (observed teammate)")


def figure_fig3(fig3: dict):
    """``run_fig3``'s result drawn like the paper's Fig. 3."""
    figure = matplotlib_figure("the Fig. 3 plot", figsize=(10, 7.5), layout="constrained")
    paths_axes, std_axes = figure.subplots(2, 1, height_ratios=(1, 1.4))
    _draw_paths(paths_axes, fig3)
    _draw_standard_deviations(std_axes, fig3)
    figure.suptitle(f"Fig. 3: laser-based cooperative localization on the convoy, seed {fig3['seed']}")
    return figure
