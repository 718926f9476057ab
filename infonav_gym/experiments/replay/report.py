"""Sweeps of replays over policies and budgets, the outage experiment, and their tables."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from tqdm.auto import tqdm

from infonav_gym.datasets.mrclam import MRCLAMDataset
from infonav_gym.datasets.noise_model import corrected_logs
from infonav_gym.datasets.timeline import make_timeline
from infonav_gym.experiments.paths import output_file
from infonav_gym.experiments.replay.comparison import comparison_markdown
from infonav_gym.experiments.replay.filters import ReplayConfig
from infonav_gym.experiments.replay.metrics import mean_and_ci95
from infonav_gym.experiments.replay.plots import figure_nees_over_time
from infonav_gym.experiments.replay.policies import POLICIES
from infonav_gym.experiments.replay.run import SUMMARY_KEYS, replay, replay_header
from infonav_gym.experiments.replay.tables import budget_cells, table_lines
from infonav_gym.rendering import save_figure

# a sweep row's metrics: a replay's, but for dead reckoning's (a row of its own) and these
ROW_LEFT_OUT = ("relative_updates_used", "updates_gated")
ROW_KEYS = tuple(key for key in SUMMARY_KEYS if not key.startswith("dead_reckoning") and key not in ROW_LEFT_OUT)


def check_experiments(policies, ks, windows_s, n_seeds: int) -> None:
    """Raise ``ValueError`` unless the policies are known and the budgets (``k >= 1``, ``window_s > 0``) and
    ``n_seeds >= 1`` make sense; ``run_experiments`` calls it, a caller may too before loading a dataset."""
    unknown = [name for name in policies if name not in POLICIES]
    if unknown:
        raise ValueError(f"unknown policy {unknown!r}: expected one of {', '.join(POLICIES)}")
    if not ks or not windows_s or min(ks) < 1 or not min(windows_s) > 0 or n_seeds < 1:
        raise ValueError(f"need k >= 1, window-s > 0 and seeds >= 1, got {list(ks)}, {list(windows_s)}, {n_seeds}")


def run_experiments(
    dataset: MRCLAMDataset,
    policies=("all",),
    ks=(1,),
    windows_s=(1.0,),
    n_seeds: int = 1,
    seed: int = 0,
    outage: tuple[int, float, float] | None = None,
    config: ReplayConfig | None = None,
    dt: float = 0.02,
    duration_s: float | None = None,
    progress: bool = False,
) -> dict:
    """Replay every policy (budgeted ones at every ``(k, window)``), plus dead reckoning and an optional outage.

    Args:
        dataset: a loaded MRCLAM dataset.
        policies: names from ``POLICIES``; ``all`` runs once, the others once per ``(k, window)``.
        ks, windows_s: budgets: ``k`` observations per robot per window of ``window_s`` seconds.
        n_seeds, seed: runs of ``random`` per budget, seeds ``seed .. seed + n_seeds - 1`` (mean and 95 % CI).
        outage: ``(robot, start_s, end_s)``: also run the outage experiment, a cooperative replay (the joint filter,
            every landmark and robot-to-robot observation) in which ``robot`` gets no landmark observations over the
            span, against the landmark-only replay in which it dead-reckons.
        config: filter settings (noise, gate, cooperative) shared by every run.
        dt, duration_s: replay tick [s]; replay only this long [s].
        progress: show tqdm bars.

    Returns:
        A JSON-ready dict with ``rows`` (one per policy and budget), ``dead_reckoning``, ``runs`` and ``outage``.
    """
    check_experiments(policies, ks, windows_s, n_seeds)
    if outage and outage[0] not in dataset.robots:
        raise ValueError(f"outage robot {outage[0]} is not one of the robots {list(dataset.robots)}")
    base = config or ReplayConfig()
    timeline = make_timeline(corrected_logs(dataset, base.noise), dt=dt, duration_s=duration_s)
    plan = []
    for policy in policies:
        seeds = list(range(seed, seed + n_seeds)) if policy == "random" else [seed]
        budgets = [(None, None)] if policy == "all" else [(k, window) for k in ks for window in windows_s]
        plan.extend((policy, k, window, seeds) for k, window in budgets)
    n_runs = sum(len(seeds) for *_, seeds in plan) + (1 if outage else 0)
    bar = tqdm(total=n_runs, desc="replays", unit="run", disable=not progress or n_runs == 1)
    rows, runs = [], []
    for policy, k, window, seeds in plan:
        settings = {"policy": policy} | ({"k": k, "window_s": window} if k is not None else {})
        results = []
        for run_seed in seeds:
            run_config = dataclasses.replace(base, seed=run_seed, **settings)
            results.append(replay(dataset, run_config, timeline=timeline, progress=progress and n_runs == 1))
            bar.update()
        runs.extend(results)
        rows.append(_row(policy, k, window, results))
    summary = {
        **replay_header(dataset, timeline, base),
        "missing": list(dataset.missing),
        "rows": rows,
        "dead_reckoning": _dead_reckoning(runs[0]) if runs else None,
        "runs": runs,
    }
    if outage:
        robot, start_s, end_s = outage
        outage_config = dataclasses.replace(
            base, policy="all", cooperative=True, outage_robot=robot, outage_start_s=start_s, outage_end_s=end_s
        )
        outage_run = replay(dataset, outage_config, timeline=timeline, progress=progress and n_runs == 1)
        bar.update()
        summary["outage"] = outage_run["outage"] | {"cooperative_run": outage_run}
    bar.close()
    return summary


def _row(policy, k, window, results) -> dict:
    row = {"policy": policy, "k": k, "window_s": window, "n_runs": len(results)}
    for key in ROW_KEYS:
        values = [result["mean"][key] for result in results]
        row[key] = None if any(value is None for value in values) else mean_and_ci95(values)
    row["position_rmse_m_per_robot"] = {
        robot: _mean([result["robots"][robot]["position_rmse_m"] for result in results])
        for robot in results[0]["robots"]
    }
    return row


def _mean(values):
    return None if any(value is None for value in values) else sum(values) / len(values)


def _dead_reckoning(result) -> dict:
    return {
        "position_rmse_m": result["mean"]["dead_reckoning_position_rmse_m"],
        "heading_rmse_rad": result["mean"]["dead_reckoning_heading_rmse_rad"],
        "position_rmse_m_per_robot": {
            robot: metrics["dead_reckoning_position_rmse_m"] for robot, metrics in result["robots"].items()
        },
    }


INTERVAL_NOTE = (
    "Cells of several runs: mean ± half-width of its 95% confidence interval (Student t) over the runs "
    "(random: one run per seed); a single run has no interval."
)


NEES_NOTE = (
    "NEES / NIS inside 95%: the share of time steps (NEES, 3 dof) or accepted updates (NIS, 2 dof) inside the "
    "two-sided 95% chi-square interval; a consistent filter has mean NEES 3, mean NIS 2 and about 95% inside."
)


def _cell(value, digits=3) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, dict):
        text = f"{value['mean']:.{digits}f}"
        return text + (f" ± {value['ci95']:.{digits}f}" if value["n"] > 1 else "")
    return f"{value:.{digits}f}"


def markdown_table(summary: dict) -> str:
    """The sweep as Markdown: one row per policy and budget, dead reckoning, per-robot RMSE, the outage."""
    lines = []
    if not summary["has_groundtruth"]:
        lines.append("Ground truth is missing for some robots: their RMSE and NEES are n/a; see the NIS columns.\n")
    header = ["policy", "k", "window [s]", "runs", "position RMSE [m]", "heading RMSE [rad]", "mean NEES"]
    header += ["NEES inside 95%", "updates used", "mean posterior entropy [nats]", "mean NIS", "NIS inside 95%"]
    digits = {"mean_nees": 2, "updates_used": 0}  # the others: 3
    rows = [
        [row["policy"], *budget_cells(row), str(row["n_runs"])]
        + [_cell(row[key], digits.get(key, 3)) for key in ROW_KEYS]
        for row in summary["rows"]
    ]
    dead_reckoning = summary.get("dead_reckoning")
    if dead_reckoning:
        errors = [_cell(dead_reckoning["position_rmse_m"]), _cell(dead_reckoning["heading_rmse_rad"])]
        rows.append(["dead reckoning", "-", "-", "1", *errors, "n/a", "n/a", "0", "n/a", "n/a", "n/a"])
    lines += table_lines(header, rows)
    lines += ["", INTERVAL_NOTE, "", NEES_NOTE]
    if dead_reckoning:
        robots = list(dead_reckoning["position_rmse_m_per_robot"])
        lines += ["", "Position RMSE per robot [m]:", ""]
        per_robot = [
            [row["policy"], *budget_cells(row), *(_cell(row["position_rmse_m_per_robot"][robot]) for robot in robots)]
            for row in [*summary["rows"], {"policy": "dead reckoning", "k": None} | dead_reckoning]
        ]
        lines += table_lines(["policy", "k", "window [s]", *(f"robot {robot}" for robot in robots)], per_robot)
    outage = summary.get("outage")
    if outage:
        lines += [
            "",
            f"Outage: robot {outage['robot']} without landmark observations from {outage['start_s']:g} s "
            f"to {outage['end_s']:g} s; its position RMSE over the span [m]:",
            "",
            "| cooperative (relative observations) | landmark-only (dead-reckons through the outage) "
            "| dead reckoning from the start | ratio cooperative / landmark-only |",
            "| --- | --- | --- | --- |",
            f"| {_cell(outage['position_rmse_m'])} | {_cell(outage['without_relative_position_rmse_m'])} "
            f"| {_cell(outage['dead_reckoning_from_start_position_rmse_m'])} | {_cell(outage['ratio'])} |",
        ]
    return "\n".join(lines)


def write_results(summary: dict, output: Path, command: str) -> list[Path]:
    """Write ``OUTPUT.md`` (table and command), ``OUTPUT.json`` (everything but the per-run detail) and, with an
    all-landmark run, ``OUTPUT_nees.png`` (its NEES over time)."""
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    markdown = output_file(output, ".md")
    comparison = summary.get("comparison")
    markdown.write_text(
        f"# MRCLAM replay: {Path(summary['dataset']).name}\n\nCommand:\n\n```\n{command}\n```\n\n"
        f"Noise model: {summary['config']['noise']}\n\n"
        + markdown_table(summary)
        + ("\n\n## Before and after calibration\n\n" + comparison_markdown(comparison) if comparison else "")
        + "\n"
    )
    compact = {key: value for key, value in summary.items() if key != "runs"} | {"command": command}
    if "outage" in compact:
        compact["outage"] = {key: value for key, value in compact["outage"].items() if key != "cooperative_run"}
        compact["outage"]["cooperative_mean"] = summary["outage"]["cooperative_run"]["mean"]
    path_json = output_file(output, ".json")
    path_json.write_text(json.dumps(compact, indent=1) + "\n")
    written = [markdown, path_json]
    all_landmarks = [run for run in summary["runs"] if run["config"]["policy"] == "all"]
    if all_landmarks and any("nees_over_time" in metrics for metrics in all_landmarks[0]["robots"].values()):
        title = f"{Path(summary['dataset']).name}, all landmarks, noise: {summary['config']['noise']}"
        figure = figure_nees_over_time(all_landmarks[0], title)
        written.append(save_figure(figure, output_file(output, "_nees.png"), dpi=110))
    return written
