"""Evaluate agents on an env: same seeds for every agent, the env's own metrics with 95% confidence intervals."""

from __future__ import annotations

import contextlib
import itertools

from tqdm.auto import tqdm

from agents.ray_support import import_ray
from infonav_gym.compiled import INTERRUPTIONS, pressed_ctrl_c
from infonav_gym.envs.traits import episode_metrics_of, traits_of
from infonav_gym.experiments.episode_pool import EpisodeRunner, checked_workers, played, seeds_of
from infonav_gym.experiments.episodes import AGENT_NAMES, check_agent_name
from infonav_gym.experiments.intervals import summary_of
from infonav_gym.experiments.paths import Interrupted


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
    """Run every agent (each once) for ``episodes`` episodes on seeds ``seed ..``; in a PettingZoo env every robot plays
    its own copy. ``workers`` processes or Ray tasks give the same results as one. Returns ``{"env_id", "episodes",
    "seeds", "env_kwargs", "env_config", "metrics", "agents": {name: {"episodes", "summary"}}}``; ``ValueError`` before
    any episode for bad input, ``Interrupted`` on Ctrl-C with the seeds every agent finished."""
    seeds = seeds_of(seed, episodes)
    if not agent_names:
        raise ValueError(f"no agents given; choose from {', '.join(AGENT_NAMES)}")
    for name in agent_names:
        check_agent_name(name)
    if len(set(agent_names)) < len(agent_names):
        raise ValueError(f"an agent is given twice in {', '.join(agent_names)}: give each once")
    tasks = episodes * len(agent_names)
    workers = checked_workers(workers, tasks, tasks, f"{episodes} episodes of {len(agent_names)} agent(s)")
    if use_ray:
        import_ray(address)  # before any episode: a missing extra or a wrong address is a one-line error
    env_kwargs = dict(env_kwargs or {})
    runner = EpisodeRunner(env_id, env_kwargs, agent_names)
    env = runner.env
    declared = episode_metrics_of(env)
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
    seed_tasks = ((name, episode_seed) for episode_seed in seeds for name in runner.agents)  # made as played
    how = workers, use_ray, address
    bar = tqdm(total=tasks, desc=f"evaluating on {env_id}", disable=not progress, unit="episode")
    try:
        with contextlib.closing(played(runner, seed_tasks, *how)) as played_metrics:  # closed: the workers stop
            for name, metrics in zip(itertools.cycle(runner.agents), played_metrics):
                results["agents"][name]["episodes"].append(metrics)
                bar.update()
    except INTERRUPTIONS as error:
        if not pressed_ctrl_c(error):
            raise
        whole = min(len(result["episodes"]) for result in results["agents"].values())  # seeds every agent finished
        for result in results["agents"].values():
            del result["episodes"][whole:]
        results.update(interrupted=True, seeds=seeds[:whole], agents=results["agents"] if whole else {})
    finally:
        bar.close()
        runner.close()
    results["seeds"] = list(results["seeds"])
    for result in results["agents"].values():
        result["summary"] = {
            metric.name: summary_of(metric, [e[metric.name] for e in result["episodes"]]) for metric in declared
        }
    if results.get("interrupted"):
        raise Interrupted(f"interrupted after {len(results['seeds'])} of {episodes} seeds", results)
    return results
