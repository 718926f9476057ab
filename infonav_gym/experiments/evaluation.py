"""Evaluate baseline agents on an env: same seeds for every agent, means and 95% confidence intervals.

What is reported comes from the env: its class's ``episode_metrics`` and ``traits``
(``infonav_gym.envs.metrics``, ``infonav_gym.envs.traits``); whether every robot acts at once
from the registry's ``api`` (``infonav_gym.registry``).
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats
from tqdm.auto import tqdm

from agents.ray_support import import_ray
from infonav_gym.envs.traits import episode_metrics_of, traits_of
from infonav_gym.experiments.episode_pool import EpisodeRunner, check_positive, played
from infonav_gym.experiments.episodes import AGENT_NAMES, PPO_PREFIX, check_agent_name
from infonav_gym.experiments.paths import Interrupted, output_file
from infonav_gym.rendering import matplotlib_figure, save_figure

STUDENT_T, WILSON = "student_t", "wilson"
Z_95 = float(stats.norm.ppf(0.975))  # two-sided 95% quantile of the standard normal
INTERVAL_NOTES = {
    STUDENT_T: "mean ± half-width of its 95% confidence interval (Student t)",
    WILSON: "rate [low, high]: its 95% confidence interval (Wilson score)",
}


def wilson_interval(successes: int, trials: int, z: float = Z_95) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion ``successes / trials``, inside [0, 1].

    Raises:
        ValueError: unless ``0 <= successes <= trials`` and ``trials >= 1``.
    """
    if trials < 1 or not 0 <= successes <= trials:
        raise ValueError(f"a proportion needs 0 <= successes <= trials and trials >= 1, got {successes} of {trials}")
    rate, z2 = successes / trials, z * z
    center = (rate + z2 / (2 * trials)) / (1 + z2 / trials)
    half_width = z / (1 + z2 / trials) * math.sqrt(rate * (1 - rate) / trials + z2 / (4 * trials * trials))
    return max(0.0, center - half_width), min(1.0, center + half_width)


@dataclass(frozen=True)
class Summary:
    """The mean of a metric over episodes and the half-width of its 95% confidence interval (Student t)."""

    mean: float
    ci95: float  # nan for a single episode

    @classmethod
    def of(cls, values) -> Summary:
        values = np.asarray(values, dtype=float)
        if len(values) < 2:
            return cls(float(values.mean()), float("nan"))
        half_width = stats.t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / math.sqrt(len(values))
        return cls(float(values.mean()), float(half_width))

    def as_dict(self) -> dict:
        return {"mean": self.mean, "ci95": self.ci95, "interval": STUDENT_T}


@dataclass(frozen=True)
class ProportionSummary:
    """The rate of a 0/1 metric over episodes and its 95% Wilson score interval ``[low, high]``."""

    mean: float
    low: float
    high: float

    @classmethod
    def of(cls, values) -> ProportionSummary:
        """Raises ``ValueError`` if a value is not 0 or 1."""
        values = np.asarray(values, dtype=float)
        if not np.isin(values, (0.0, 1.0)).all():
            raise ValueError(f"a proportion metric takes values 0 or 1 per episode, got {values.tolist()}")
        return cls(float(values.mean()), *wilson_interval(int(values.sum()), len(values)))

    def as_dict(self) -> dict:
        return {"mean": self.mean, "ci95_low": self.low, "ci95_high": self.high, "interval": WILSON}


def evaluate(
    env_id: str,
    agent_names,
    episodes: int,
    seed: int = 0,
    env_kwargs: dict | None = None,
    progress=True,
    workers: int = 1,
    use_ray: bool = False,
    address: str | None = None,
):
    """Run every agent for ``episodes`` episodes on seeds ``seed, seed + 1, ...``.

    ``env_id``: any registered env (``infonav_gym.registry``). In a PettingZoo parallel env (e.g.
    ``cooperative_localization_v0``) every robot plays its own copy of the agent, ``ppo:PATH`` one policy
    for every robot. ``agent_names``: random, greedy, planner (envs with a planning model), ppo:PATH (a model
    written by ``infonav train``). The metrics are the env's ``episode_metrics``. ``workers`` processes play
    the episodes at once (``use_ray``: as Ray tasks, on the cluster at ``address`` or a local Ray), with the
    same results as one (``episode_pool``).

    Returns:
        ``{"env_id", "episodes", "seeds", "env_kwargs", "env_config", "metrics", "agents": {name: {"episodes":
        [...], "summary": {...}}}}``; ``env_config`` is the config the env ran, defaults included.

    Raises:
        Interrupted: on Ctrl-C, with the evaluation of the episodes finished (``"interrupted": True``; only the
            seeds and agents that finished one). The episodes are played seed by seed, every agent on each seed.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if not agent_names:
        raise ValueError(f"no agents given; choose from {', '.join(AGENT_NAMES)}")
    for name in agent_names:
        check_agent_name(name)
    check_positive(workers, "workers")
    if use_ray:
        import_ray(address)  # before any episode: a missing extra or a wrong address is a one-line error
    env_kwargs = dict(env_kwargs or {})
    runner = EpisodeRunner(env_id, env_kwargs, agent_names)
    env = runner.env
    declared = episode_metrics_of(env)
    seeds = list(range(seed, seed + episodes))
    results = {
        "env_id": env_id,
        "episodes": episodes,
        "seeds": seeds,
        "env_kwargs": env_kwargs,
        "env_config": dict(getattr(env.unwrapped, "config", {})),
        "reward_config_keys": list(traits_of(env).reward_config_keys),
        "metrics": {metric.name: metric.title for metric in declared},
        "agents": {name: {"episodes": []} for name in runner.agents},
    }
    tasks = [(name, episode_seed) for episode_seed in seeds for name in runner.agents]
    bar = tqdm(total=len(tasks), desc=f"evaluating on {env_id}", disable=not progress, unit="episode")
    finished = 0
    try:
        for (name, _), metrics in zip(tasks, played(runner, tasks, workers, use_ray, address)):
            results["agents"][name]["episodes"].append(metrics)
            finished += 1
            bar.update()
    except KeyboardInterrupt:
        played_agents = {name: result for name, result in results["agents"].items() if result["episodes"]}
        seeds_played = max(map(len, (result["episodes"] for result in played_agents.values())), default=0)
        results.update(interrupted=True, agents=played_agents, seeds=seeds[:seeds_played])
    finally:
        bar.close()
        runner.close()
    for result in results["agents"].values():
        result["summary"] = {
            metric.name: (ProportionSummary if metric.proportion else Summary)
            .of([e[metric.name] for e in result["episodes"]])
            .as_dict()
            for metric in declared
        }
    if results.get("interrupted"):
        raise Interrupted(f"interrupted after {finished} of {len(tasks)} episodes", results)
    return results


def _cell(summary: dict) -> str:
    if summary["interval"] == WILSON:
        return f"{summary['mean']:.3f} [{summary['ci95_low']:.3f}, {summary['ci95_high']:.3f}]"
    if math.isnan(summary["ci95"]):  # one episode: no interval
        return f"{summary['mean']:.3f} ± n/a"
    return f"{summary['mean']:.3f} ± {summary['ci95']:.3f}"


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
    """The summary as a Markdown table (a cell per agent and metric), and what its intervals are (a sentence
    per kind of interval it holds)."""
    metrics = results["metrics"]
    header = "| agent | " + " | ".join(metrics.values()) + " |"
    lines = [header, "|" + " --- |" * (len(metrics) + 1)]
    for name, result in results["agents"].items():
        lines.append(f"| {name} | " + " | ".join(_cell(result["summary"][key]) for key in metrics) + " |")
    kinds = {s["interval"] for result in results["agents"].values() for s in result["summary"].values()}
    note = "; ".join(note for kind, note in INTERVAL_NOTES.items() if kind in kinds)
    return "\n".join(lines) + f"\n\nEach cell: {note}."


def _error_bar(summary: dict) -> tuple[float, float]:
    """The distances below and above the mean to the ends of its 95% interval (0 where undefined)."""
    if summary["interval"] == WILSON:
        return summary["mean"] - summary["ci95_low"], summary["ci95_high"] - summary["mean"]
    half_width = 0.0 if math.isnan(summary["ci95"]) else summary["ci95"]
    return half_width, half_width


def _plot_label(name: str) -> str:
    """``ppo:runs/x/model.zip`` -> ``ppo:x/model.zip``: short enough for an axis."""
    if not name.startswith(PPO_PREFIX):
        return name
    path = Path(name[len(PPO_PREFIX) :])
    return PPO_PREFIX + "/".join(path.parts[-2:])


def plot_results(results: dict, path: Path) -> Path:
    """A box plot per metric of every agent's per-episode values, and the mean with its 95% CI (as in the table)."""
    metrics, names = results["metrics"], list(results["agents"])
    figure = matplotlib_figure("the evaluation plot", figsize=(3.2 * len(metrics) + 1, 3.6))
    axes = figure.subplots(1, len(metrics), squeeze=False)
    positions = np.arange(1, len(names) + 1)
    for axis, (key, title) in zip(axes[0], metrics.items()):
        values = [[e[key] for e in results["agents"][name]["episodes"]] for name in names]
        axis.boxplot(values, positions=positions, widths=0.5, showfliers=True)
        summaries = [results["agents"][name]["summary"][key] for name in names]
        means = [s["mean"] for s in summaries]
        errors = np.array([_error_bar(s) for s in summaries]).T
        label = f"mean, 95% CI ({'Wilson score' if summaries[0]['interval'] == WILSON else 'Student t'})"
        axis.errorbar(positions, means, yerr=errors, fmt="o", color="tab:red", capsize=4, label=label)
        axis.legend(fontsize=8)
        axis.set_xticks(positions, [_plot_label(name) for name in names], rotation=20, ha="right")
        axis.set_title(title, fontsize=10)
    figure.suptitle(f"{results['env_id']}: {results['episodes']} episodes per agent", fontsize=11)
    figure.tight_layout()
    return save_figure(figure, path, dpi=110)


def write_results(results: dict, stem: Path, command: str) -> list[Path]:
    """Write ``stem.md`` (table and command), ``stem.csv`` (per episode), ``stem.json`` and ``stem.png``.

    The plot needs matplotlib (the ``render`` extra); without it the other three are written.
    """
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
