"""What each attempt at matching the planner on ``cooperative_exploration_v0`` reached: the ablation table.

Reads the committed 50-seed evaluations (``results/cooperative_exploration*.json``) and each model's ``train.json``
(its config, env steps, wall time and warm start), times every agent's decisions in this process (milliseconds
per robot and step, over the first ``--steps`` steps of seeds 0 and 1) and writes
``results/cooperative_exploration_ablation.md``.

    python scripts/exploration_ablation.py   # about a minute (the planner's decisions are most of it)
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import numpy as np

from infonav_gym.experiments.episodes import make_team_agents, parallel_episode_infos
from infonav_gym.experiments.intervals import interval_cell
from infonav_gym.registry import make_env

ENV_ID = "cooperative_exploration_v0"
RESULTS = Path("results")
ATTEMPTS = (  # (what was tried, the evaluation file, the agent in it)
    ("greedy (immediate gains)", "cooperative_exploration.json", "greedy"),
    ("planner (20-step look-ahead search)", "cooperative_exploration.json", "planner"),
    ("PPO, default observation", "cooperative_exploration_ppo.json", "ppo:results/models/cooperative_exploration_ppo"),
    (
        "PPO, `observe_gains=True`",
        "cooperative_exploration_gains.json",
        "ppo:results/models/cooperative_exploration_ppo_gains",
    ),
    (
        "PPO, `observe_gains=True`, warm start: cloned planner",
        "cooperative_exploration_gains.json",
        "ppo:results/models/cooperative_exploration_ppo_planner",
    ),
)
METRICS = ("success_rate", "failure_rate", "final_coverage", "episode_steps")


class TimedAgent:
    """An agent whose ``act`` calls are timed (seconds, appended to ``times``)."""

    def __init__(self, agent, times: list):
        self.agent, self.times = agent, times

    def reset(self, seed=None) -> None:
        self.agent.reset(seed=seed)

    def act(self, observation, info):
        start = time.perf_counter()
        action = self.agent.act(observation, info)
        self.times.append(time.perf_counter() - start)
        return action


def decision_ms(agent_name: str, env_kwargs: dict, steps: int) -> float:
    """The mean milliseconds one robot's agent takes to decide, over the first ``steps`` steps of seeds 0 and 1,
    played as ``infonav evaluate`` plays them (``parallel_episode_infos``)."""
    env, times = make_env(ENV_ID, **env_kwargs), []
    agents = {robot: TimedAgent(agent, times) for robot, agent in make_team_agents(agent_name, env).items()}
    for seed in (0, 1):
        for _ in itertools.islice(parallel_episode_infos(env, agents, seed), steps + 1):
            pass  # the reset's infos, then a step each
    env.close()
    return 1000 * float(np.mean(times))


def training(agent_name: str) -> str:
    """The model's env steps, wall time and warm start, from its train.json; empty for a baseline."""
    if not agent_name.startswith("ppo:"):
        return ""
    record = json.loads((Path(agent_name[4:]) / "train.json").read_text())
    text = f"{record['timesteps'] / 1e6:.1f}M robot steps, {record['seconds'] / 60:.0f} min"
    start = record.get("warm_start")
    if start:
        minutes = (start["demonstration_seconds"] + start["cloning_seconds"]) / 60
        text += (
            f" + {len(start['seeds'])} planner episodes cloned ({start['agreement']:.0%} agreement, {minutes:.0f} min)"
        )
    return text


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=25, help="steps of each timed episode (default: 25)")
    args = parser.parse_args(argv)
    head = "| attempt | success rate | robot lost rate | final coverage | episode length [steps] | training |"
    lines = [head + " decision [ms per robot-step] |", "|" + " --- |" * 7]
    for attempt, file, agent_name in ATTEMPTS:
        results = json.loads((RESULTS / file).read_text())
        agent = next(name for name in results["agents"] if name.rstrip("/").removesuffix("/model.zip") == agent_name)
        cells = [interval_cell(results["agents"][agent]["summary"][key]) for key in METRICS]
        ms = decision_ms(agent_name, results["env_kwargs"], args.steps)
        lines.append(f"| {attempt} | " + " | ".join(cells) + f" | {training(agent_name)} | {ms:.3g} |")
    text = "\n".join(lines)
    (RESULTS / "cooperative_exploration_ablation.md").write_text(
        f"# {ENV_ID}: what each attempt at matching the planner reached (50 seeds, 0..49)\n\n{text}\n\n"
        "Each cell: the committed evaluation's mean ± Student t half-width, or rate [Wilson 95% interval]; decision "
        f"times measured on this machine over the first {args.steps} steps of seeds 0 and 1.\n\n"
        "Regenerate with:\n\n    python scripts/exploration_ablation.py\n"
    )
    print(text)


if __name__ == "__main__":
    main()
