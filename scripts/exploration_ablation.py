"""What each attempt at matching the planner on ``cooperative_exploration_v0`` reached: the ablation table.

Reads the committed 50-seed evaluations (``results/cooperative_exploration*.json``) and each model's ``train.json``
(its config, env steps, wall time, warm start and validation), plays each PPO model on ``FRESH_EPISODES`` further
seeds (from ``FRESH_SEEDS``: neither the evaluations', the demonstrations' nor the validations'; a native vector
env, ``agents.validation.validation_metrics``; the planner's, too slow to play here, on the first of them from the
committed ``FURTHER_EVALUATION``), times every agent's decisions in this process (milliseconds per
robot and step, over the first ``--steps`` steps of seeds 0 and 1), tabulates the validations of every run that kept
its best policy (``results/models/*`` and ``results/exploration_runs/*``, the runs whose models are not committed)
and writes ``results/cooperative_exploration_ablation.md``.

    python scripts/exploration_ablation.py   # about three minutes on 2 cores
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import numpy as np

from agents.learning_curve import VALIDATION_CSV, read_validations
from agents.ppo import load_model, load_normalization, model_file, training_vec_env
from agents.validation import validation_metrics
from infonav_gym.experiments.episodes import make_team_agents, parallel_episode_infos
from infonav_gym.experiments.intervals import ProportionSummary, interval_cell
from infonav_gym.registry import make_env

ENV_ID = "cooperative_exploration_v0"
RESULTS = Path("results")
RUNS = (RESULTS / "models", RESULTS / "exploration_runs")  # runs with a train.json; exploration_runs: no model
FRESH_SEEDS, FRESH_EPISODES = 3_000_000, 1000
FURTHER_EVALUATION = "cooperative_exploration_further_seeds.json"  # the planner on further seeds: too slow to play here
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
    (
        "behaviour cloning of the planner alone (no PPO), `observe_gains=True`",
        "cooperative_exploration_best.json",
        "ppo:results/models/cooperative_exploration_bc",
    ),
    *(
        (
            f"PPO, `observe_gains=True`, gamma {gamma}, the best of its validations",
            "cooperative_exploration_best.json",
            f"ppo:results/models/cooperative_exploration_ppo_gamma{tag}/best",
        )
        for gamma, tag in (("0.9", "090"), ("0.8", "080"))
    ),
    (
        "PPO, `observe_gains=True`, gamma 0.8, learning rate annealed to 0 (`lin_3e-4`), the best of its validations",
        "cooperative_exploration_best.json",
        "ppo:results/models/cooperative_exploration_ppo_gamma080_lin/best",
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
    """The model's env steps, wall time, warm start and validation, from its run's train.json; empty for a
    baseline. A policy kept on validation seeds (``OUTPUT/best``) reads the train.json of its run (``OUTPUT``)."""
    if not agent_name.startswith("ppo:"):
        return ""
    model = Path(agent_name[4:])
    run = model.parent if not (model / "train.json").is_file() else model
    record = json.loads((run / "train.json").read_text())
    text = (
        f"{record['timesteps'] / 1e6:.1f}M robot steps, {record['seconds'] / 60:.0f} min"
        if record["timesteps"]
        else "no PPO"
    )
    start = record.get("warm_start")
    if start:
        minutes = (start["demonstration_seconds"] + start["cloning_seconds"]) / 60
        text += (
            f" + {len(start['seeds'])} planner episodes cloned ({start['agreement']:.0%} agreement, {minutes:.0f} min)"
        )
    kept = record.get("validation")
    if kept and run != model:
        text += (
            f"; kept: the best of its validations on {kept['episodes']} seeds, success {kept['best_metric']:.2f} "
            f"after {kept['best_steps'] / 1e6:.2f}M"
        )
    return text


def fresh_success(agent_name: str, env_kwargs: dict) -> str:
    """A PPO model's success rate [Wilson 95%] over ``FRESH_EPISODES`` seeds from ``FRESH_SEEDS``, deterministic as
    ``infonav evaluate`` plays it; a baseline's from ``committed_further_success``."""
    if not agent_name.startswith("ppo:"):
        return committed_further_success(agent_name)
    path = Path(agent_name[4:])
    copies = training_vec_env(ENV_ID, FRESH_EPISODES, 0, env_kwargs)[1]
    successes = validation_metrics(
        load_model(path), copies, FRESH_EPISODES, FRESH_SEEDS, load_normalization(model_file(path))
    )
    copies.close()
    return interval_cell(ProportionSummary.of(successes).as_dict())


def committed_further_success(agent_name: str) -> str:
    """An agent's success rate in the committed ``FURTHER_EVALUATION`` (seeds from ``FRESH_SEEDS``) and how many of
    those seeds it played; empty when it is not there."""
    further = json.loads((RESULTS / FURTHER_EVALUATION).read_text())
    if agent_name not in further["agents"] or further["seeds"][0] != FRESH_SEEDS:
        return ""
    success = interval_cell(further["agents"][agent_name]["summary"]["success_rate"])
    return f"{success} (the first {further['episodes']}: `{FURTHER_EVALUATION.removesuffix('.json')}.md`)"


def validation_rows() -> list[str]:
    """A row per run that kept its best policy on validation seeds: its config, steps and validations."""
    rows = []
    for record_path in sorted(path for runs in RUNS for path in runs.glob("*/train.json")):
        record = json.loads(record_path.read_text())
        kept = record.get("validation")
        if record["env_id"] != ENV_ID or not kept:
            continue
        last_metric = read_validations(record_path.parent / VALIDATION_CSV)[-1, 1]
        gamma = record["constructor"]["gamma"]
        rate = record["hyperparameters"].get("learning_rate", record["constructor"]["learning_rate"])
        start = "cloned planner" if record.get("warm_start") else ""
        rows.append(
            f"| {record_path.parent.relative_to(RESULTS)} | {gamma} | {rate} | {record['seed']} | {start} | "
            f"{record['timesteps'] / 1e6:.2f}M, {record['seconds'] / 60:.0f} min | {kept['episodes']} | "
            f"{kept['best_metric']:.3f} after {kept['best_steps'] / 1e6:.2f}M | {last_metric:.3f} |"
        )
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=25, help="steps of each timed episode (default: 25)")
    args = parser.parse_args(argv)
    head = "| attempt | success rate | robot lost rate | final coverage | episode length [steps] | training |"
    lines = [
        head + f" success on {FRESH_EPISODES} further seeds | decision [ms per robot-step] |",
        "|" + " --- |" * 8,
    ]
    for attempt, file, agent_name in ATTEMPTS:
        results = json.loads((RESULTS / file).read_text())
        agent = next(name for name in results["agents"] if name.rstrip("/").removesuffix("/model.zip") == agent_name)
        cells = [interval_cell(results["agents"][agent]["summary"][key]) for key in METRICS]
        fresh = fresh_success(agent_name, results["env_kwargs"])
        ms = decision_ms(agent_name, results["env_kwargs"], args.steps)
        lines.append(f"| {attempt} | " + " | ".join(cells) + f" | {training(agent_name)} | {fresh} | {ms:.3g} |")
    runs = [
        "| run | gamma | learning rate | seed | warm start | trained | validation seeds | best validation success | "
        "last validation success |",
        "|" + " --- |" * 9,
        *validation_rows(),
    ]
    text = "\n".join(lines)
    (RESULTS / "cooperative_exploration_ablation.md").write_text(
        f"# {ENV_ID}: what each attempt at matching the planner reached (50 seeds, 0..49)\n\n{text}\n\n"
        "Each cell: the committed evaluation's mean ± Student t half-width, or rate [Wilson 95% interval]; "
        f"further seeds: {FRESH_SEEDS}..{FRESH_SEEDS + FRESH_EPISODES - 1}, played here with the deterministic policy; "
        f"decision times measured on this machine over the first {args.steps} steps of seeds 0 and 1.\n\n"
        "## Keeping the best policy on validation seeds\n\n"
        "Runs of `infonav train --eval-episodes K` (`observe_gains=True`): the deterministic policy's success on "
        "K validation seeds (from 2,000,000 + the seed), validated every 32,768 to 196,608 robot steps; the best "
        "is kept in the run's `best/`. Runs under `exploration_runs/` keep their records, not their models.\n\n"
        + "\n".join(runs)
        + "\n\nRegenerate with:\n\n    python scripts/exploration_ablation.py\n"
    )
    print(text + "\n\n" + "\n".join(runs))


if __name__ == "__main__":
    main()
