"""Evaluate baseline agents on an env: same seeds for every agent, mean and 95% confidence intervals."""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
from scipy import stats
from tqdm.auto import tqdm

from agents import GreedyEntropyAgent, RandomAgent

AGENT_NAMES = ("random", "greedy")
METRICS = {
    "cumulative_mi": "cumulative MI [nats]",
    "final_pose_entropy": "final pose entropy [nats]",
    "pose_rmse_m": "position RMSE [m]",
}


def make_agent(name: str, n_actions: int):
    """A baseline agent by name."""
    if name == "random":
        return RandomAgent(n_actions)
    if name == "greedy":
        return GreedyEntropyAgent()
    raise ValueError(f"unknown agent {name!r}; choose from {', '.join(AGENT_NAMES)}")


def run_episode(env: gym.Env, agent, seed: int) -> dict:
    """One seeded episode; returns the per-episode metrics."""
    observation, info = env.reset(seed=seed)
    agent.reset(seed=seed)
    cumulative_mi, squared_errors = 0.0, []
    done = False
    while not done:
        observation, _, terminated, truncated, info = env.step(agent.act(observation, info))
        cumulative_mi += info["reward_terms"].get("mutual_information", 0.0)
        squared_errors.append(info["position_error_m"] ** 2)
        done = terminated or truncated
    return {
        "cumulative_mi": cumulative_mi,
        "final_pose_entropy": info["pose_entropy"],
        "pose_rmse_m": math.sqrt(float(np.mean(squared_errors))),
    }


@dataclass
class Summary:
    mean: float
    ci95: float  # half-width of the 95% confidence interval of the mean (Student t)

    @classmethod
    def of(cls, values) -> Summary:
        values = np.asarray(values, dtype=float)
        if len(values) < 2:
            return cls(float(values.mean()), float("nan"))
        half_width = stats.t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / math.sqrt(len(values))
        return cls(float(values.mean()), float(half_width))


def evaluate(env_id: str, agent_names, episodes: int, seed: int = 0, env_kwargs: dict | None = None, progress=True):
    """Run every agent for ``episodes`` episodes on seeds ``seed, seed + 1, ...``.

    Returns:
        ``{"env_id", "episodes", "seeds", "env_kwargs", "agents": {name: {"episodes": [...], "summary": {...}}}}``.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    env_kwargs = dict(env_kwargs or {})
    env = gym.make(env_id, **env_kwargs)
    agents = {name: make_agent(name, env.action_space.n) for name in agent_names}
    seeds = list(range(seed, seed + episodes))
    results = {"env_id": env_id, "episodes": episodes, "seeds": seeds, "env_kwargs": env_kwargs, "agents": {}}
    bar = tqdm(total=len(agents) * episodes, desc=f"evaluating on {env_id}", disable=not progress, unit="episode")
    for name, agent in agents.items():
        per_episode = []
        for episode_seed in seeds:
            per_episode.append(run_episode(env, agent, episode_seed))
            bar.update()
        summary = {key: vars(Summary.of([e[key] for e in per_episode])) for key in METRICS}
        results["agents"][name] = {"episodes": per_episode, "summary": summary}
    bar.close()
    env.close()
    return results


def markdown_table(results: dict) -> str:
    """The summary as a Markdown table: mean +- 95% CI half-width per agent and metric."""
    header = "| agent | " + " | ".join(METRICS.values()) + " |"
    lines = [header, "|" + " --- |" * (len(METRICS) + 1)]
    for name, result in results["agents"].items():
        cells = [f"{s['mean']:.3f} ± {s['ci95']:.3f}" for s in (result["summary"][key] for key in METRICS)]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_results(results: dict, stem: Path, command: str) -> list[Path]:
    """Write ``stem.md`` (table and command), ``stem.csv`` (per episode) and ``stem.json``."""
    stem.parent.mkdir(parents=True, exist_ok=True)
    md, csv_path, json_path = stem.with_suffix(".md"), stem.with_suffix(".csv"), stem.with_suffix(".json")
    md.write_text(
        f"# {results['env_id']}: {results['episodes']} episodes per agent, seeds "
        f"{results['seeds'][0]}..{results['seeds'][-1]}\n\n{markdown_table(results)}\n\n"
        f"Mean ± half-width of the 95% confidence interval (Student t). Regenerate with:\n\n    {command}\n"
    )
    with csv_path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["agent", "seed", *METRICS])
        for name, result in results["agents"].items():
            for episode_seed, episode in zip(results["seeds"], result["episodes"]):
                writer.writerow([name, episode_seed, *(episode[key] for key in METRICS)])
    json_path.write_text(json.dumps({**results, "command": command}, indent=2) + "\n")
    return [md, csv_path, json_path]
