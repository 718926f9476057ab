"""The paper's Fig. 3: robot #2 loses DGPS at 21 s and relocalizes through laser observations of robot #1.

The convoy team (``infonav_gym.multi.team.CONVOY_SUITES``) is run twice with the
same seed: every robot greedy on the expected information gain, and dead
reckoning (no relative observations). Odometry and DGPS noise come from their own
random streams, so both runs see the same noise and differ only by the choices.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from agents import GreedyEntropyAgent
from infonav_gym.experiments.reproduce import figure_paths, files_line, paper_label, write_result
from infonav_gym.experiments.reproduce.fig3_plot import plot_fig3
from infonav_gym.multi import cooperative_localization_v0
from infonav_gym.multi.team import DEFAULT_OUTAGE
from infonav_gym.multi.team_sensing import NO_OBSERVATION

FIG3_ENV_CONFIG = {"scenario": "convoy", "n_robots": 3, "max_cycles": 120}
OBSERVER = "robot_1"  # the paper's robot #2, which loses DGPS
DGPS_LOSS_S = DEFAULT_OUTAGE[1]  # [s]
PATH_ROBOTS = ("robot_0", "robot_1")  # the paper's robots #1 and #2, drawn in Fig. 3(a)


def position_std_m(pose_std) -> float:
    """``sqrt(std_x^2 + std_y^2)`` of a pose's ``(x, y, heading)`` standard deviations [m]."""
    return math.hypot(pose_std[0], pose_std[1])


def _greedy_team(observations: dict, infos: dict) -> dict:
    agent = GreedyEntropyAgent()
    return {name: agent.act(observations[name], infos[name]) for name in infos}


def _dead_reckoning(observations: dict, infos: dict) -> dict:
    return dict.fromkeys(infos, NO_OBSERVATION)


def _run_episode(env, policy, seed: int) -> list[dict]:
    """The infos of every step, from ``reset`` to truncation, with ``policy`` choosing every robot's action."""
    observations, infos = env.reset(seed=seed)
    history = [infos]
    while env.agents:
        observations, _, _, _, infos = env.step(policy(observations, infos))
        history.append(infos)
    return history


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
    """Fig. 3 for one seed: robot #2's steps, the corrections and the paths, greedy team vs dead reckoning.

    Returns:
        A JSON-ready dict: ``steps`` (robot #2's per-step ``time_s``, prior ``pose_std``,
        ``pose_std_after_update``, ``gps_available``, ``gains_nats`` of the visible
        teammates and the ``chosen`` one or None), ``corrections``, ``correction_bursts``,
        ``position_std`` (at the last DGPS fix and the outage peak), ``paths`` and
        ``position_error_m`` per policy, and the convoy's ``walls``.
    """
    env = cooperative_localization_v0.parallel_env(**FIG3_ENV_CONFIG)
    greedy = _run_episode(env, _greedy_team, seed)
    dead_reckoning = _run_episode(env, _dead_reckoning, seed)
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
    """Robot #2's position RMSE over the outage (``t >= 21 s`` to the end), greedy team vs dead reckoning.

    Args:
        seeds: the episode seeds; both policies run each one.
        progress: show a tqdm bar over the seeds.

    Returns:
        ``per_seed`` records, the mean RMSE of each policy [m], ``ratio`` (mean greedy
        over mean dead reckoning) and ``mean_per_seed_ratio``.
    """
    seeds = list(seeds)
    if not seeds:
        raise ValueError("outage_rmse needs at least one seed, got none")
    env = cooperative_localization_v0.parallel_env(**FIG3_ENV_CONFIG)
    per_seed = []
    for seed in tqdm(seeds, desc="Fig. 3 outage RMSE", unit="seed", disable=not progress):
        greedy = _outage_rmse_m(_run_episode(env, _greedy_team, seed))
        dead_reckoning = _outage_rmse_m(_run_episode(env, _dead_reckoning, seed))
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


def reproduce_fig3(
    output_dir: Path, seed: int = 0, n_seeds: int = 20, progress: bool = False, command: str = ""
) -> dict:
    """Run Fig. 3, write ``output_dir/fig3.png`` and ``output_dir/fig3.json``; return what the JSON holds.

    Args:
        output_dir: directory for the two files (created if missing).
        seed: the seed of the plotted run, and the first of the RMSE seeds.
        n_seeds: how many seeds (``seed .. seed + n_seeds - 1``) the outage RMSE averages.
        progress: show a tqdm bar over the RMSE seeds.
        command: the command line that made the files, recorded in the JSON.
    """
    png, json_path = figure_paths(output_dir, "fig3", n_seeds, "how many seeds the outage RMSE averages")
    result = {
        "command": command,
        "fig3": run_fig3(seed),
        "outage_rmse": outage_rmse(range(seed, seed + n_seeds), progress=progress),
    }
    return write_result(result, png, json_path, lambda path: plot_fig3(result["fig3"], path))


def fig3_table(result: dict) -> str:
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
        files_line(result),
    ]
    return "\n".join(lines)
