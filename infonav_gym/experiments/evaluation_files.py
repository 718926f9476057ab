"""What ``infonav evaluate`` prints and writes: its heading, config line, Markdown table, plot and files."""

from __future__ import annotations

import csv
import json
import textwrap
from pathlib import Path

import numpy as np

from infonav_gym.experiments.episodes import PPO_PREFIX
from infonav_gym.experiments.intervals import INTERVAL_NOTES, WILSON, error_bar, interval_cell
from infonav_gym.experiments.paths import output_file
from infonav_gym.rendering import matplotlib_figure, save_figure

TICK_CHARACTERS = 16  # an agent's name on the plot's axis is wrapped to lines this long
TICK_CHARACTER_IN = 0.075  # the width of a character of a tick label (8 pt) [in], with room to spare
PANELS_PER_ROW = 3  # the plot's metric panels per row


def heading(results: dict) -> str:
    """``env, N episodes per agent, seeds a..b``, and the config keys that decide the reward (env traits)."""
    seeds, episodes = results["seeds"], f"{results['episodes']} episodes per agent"
    if results.get("interrupted"):
        episodes = f"interrupted after {len(seeds)} of {episodes}"
    text = f"{results['env_id']}, {episodes}, seeds {seeds[0]}..{seeds[-1]}"
    reward_keys = results.get("reward_config_keys", [])
    defaults = results["env_config"]
    choices = [f"{key}={defaults[key]!r}{'' if key in results['env_kwargs'] else ' (default)'}" for key in reward_keys]
    return text + (f"; reward set by {', '.join(choices)}" if choices else "")


def config_line(results: dict) -> str:
    """The env config the evaluation ran, defaults included, as ``key=value`` pairs."""
    return "env config: " + ", ".join(f"{key}={value!r}" for key, value in results["env_config"].items())


def markdown_table(results: dict) -> str:
    """The summary as a Markdown table (a cell per agent and metric) and a sentence per kind of interval in it."""
    metrics = results["metrics"]
    header = "| agent | " + " | ".join(metrics.values()) + " |"
    lines = [header, "|" + " --- |" * (len(metrics) + 1)]
    for name, result in results["agents"].items():
        lines.append(f"| {name} | " + " | ".join(interval_cell(result["summary"][key]) for key in metrics) + " |")
    kinds = {s["interval"] for result in results["agents"].values() for s in result["summary"].values()}
    note = "; ".join(note for kind, note in INTERVAL_NOTES.items() if kind in kinds)
    return "\n".join(lines) + f"\n\nEach cell: {note}."


def _plot_label(name: str) -> str:
    """``ppo:runs/x/model.zip`` -> ``ppo:x/model.zip``, in lines of ``TICK_CHARACTERS``: short enough for an axis."""
    if name.startswith(PPO_PREFIX):
        name = PPO_PREFIX + "/".join(Path(name[len(PPO_PREFIX) :]).parts[-2:])
    return "\n".join(textwrap.wrap(name, TICK_CHARACTERS))


def plot_results(results: dict, path: Path) -> Path:
    """Write ``figure_results(results)`` to ``path``."""
    return save_figure(figure_results(results), path, dpi=110)


def figure_results(results: dict):
    """One panel per metric: a 0/1 metric's rate with its Wilson interval, else a box plot of the per-episode values
    with the mean and its Student t interval; the marks explained once, below."""
    metrics, names = results["metrics"], list(results["agents"])
    labels = [_plot_label(name) for name in names]
    widest = max(len(line) for label in labels for line in label.split("\n"))
    width = max(3.2, len(names) * (TICK_CHARACTER_IN * widest + 0.3))  # [in] per panel: room for every agent's name
    columns = min(len(metrics), PANELS_PER_ROW)
    rows = -(-len(metrics) // columns)
    figure = matplotlib_figure("the evaluation plot", figsize=(width * columns + 1, 4.2 * rows), layout="constrained")
    axes = figure.subplots(rows, columns, squeeze=False).ravel()
    for unused in axes[len(metrics) :]:
        unused.set_visible(False)
    positions = np.arange(1, len(names) + 1)
    for axis, (key, title) in zip(axes, metrics.items()):
        summaries = [results["agents"][name]["summary"][key] for name in names]
        rate = summaries[0]["interval"] == WILSON
        if rate:
            axis.set_ylim(-0.05, 1.05)
        else:
            values = [[e[key] for e in results["agents"][name]["episodes"]] for name in names]
            axis.boxplot(
                values,
                positions=positions,
                widths=0.5,
                showfliers=True,
                label="episodes: median, quartiles, whiskers to 1.5 IQR",
            )
        errors = np.array([error_bar(s) for s in summaries]).T
        label = "rate, 95% CI (Wilson score)" if rate else "mean, 95% CI (Student t)"
        colour = "tab:blue" if rate else "tab:red"
        axis.errorbar(
            positions, [s["mean"] for s in summaries], yerr=errors, fmt="o", color=colour, capsize=4, label=label
        )
        axis.set_xticks(positions, labels, fontsize=8)
        axis.set_xlim(0.5, len(names) + 0.5)
        axis.set_ylabel(title)
    marks = {label: handle for axis in axes for handle, label in zip(*axis.get_legend_handles_labels())}
    figure.legend(marks.values(), marks.keys(), loc="outside lower center", ncols=len(marks), fontsize=8)
    figure.suptitle(f"{results['env_id']}: {results['episodes']} episodes per agent", fontsize=11)
    return figure


def write_results(results: dict, stem: Path, command: str) -> list[Path]:
    """Write ``stem.md``, ``stem.csv`` (per episode), ``stem.json`` and, with matplotlib, ``stem.png``."""
    stem.parent.mkdir(parents=True, exist_ok=True)
    md, csv_path, json_path = (output_file(stem, suffix) for suffix in (".md", ".csv", ".json"))
    md.write_text(
        f"# {heading(results)}\n\n{config_line(results)}\n\n{markdown_table(results)}\n\n"
        f"Regenerate with:\n\n    {command}\n"
    )
    with csv_path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["agent", "seed", *results["metrics"]])
        for name, result in results["agents"].items():
            for episode_seed, episode in zip(results["seeds"], result["episodes"]):
                writer.writerow([name, episode_seed, *(episode[key] for key in results["metrics"])])
    json_path.write_text(json.dumps({**results, "command": command}, indent=2) + "\n")
    written = [md, csv_path, json_path]
    try:
        written.append(plot_results(results, output_file(stem, ".png")))
    except ImportError:
        pass  # matplotlib is optional
    return written
