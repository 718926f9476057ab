"""DAgger (Ross, Gordon and Bagnell 2011) for ``infonav clone --dagger``: the planner's labels on the states the clone
itself reaches. Round 0 clones the dataset; in each later round the latest policy drives episodes on fresh seeds while
the planner labels every robot's decision, the labels join all earlier ones and a new policy is fitted to them all, so
it learns what to do after its own errors, which the planner's own episodes never show it (covariate shift)."""

from __future__ import annotations

import json
import time
from functools import partial
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from agents.base import torch_threads
from agents.imitation import Demonstrations, agreement, planner_demonstrations
from agents.ppo import MODEL_FILE, PPOAgent, load_model, load_normalization, model_file, train, training_vec_env
from agents.validation import VALIDATION_SEEDS, validation_metrics
from infonav_gym.compiled import INTERRUPTIONS, pressed_ctrl_c
from infonav_gym.decisions import argmax_tied
from infonav_gym.experiments.paths import Interrupted

DAGGER_SEEDS = 5_000_000  # round r drives seeds DAGGER_SEEDS + seed + (r - 1) * episodes ..: none that is evaluated
ROUND_DIR = "round_{}"  # OUTPUT/round_R holds round R's policy; the last round's is OUTPUT itself
RECORD_FILE = "dagger.json"  # OUTPUT/dagger.json: every finished round, rewritten after each


def dagger(
    env_id: str,
    env_kwargs: dict,
    demonstrations,
    rounds: int,
    episodes: int,
    output: Path | str,
    seed: int = 0,
    gamma: float = 0.99,
    workers: int = 1,
    validation_episodes: int = 10,
    progress: bool = True,
) -> Path:
    """Clone ``demonstrations`` (``agents.imitation.Demonstrations``), then ``rounds`` DAgger rounds of ``episodes``
    planner-labelled episodes each (played in ``workers`` processes); each policy is saved as ``infonav train`` saves
    one and validated on ``validation_episodes`` seeds from ``VALIDATION_SEEDS + seed`` (the env's main metric).
    Returns the last policy's model path (``output/model.zip``); ``output/dagger.json`` records the rounds and the one
    best on validation (``best_round``: DAgger returns that policy). Ctrl-C keeps the finished rounds and raises
    ``Interrupted``."""
    if rounds < 1 or episodes < 1 or workers < 1 or validation_episodes < 0:
        raise ValueError(
            "DAgger needs rounds >= 1, episodes >= 1, workers >= 1 and validation episodes >= 0, got "
            f"{rounds}, {episodes}, {workers} and {validation_episodes}"
        )
    output = Path(output)
    record = {"rounds": rounds, "episodes_per_round": episodes, "validation_episodes": validation_episodes, "done": []}
    policy = None
    try:
        for round_index in tqdm(range(rounds + 1), desc="DAgger rounds", unit="round", disable=not progress):
            start, done = time.perf_counter(), {"round": round_index}
            if policy is not None:
                first = DAGGER_SEEDS + seed + (round_index - 1) * episodes
                labels = planner_demonstrations(
                    env_id, episodes, first, gamma, env_kwargs, workers, progress, partial(PPOAgent, policy)
                )
                record["done"][-1]["agreement_on_own_states"] = _agreement(policy, labels)
                demonstrations = Demonstrations.joined([demonstrations, labels])
                done |= {"seeds": f"{first}..{first + episodes - 1}", "labelled_rows": len(labels.actions)}
            labelled = time.perf_counter()
            policy = output if round_index == rounds else output / ROUND_DIR.format(round_index)
            train(
                env_id,
                0,
                seed,
                output_dir=policy,
                env_kwargs=env_kwargs,
                init_from_planner=demonstrations,
                progress=False,
            )
            fitted = time.perf_counter()
            done |= {
                "model": str(policy),
                "rows": len(demonstrations.actions),
                "agreement_fitted": json.loads((policy / "train.json").read_text())["warm_start"]["agreement"],
                "validation_mean": _validation_mean(env_id, env_kwargs, policy, validation_episodes, seed),
                "labelling_seconds": labelled - start,
                "fitting_seconds": fitted - labelled,
                "validation_seconds": time.perf_counter() - fitted,
            }
            record["done"].append(done)
            if validation_episodes:  # DAgger's answer: the policy best on validation (ties: the earliest)
                record["best_round"] = argmax_tied([entry["validation_mean"] for entry in record["done"]])
            (output / RECORD_FILE).write_text(json.dumps(record, indent=2) + "\n")
    except INTERRUPTIONS as error:
        if not pressed_ctrl_c(error):
            raise
        record["interrupted"] = True
        output.mkdir(parents=True, exist_ok=True)
        (output / RECORD_FILE).write_text(json.dumps(record, indent=2) + "\n")
        kept = f"the policies of rounds 0..{len(record['done']) - 1} are in {output}" if record["done"] else "nothing"
        raise Interrupted(f"interrupted in DAgger round {len(record['done'])}; kept {kept}", record) from None
    return output / MODEL_FILE


def _loaded(policy: Path):
    """The model saved in ``policy`` and its ``VecNormalize`` statistics (``None`` without)."""
    return load_model(policy), load_normalization(model_file(policy))


def _agreement(policy: Path, labels) -> float:
    """How often the policy in ``policy`` chooses the planner's label."""
    model, normalization = _loaded(policy)
    return agreement(model, labels, normalization)


def _validation_mean(env_id: str, env_kwargs: dict, policy: Path, episodes: int, seed: int) -> float | None:
    """The mean main metric of the policy in ``policy`` on ``episodes`` validation seeds (``None`` for 0)."""
    if not episodes:
        return None
    model, normalization = _loaded(policy)
    copies = training_vec_env(env_id, episodes, 0, env_kwargs)[1]
    try:
        with torch_threads():
            return float(np.mean(validation_metrics(model, copies, episodes, VALIDATION_SEEDS + seed, normalization)))
    finally:
        copies.close()
