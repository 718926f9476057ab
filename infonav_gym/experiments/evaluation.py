"""Evaluate agents on an env: same seeds for every agent, means and 95% confidence intervals (``intervals``);
``evaluation_files`` prints and writes what it finds.

What is reported comes from the env: its class's ``episode_metrics`` and ``traits``
(``infonav_gym.envs.metrics``, ``infonav_gym.envs.traits``); whether every robot acts at once
from the registry's ``api`` (``infonav_gym.registry``).
"""

from __future__ import annotations

from tqdm.auto import tqdm

from agents.ray_support import import_ray
from infonav_gym.compiled import INTERRUPTIONS, pressed_ctrl_c
from infonav_gym.envs.traits import episode_metrics_of, traits_of
from infonav_gym.experiments.episode_pool import EpisodeRunner, check_positive, played
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
    except INTERRUPTIONS as error:
        if not pressed_ctrl_c(error):
            raise
        played_agents = {name: result for name, result in results["agents"].items() if result["episodes"]}
        seeds_played = max(map(len, (result["episodes"] for result in played_agents.values())), default=0)
        results.update(interrupted=True, agents=played_agents, seeds=seeds[:seeds_played])
    finally:
        bar.close()
        runner.close()
    for result in results["agents"].values():
        result["summary"] = {
            metric.name: summary_of(metric, [e[metric.name] for e in result["episodes"]]) for metric in declared
        }
    if results.get("interrupted"):
        raise Interrupted(f"interrupted after {finished} of {len(tasks)} episodes", results)
    return results
