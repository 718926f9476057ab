"""``BenchMARLAgent``: a robot of a team env acting with the actor ``infonav train --backend benchmarl`` trained,
deterministically: the masked argmax of its logits (the mode of BenchMARL's masked categorical policy)."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
from gymnasium.spaces import Discrete

from agents.base import checked_action_count, trained_elsewhere, usable_mask

MARL_HINT = 'pip install "infonav-gym[marl]"'


def import_benchmarl_training():
    """``agents.benchmarl_train``, or ``ValueError`` saying which extra installs BenchMARL and TorchRL."""
    try:
        from agents import benchmarl_train
    except ImportError as error:
        raise ValueError(f"BenchMARL agents need the marl extra ({MARL_HINT}): {error}") from None
    return benchmarl_train


class BenchMARLAgent:
    """Robot ``agent`` of PettingZoo team env ``env`` played by the actor of a BenchMARL training directory
    (``train.json`` + ``actor.pt``); ``ValueError`` without the marl extra, for a directory that is not one, or for an
    actor trained on another env (naming it) or with other spaces or team size."""

    def __init__(self, directory: Path | str, env, agent: str | None = None):
        training = import_benchmarl_training()
        directory = Path(directory)
        record_path, actor_path = directory / "train.json", directory / training.ACTOR_FILE
        if not record_path.is_file() or not actor_path.is_file():
            raise ValueError(
                f"{str(directory)!r} is not a BenchMARL training directory (no train.json and {training.ACTOR_FILE}): "
                "write one with infonav train --backend benchmarl --output DIR"
            )
        record = json.loads(record_path.read_text())
        actor, where = record["actor"], f"BenchMARL actor in {str(directory)!r} (env {record['env_id']!r})"
        robots = list(getattr(env, "possible_agents", []))
        if agent not in robots or len(robots) != actor["n_agents"]:
            team = f"robots {robots}" if robots else "one robot (a single-agent env)"
            raise trained_elsewhere(where, f"a team of {actor['n_agents']} robots", team, agent)
        self.n_actions = checked_action_count(
            where, tuple(actor["observation_shape"]), Discrete(actor["n_actions"]), env, agent
        )
        model, loc_scale = training.load_actor(record, actor_path), training.observation_standardization(record)
        self.logits = functools.partial(training.robot_logits, model, robots.index(agent), *loc_scale)

    def reset(self, seed: int | None = None) -> None:
        """Deterministic: nothing to reset."""

    def act(self, observation, info: dict) -> int:
        mask = usable_mask(info.get("action_mask"), self.n_actions)
        return int(np.argmax(np.where(mask, self.logits(observation), -np.inf)))
