"""The leaderboard: every env's baselines and committed models on the same seeds, ranked by the env's main metric.
Each cell is played alone after a ``WARMUP_STEPS`` warm-up: its wall time over its episodes is seconds per episode."""

from __future__ import annotations

import contextlib
import itertools
import json
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from tqdm.auto import tqdm

from agents.ray_support import local_or_cluster_ray
from infonav_gym.compiled import INTERRUPTIONS, pressed_ctrl_c
from infonav_gym.envs.traits import has_planning_model, main_metric_of
from infonav_gym.experiments.episode_pool import EpisodeRunner, checked_workers, played, seeds_of
from infonav_gym.experiments.intervals import INTERVAL_NOTES, interval_cell, summary_of
from infonav_gym.experiments.paths import Interrupted, output_file
from infonav_gym.registry import available_envs, env_entry, missing_dataset

COLUMNS = {
    "random": "random",
    "greedy": "greedy",
    "planner": "planner",
    "ppo": "PPO",
    "rllib": "RLlib PPO",
    "benchmarl": "BenchMARL MAPPO",
}
MODEL_COLUMNS = {"sb3": "ppo", "rllib": "rllib", "benchmarl": "benchmarl"}  # train.json's backend: its column
BASELINES = ("random", "greedy", "planner")  # agent name = column; the learned ones come from results/models
WARMUP_STEPS = 2  # steps of an untimed, uncounted episode start before each cell's timed episodes
TIE_TOLERANCE = 1e-9  # means within TIE_TOLERANCE * max(1, |best|) of the best mean are tied for the best


@dataclass(frozen=True)
class Row:
    """An env, its config, the agent each baseline column plays and the config's learned ``models``: ``(column,
    agent name, model name)`` each."""

    env_id: str
    env_kwargs: dict
    agents: dict
    models: tuple = ()


def committed_models(directory: Path) -> list[tuple[str, str, str, dict, str]]:
    """``(column, agent name, env id, env kwargs, model name)`` of each ``*/train.json`` in ``directory`` (a run
    that kept a best policy plays that one; one whose env's dataset is absent here is left out, with a warning);
    ``ValueError`` naming a ``train.json`` that is not an env's or names an unknown backend."""
    models = []
    for record_path in sorted(Path(directory).glob("*/train.json")):
        try:
            record = json.loads(record_path.read_text())
            env_entry(record["env_id"])
        except (ValueError, KeyError) as error:
            raise ValueError(f"{record_path}: not the train.json of a registered env ({error})") from None
        if reason := missing_dataset(record["env_id"], **record.get("env_kwargs", {})):
            warnings.warn(f"{record_path.parent} left out: {reason}", stacklevel=2)
            continue
        column = MODEL_COLUMNS.get(record.get("backend", "sb3"))
        if column is None:
            raise ValueError(f"{record_path}: backend {record['backend']!r} is none of {', '.join(MODEL_COLUMNS)}")
        model = record_path.parent
        if record.get("validation"):
            model /= Path(record["validation"]["best"]).name
        models.append(
            (column, f"{column}:{model}", record["env_id"], record.get("env_kwargs", {}), record_path.parent.name)
        )
    return models


def leaderboard_rows(env_ids, columns, models_dir: Path | None) -> list[Row]:
    """A row per env of ``env_ids`` and config of its models (the defaults if none), with the baseline ``columns``
    that apply and every model of the learned ``columns``. ``ValueError`` for an unknown column or env."""
    for column in columns:
        if column not in COLUMNS:
            raise ValueError(f"unknown agent {column!r} in --agents; choose from {', '.join(COLUMNS)}")
    models = committed_models(models_dir) if models_dir else []
    rows = []
    for env_id in env_ids:
        has_planner = has_planning_model(env_entry(env_id).load())
        configs = {}  # config as sorted JSON -> (config, [(column, model agent, its name), ...])
        for column, agent, model_env_id, env_kwargs, name in models:
            if model_env_id == env_id and column in columns:
                configs.setdefault(json.dumps(env_kwargs, sort_keys=True), (env_kwargs, []))[1].append(
                    (column, agent, name)
                )
        baselines = {name: name for name in BASELINES if name in columns and (name != "planner" or has_planner)}
        for env_kwargs, learned in configs.values() or [({}, [])]:
            if baselines or learned:
                rows.append(Row(env_id, env_kwargs, baselines, tuple(learned)))
    if not rows:
        raise ValueError(f"no agent of {', '.join(columns)} applies to {', '.join(env_ids)}: nothing to play")
    return rows


def best_indices(means: list[float]) -> list[int]:
    """The indices of the best (highest) of ``means``, within ``TIE_TOLERANCE``, in order."""
    best = max(means)
    return [index for index, mean in enumerate(means) if best - mean <= TIE_TOLERANCE * max(1, abs(best))]


def best_columns(cells: dict) -> list[str]:
    """The columns whose mean is the best (highest) one, within ``TIE_TOLERANCE``."""
    columns = list(cells)
    return [columns[index] for index in best_indices([cell["summary"]["mean"] for cell in cells.values()])]


def _played_row(row: Row, seeds: range, bar, how: tuple) -> dict:
    """Every agent of ``row`` on ``seeds``: values, summary and seconds per episode of its main metric. ``"cells"``:
    each baseline's and each model family's best model's (by mean); ``"models"``: every model's, named."""
    cells, models = {}, []
    for column, agent in row.agents.items():
        metric, cells[column] = _played_cell(row, agent, seeds, bar, *how)
    for column, agent, name in row.models:
        metric, cell = _played_cell(row, agent, seeds, bar, *how)
        models.append({"column": column, "name": name, **cell})
    for column in COLUMNS:
        family = [model for model in models if model["column"] == column]
        if family:
            best = family[best_indices([model["summary"]["mean"] for model in family])[0]]
            cells[column] = {key: value for key, value in best.items() if key != "column"}
    return {
        "env_id": row.env_id,
        "env_kwargs": row.env_kwargs,
        "metric": {"name": metric.name, "title": metric.title},
        "cells": cells,
        "models": models,
        "best": best_columns(cells),
    }


def _played_cell(row: Row, agent: str, seeds: range, bar, workers: int, use_ray: bool, address: str | None):
    """``(the env's main metric, the cell)`` of ``agent`` in ``row``'s env and config on ``seeds``."""
    runner = EpisodeRunner(row.env_id, row.env_kwargs, [agent])
    try:
        metric = main_metric_of(runner.env)
        for _ in itertools.islice(runner.infos((agent, seeds[0])), WARMUP_STEPS + 1):
            pass  # compiles and loads what the agent and env need before the clock starts
        values, start = [], time.perf_counter()
        with contextlib.closing(played(runner, ((agent, seed) for seed in seeds), workers, use_ray, address)) as cell:
            for metrics in cell:
                values.append(metrics[metric.name])
                bar.update()
        seconds = time.perf_counter() - start
    finally:
        runner.close()
    cell = {"agent": agent, "summary": summary_of(metric, values), "values": values}
    return metric, cell | {"seconds_per_episode": seconds / len(seeds)}


def leaderboard(
    env_ids=None,
    columns=tuple(COLUMNS),
    models_dir: Path | None = None,
    episodes: int = 50,
    seed: int = 0,
    progress=True,
    workers: int = 1,
    use_ray: bool = False,
    address: str | None = None,
) -> dict:
    """Play the rows (``leaderboard_rows``) on seeds ``seed .. seed + episodes - 1`` (``env_ids``: default all): a dict
    of ``"episodes", "seeds", "columns", "workers", "tie_tolerance"`` and ``"rows"`` (each with its ``"cells"`` and
    ``"best"`` columns). ``ValueError`` before any episode for bad input; ``Interrupted`` with the finished rows."""
    seeds = seeds_of(seed, episodes)
    env_ids = [entry.id for entry in available_envs()] if env_ids is None else list(env_ids)
    rows = leaderboard_rows(env_ids, columns, models_dir)
    cells = sum(len(row.agents) + len(row.models) for row in rows)
    workers = checked_workers(workers, episodes, episodes * cells, f"{episodes} episodes of {cells} cells")
    results = {"episodes": episodes, "seeds": list(seeds), "columns": [c for c in COLUMNS if c in columns], "rows": []}
    results |= {"workers": workers, "tie_tolerance": TIE_TOLERANCE}
    bar = tqdm(total=episodes * cells, desc="leaderboard", disable=not progress, unit="episode")
    try:
        with local_or_cluster_ray(address) if use_ray else contextlib.nullcontext():  # one Ray for every cell
            for row in rows:
                results["rows"].append(_played_row(row, seeds, bar, (workers, use_ray, address)))
    except INTERRUPTIONS as error:
        if not pressed_ctrl_c(error):
            raise
        raise Interrupted(
            f"interrupted after {len(results['rows'])} of {len(rows)} rows", results | {"interrupted": True}
        ) from None
    finally:
        bar.close()
    return results


def _config_text(row: dict) -> str:
    """A row's config."""
    return ", ".join(f"{key}={value!r}" for key, value in row["env_kwargs"].items()) or "defaults"


def markdown_tables(results: dict) -> str:
    """The main metric table (best per row in bold), the seconds-per-episode table and what their cells are."""
    titles = [COLUMNS[column] for column in results["columns"]]
    lines = ["| env | config | main metric | " + " | ".join(titles) + " |", "|" + " --- |" * (len(titles) + 3)]
    times = ["| env | config | " + " | ".join(titles) + " |", "|" + " --- |" * (len(titles) + 2)]
    for row in results["rows"]:
        cells, head = row["cells"], f"| {row['env_id']} | {_config_text(row)} |"
        shown = [interval_cell(cells[c]["summary"]) if c in cells else "" for c in results["columns"]]
        bold = [f"**{text}**" if column in row["best"] else text for column, text in zip(results["columns"], shown)]
        lines.append(f"{head} {row['metric']['title']} | " + " | ".join(bold) + " |")
        seconds = [f"{cells[c]['seconds_per_episode']:.3g}" if c in cells else "" for c in results["columns"]]
        times.append(f"{head} " + " | ".join(seconds) + " |")
    kinds = {cell["summary"]["interval"] for row in results["rows"] for cell in row["cells"].values()}
    notes = "; ".join(note for kind, note in INTERVAL_NOTES.items() if kind in kinds)
    return (
        "\n".join(lines) + f"\n\nEach cell: {notes}. Bold: the best mean of the row (higher is better; means within "
        f"{results['tie_tolerance']:g} x max(1, |best|) of it tie). An empty cell: the agent does not apply.\n\n"
        f"Seconds per episode (the wall time of an agent's episodes over their count, {results['workers']} "
        f"worker(s)):\n\n" + "\n".join(times)
    )


def heading(results: dict) -> str:
    """``Leaderboard: N episodes per agent, seeds a..b`` (and how far an interrupted run got)."""
    seeds = results["seeds"]
    interrupted = " (interrupted: the finished rows)" if results.get("interrupted") else ""
    return f"Leaderboard: {results['episodes']} episodes per agent, seeds {seeds[0]}..{seeds[-1]}{interrupted}"


def models_text(results: dict) -> str:
    """Every model of each row, one line each, its family's best of the row (the cell above) in bold."""
    lines = [
        "| env | config | model | main metric | seconds per episode | agent |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for row in results["rows"]:
        for model in row.get("models", []):
            shown = interval_cell(model["summary"])
            if model["agent"] == row["cells"][model["column"]]["agent"]:
                shown = f"**{shown}**"
            lines.append(
                f"| {row['env_id']} | {_config_text(row)} | {COLUMNS[model['column']]} {model['name']} | {shown} | "
                f"{model['seconds_per_episode']:.3g} | `{model['agent']}` |"
            )
    if len(lines) == 2:
        return "No models."
    return "\n".join(["Every model (bold: its family's best of the row, the cell above):", "", *lines])


def write_leaderboard(results: dict, stem: Path, command: str) -> list[Path]:
    """Write ``stem.md`` (tables, models and command) and ``stem.json``."""
    stem.parent.mkdir(parents=True, exist_ok=True)
    md, json_path = output_file(stem, ".md"), output_file(stem, ".json")
    md.write_text(
        f"# {heading(results)}\n\n{markdown_tables(results)}\n\n{models_text(results)}\n\n"
        f"Regenerate with:\n\n    {command}\n"
    )
    json_path.write_text(json.dumps({**results, "command": command}, indent=2) + "\n")
    return [md, json_path]
