"""Sweeps of replays over policies, the outage experiment, and their tables."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from tqdm.auto import tqdm

from infonav_gym.experiments.paths import output_file
from infonav_gym.experiments.replay.comparison import comparison_markdown
from infonav_gym.experiments.replay.metrics import mean_and_ci95
from infonav_gym.experiments.replay.plots import figure_nees_over_time
from infonav_gym.experiments.replay.run import POLICIES, SUMMARY_KEYS, ReplayConfig, replay
from infonav_gym.experiments.replay.tables import table_lines
from infonav_gym.rendering import save_figure

ROW_KEYS = tuple(key for key in SUMMARY_KEYS if not key.startswith("dead_reckoning"))  # dead reckoning: its own row


def check_experiments(policies, n_seeds: int) -> None:
    """Raise ``ValueError`` unless the policies are known and ``n_seeds >= 1``; ``run_experiments`` calls it, a caller
    may too before loading a dataset."""
    unknown = [name for name in policies if name not in POLICIES]
    if unknown:
        raise ValueError(f"unknown policy {unknown!r}: expected one of {', '.join(POLICIES)}")
    if n_seeds < 1:
        raise ValueError(f"need seeds >= 1, got {n_seeds}")


def run_experiments(
    dataset_dir,
    policies=("all",),
    n_seeds: int = 1,
    seed: int = 0,
    outage: tuple[int, float, float] | None = None,
    config: ReplayConfig | None = None,
    progress: bool = False,
) -> dict:
    """Replay every policy, plus dead reckoning and an optional outage.

    Args:
        dataset_dir: an MRCLAM dataset directory.
        policies: names from ``POLICIES``.
        n_seeds, seed: runs of ``random`` (and of each policy's starting draw), seeds ``seed .. seed + n_seeds - 1``
            for ``random``, ``seed`` for the others (mean and 95 % CI over the runs).
        outage: ``(robot, start_s, end_s)``: also run the outage experiment, a cooperative replay fusing every reading
            in which ``robot`` gets no landmark readings over the span, against dead reckoning through it.
        config: noise, cooperative and duration settings shared by every run.
        progress: show a tqdm bar.

    Returns:
        A JSON-ready dict with ``rows`` (one per policy), ``dead_reckoning``, ``runs`` and ``outage``.
    """
    check_experiments(policies, n_seeds)
    base = config or ReplayConfig()
    plan = [(policy, list(range(seed, seed + n_seeds)) if policy == "random" else [seed]) for policy in policies]
    n_runs = sum(len(seeds) for _, seeds in plan) + (1 if outage else 0)
    bar = tqdm(total=n_runs, desc="replays", unit="run", disable=not progress)
    rows, runs = [], []
    for policy, seeds in plan:
        results = []
        for run_seed in seeds:
            results.append(replay(dataset_dir, dataclasses.replace(base, seed=run_seed, policy=policy)))
            bar.update()
        runs.extend(results)
        rows.append(_row(policy, results))
    summary = {
        "dataset": str(dataset_dir),
        "config": base.as_dict(),
        "rows": rows,
        "dead_reckoning": _dead_reckoning(runs[0]) if runs else None,
        "runs": runs,
    }
    if outage:
        robot, start_s, end_s = outage
        outage_config = dataclasses.replace(
            base, policy="all", cooperative=True, outage_robot=robot, outage_start_s=start_s, outage_end_s=end_s
        )
        outage_run = replay(dataset_dir, outage_config)
        bar.update()
        summary["outage"] = outage_run["outage"] | {"cooperative_run": outage_run}
    bar.close()
    return summary


def _row(policy, results) -> dict:
    row = {"policy": policy, "n_runs": len(results)}
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
    "NEES inside 95%: the share of steps inside the two-sided 95% chi-square interval (3 dof); a consistent filter "
    "has mean NEES 3 and about 95% inside."
)


def _cell(value, digits=3) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, dict):
        text = f"{value['mean']:.{digits}f}"
        return text + (f" ± {value['ci95']:.{digits}f}" if value["n"] > 1 else "")
    return f"{value:.{digits}f}"


def markdown_table(summary: dict) -> str:
    """The sweep as Markdown: one row per policy, dead reckoning, per-robot RMSE, the outage."""
    header = ["policy", "runs", "position RMSE [m]", "heading RMSE [rad]", "mean NEES", "NEES inside 95%"]
    header += ["updates used", "updates gated", "mean pose entropy [nats]"]
    digits = {"mean_nees": 2, "updates_used": 0, "updates_gated": 0}  # the others: 3
    rows = [
        [row["policy"], str(row["n_runs"])] + [_cell(row[key], digits.get(key, 3)) for key in ROW_KEYS]
        for row in summary["rows"]
    ]
    dead_reckoning = summary.get("dead_reckoning")
    if dead_reckoning:
        errors = [_cell(dead_reckoning["position_rmse_m"]), _cell(dead_reckoning["heading_rmse_rad"])]
        rows.append(["dead reckoning", "1", *errors, "n/a", "n/a", "0", "0", "n/a"])
    lines = table_lines(header, rows) + ["", INTERVAL_NOTE, "", NEES_NOTE]
    if dead_reckoning:
        robots = list(dead_reckoning["position_rmse_m_per_robot"])
        lines += ["", "Position RMSE per robot [m]:", ""]
        per_robot = [
            [row["policy"], *(_cell(row["position_rmse_m_per_robot"][robot]) for robot in robots)]
            for row in [*summary["rows"], {"policy": "dead reckoning"} | dead_reckoning]
        ]
        lines += table_lines(["policy", *(f"robot {robot}" for robot in robots)], per_robot)
    outage = summary.get("outage")
    if outage:
        lines += [
            "",
            f"Outage: robot {outage['robot']} without landmark readings from {outage['start_s']:g} s to "
            f"{outage['end_s']:g} s of the log, in the cooperative replay (every landmark and teammate reading); its "
            "position RMSE over the span [m]:",
            "",
            "| cooperative (teammates' readings) | dead reckoning from the outage's start | ratio |",
            "| --- | --- | --- |",
            f"| {_cell(outage['position_rmse_m'])} | {_cell(outage['dead_reckoning_from_start_position_rmse_m'])} "
            f"| {_cell(outage['ratio'])} |",
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
