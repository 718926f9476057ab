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

AGENT_NAMES = ("random", "greedy", "planner", "ppo:PATH")
PPO_PREFIX = "ppo:"
TEAM_ENV = "cooperative_localization_v0"  # the PettingZoo env; every robot plays its own copy of the agent
SENSOR_ENV = "infonav/SensorSelection-v0"  # rewards image information, not pose updates
REGISTRATION_ENV = "infonav/RangeRegistration-v0"  # rewards registration error reduction
METRICS = {
    "cumulative_mi": "cumulative MI [nats]",
    "final_pose_entropy": "final pose entropy [nats]",
    "pose_rmse_m": "position RMSE [m]",
}
IMAGE_METRICS = {
    "cumulative_information": "cumulative image information [nats]",
    "frames": "frames acquired",
    "mean_frame_entropy": "mean frame entropy [nats]",
}


REGISTRATION_METRICS = {
    "cumulative_reward": "cumulative reward [m]",
    "mean_error_after_m": "registration error after ICP [m]",
    "mean_control_points": "control points per frame pair",
}


SUCCESS_METRIC = {"success_rate": "success rate"}  # when the env puts info["success"] (bool) in its final info


def metrics_of(env_id: str) -> dict:
    """The metrics reported for ``env_id``: ``{key: column title}``."""
    return {SENSOR_ENV: IMAGE_METRICS, REGISTRATION_ENV: REGISTRATION_METRICS}.get(env_id, METRICS)


def _localization_metrics(infos: list[dict]) -> dict:
    return {
        "cumulative_mi": math.fsum(step["reward_terms"].get("mutual_information", 0.0) for step in infos),
        "final_pose_entropy": infos[-1]["pose_entropy"],
        "pose_rmse_m": math.sqrt(float(np.mean([step["position_error_m"] ** 2 for step in infos]))),
    }


def _image_metrics(infos: list[dict]) -> dict:
    entropies = [step["image_entropy"] for step in infos if step["sensor"] != "none"]
    return {
        "cumulative_information": math.fsum(step["reward_terms"]["image_information"] for step in infos),
        "frames": len(entropies),
        "mean_frame_entropy": float(np.mean(entropies)) if entropies else 0.0,
    }


def _registration_metrics(infos: list[dict]) -> dict:
    registered = [step for step in infos if step["registered"]]
    return {
        "cumulative_reward": math.fsum(math.fsum(step["reward_terms"].values()) for step in infos),
        "mean_error_after_m": float(np.mean([step["error_after_m"] for step in registered])) if registered else 0.0,
        "mean_control_points": float(np.mean([step["n_control_points"] for step in registered])) if registered else 0.0,
    }


def check_agent_name(name: str) -> None:
    """Raise ``ValueError`` unless ``name`` is random, greedy, planner or ppo:PATH."""
    if name in ("random", "greedy", "planner") or (name.startswith(PPO_PREFIX) and len(name) > len(PPO_PREFIX)):
        return
    raise ValueError(f"unknown agent {name!r}; choose from {', '.join(AGENT_NAMES)}")


def make_agent(
    name: str, n_actions: int, noop_action: int | None = None, env: gym.Env | None = None, agent: str | None = None
):
    """A baseline agent by name (``noop_action``: see ``RandomAgent``).

    ``planner`` (``agents.planner.PlannerAgent(env)``) and ``ppo:PATH`` (``agents.ppo.PPOAgent(PATH, env)``)
    need the ``env`` they will act in; both are imported only when asked for. In the PettingZoo
    team env ``agent`` names the robot a ``ppo:PATH`` agent acts for.
    """
    check_agent_name(name)
    if name == "random":
        return RandomAgent(n_actions, noop_action=noop_action)
    if name == "greedy":
        return GreedyEntropyAgent()
    if env is None:
        raise ValueError(f"agent {name!r} needs a single-agent Gymnasium env, not the team env")
    if name == "planner":
        try:
            from agents.planner import PlannerAgent
        except ImportError as error:
            raise ValueError(
                f"agent 'planner' is not available: agents.planner.PlannerAgent does not import ({error})"
            ) from None
        return PlannerAgent(env)
    try:
        from agents.ppo import PPOAgent
    except ImportError as error:
        raise ValueError(f"agent {name!r} needs the rl extra (pip install 'infonav-gym[rl]'): {error}") from None
    return PPOAgent(name[len(PPO_PREFIX) :], env, agent)


def make_team_agents(name: str, env) -> dict:
    """One agent per robot of the team env ``env`` (a PettingZoo parallel env): ``{robot: agent}``.

    ``random`` picks a teammate to observe (``noop_action=0``); ``ppo:PATH`` is one policy shared by
    every robot (``infonav train --env cooperative_localization_v0``), checked against each robot's spaces.
    """
    check_agent_name(name)
    if name == "planner":
        raise ValueError(f"agent 'planner' is not available for {TEAM_ENV}: use random, greedy or ppo:PATH")
    return {
        robot: make_agent(name, env.action_space(robot).n, noop_action=0, env=env, agent=robot)
        for robot in env.possible_agents
    }


def make_env(env_id: str, env_kwargs: dict | None = None) -> gym.Env:
    """``gym.make(env_id, **env_kwargs)``; an unknown id raises ``ValueError`` naming it and the infonav ids."""
    try:
        return gym.make(env_id, **(env_kwargs or {}))
    except gym.error.Error as error:
        infonav = sorted(name for name in gym.registry if name.startswith("infonav/"))
        raise ValueError(
            f"unknown env id {env_id!r} ({error}); choose from {', '.join([*infonav, TEAM_ENV])}"
        ) from None


def run_episode(env: gym.Env, agent, seed: int) -> dict:
    """One seeded episode; returns the per-episode metrics (``metrics_of`` the env)."""
    observation, info = env.reset(seed=seed)
    agent.reset(seed=seed)
    infos, done = [], False
    while not done:
        observation, _, terminated, truncated, info = env.step(agent.act(observation, info))
        infos.append(info)
        done = terminated or truncated
    env_id = env.spec.id if env.spec is not None else None
    summarize = {SENSOR_ENV: _image_metrics, REGISTRATION_ENV: _registration_metrics}.get(env_id, _localization_metrics)
    metrics = summarize(infos)
    if "success" in info:
        metrics["success_rate"] = float(bool(info["success"]))
    return metrics


def run_team_episode(env, agents: dict, seed: int) -> dict:
    """One seeded episode of the PettingZoo team env, ``agents[robot]`` acting for each robot; team metrics.

    ``agents`` comes from ``make_team_agents``. ``cumulative_mi`` is the team's (joint-state) MI;
    entropy and RMSE are means over the robots.
    """
    observations, infos = env.reset(seed=seed)
    for k, robot in enumerate(env.possible_agents):
        agents[robot].reset(seed=1000 * seed + k)
    cumulative_mi, squared_errors, steps = 0.0, np.zeros(len(agents)), 0
    while env.agents:
        actions = {name: agents[name].act(observations[name], infos[name]) for name in env.agents}
        observations, _, _, _, infos = env.step(actions)
        cumulative_mi += next(iter(infos.values()))["reward_terms"]["team_mutual_information"]
        squared_errors += [info["position_error_m"] ** 2 for info in infos.values()]
        steps += 1
    return {
        "cumulative_mi": cumulative_mi,
        "final_pose_entropy": float(np.mean([info["pose_entropy"] for info in infos.values()])),
        "pose_rmse_m": float(np.mean(np.sqrt(squared_errors / steps))),
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

    ``env_id`` is a Gymnasium id or ``"cooperative_localization_v0"`` (the team env; there
    "random" is a random choice of teammate to observe, ``ppo:PATH`` one policy for every robot,
    no planner, and the metrics are the team's).
    ``agent_names``: random, greedy, planner, ppo:PATH (a model written by ``infonav train``).
    A ``success_rate`` metric is added when every episode's final info has ``"success"``.

    Returns:
        ``{"env_id", "episodes", "seeds", "env_kwargs", "agents": {name: {"episodes": [...], "summary": {...}}}}``.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if not agent_names:
        raise ValueError(f"no agents given; choose from {', '.join(AGENT_NAMES)}")
    for name in agent_names:
        check_agent_name(name)
    env_kwargs = dict(env_kwargs or {})
    if env_id == TEAM_ENV:
        from infonav_gym.multi import cooperative_localization_v0

        env = cooperative_localization_v0.parallel_env(**env_kwargs)
    else:
        env = make_env(env_id, env_kwargs)
    try:
        if env_id == TEAM_ENV:
            agents = {name: make_team_agents(name, env) for name in agent_names}  # {robot: agent} each
        else:
            agents = {name: make_agent(name, env.action_space.n, env=env) for name in agent_names}
    except Exception:
        env.close()
        raise
    seeds = list(range(seed, seed + episodes))
    metrics = dict(metrics_of(env_id))
    results = {"env_id": env_id, "episodes": episodes, "seeds": seeds, "env_kwargs": env_kwargs, "metrics": metrics}
    results["agents"] = {}
    bar = tqdm(total=len(agents) * episodes, desc=f"evaluating on {env_id}", disable=not progress, unit="episode")
    for name, agent in agents.items():
        per_episode = []
        for episode_seed in seeds:
            if env_id == TEAM_ENV:
                per_episode.append(run_team_episode(env, agent, episode_seed))
            else:
                per_episode.append(run_episode(env, agent, episode_seed))
            bar.update()
        results["agents"][name] = {"episodes": per_episode}
    bar.close()
    env.close()
    every_episode = [e for result in results["agents"].values() for e in result["episodes"]]
    if all("success_rate" in e for e in every_episode):
        metrics.update(SUCCESS_METRIC)
    for result in results["agents"].values():
        result["summary"] = {key: vars(Summary.of([e[key] for e in result["episodes"]])) for key in metrics}
    return results


def markdown_table(results: dict) -> str:
    """The summary as a Markdown table: mean +- 95% CI half-width per agent and metric."""
    metrics = results["metrics"]
    header = "| agent | " + " | ".join(metrics.values()) + " |"
    lines = [header, "|" + " --- |" * (len(metrics) + 1)]
    for name, result in results["agents"].items():
        cells = [f"{s['mean']:.3f} ± {s['ci95']:.3f}" for s in (result["summary"][key] for key in metrics)]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _plot_label(name: str) -> str:
    """``ppo:runs/x/model.zip`` -> ``ppo:x/model.zip``: short enough for an axis."""
    if not name.startswith(PPO_PREFIX):
        return name
    path = Path(name[len(PPO_PREFIX) :])
    return PPO_PREFIX + "/".join(path.parts[-2:])


def plot_results(results: dict, path: Path) -> Path:
    """A box plot per metric of the per-episode values of every agent, with the mean and its 95% CI as a dot."""
    from matplotlib.figure import Figure  # no pyplot: renders with Agg, leaves the caller's backend alone

    metrics, names = results["metrics"], list(results["agents"])
    figure = Figure(figsize=(3.2 * len(metrics) + 1, 3.6))
    axes = figure.subplots(1, len(metrics), squeeze=False)
    positions = np.arange(1, len(names) + 1)
    for axis, (key, title) in zip(axes[0], metrics.items()):
        values = [[e[key] for e in results["agents"][name]["episodes"]] for name in names]
        axis.boxplot(values, positions=positions, widths=0.5, showfliers=True)
        summaries = [results["agents"][name]["summary"][key] for name in names]
        means = [s["mean"] for s in summaries]
        errors = [0.0 if math.isnan(s["ci95"]) else s["ci95"] for s in summaries]
        axis.errorbar(positions, means, yerr=errors, fmt="o", color="tab:red", capsize=4, label="mean ± 95% CI")
        axis.set_xticks(positions, [_plot_label(name) for name in names], rotation=20, ha="right")
        axis.set_title(title, fontsize=10)
    axes[0][0].legend(fontsize=8)
    figure.suptitle(f"{results['env_id']}: {results['episodes']} episodes per agent", fontsize=11)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    return path


def write_results(results: dict, stem: Path, command: str) -> list[Path]:
    """Write ``stem.md`` (table and command), ``stem.csv`` (per episode), ``stem.json`` and ``stem.png``.

    The plot needs matplotlib (the ``render`` extra); without it the other three are written.
    """
    stem.parent.mkdir(parents=True, exist_ok=True)
    md, csv_path, json_path = stem.with_suffix(".md"), stem.with_suffix(".csv"), stem.with_suffix(".json")
    md.write_text(
        f"# {results['env_id']}: {results['episodes']} episodes per agent, seeds "
        f"{results['seeds'][0]}..{results['seeds'][-1]}\n\n{markdown_table(results)}\n\n"
        f"Mean ± half-width of the 95% confidence interval (Student t). Regenerate with:\n\n    {command}\n"
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
        written.append(plot_results(results, stem.with_suffix(".png")))
    except ImportError:
        pass  # matplotlib is optional
    return written
