"""``RLlibAgent``: a policy trained by ``infonav train --backend rllib`` acting greedily among the valid actions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch

from agents.base import checked_action_count, env_name, trained_elsewhere
from agents.ray_support import import_ray
from agents.rllib_masking import ACTION_MASK, OBSERVATION, mask_observation
from agents.rllib_train import CHECKPOINT_DIR, SHARED_POLICY

SINGLE_AGENT_POLICY = "default_policy"  # RLlib's module id of a single-agent algorithm
MODULES_PATH = ("learner_group", "learner", "rl_module")  # where an algorithm checkpoint keeps its modules


class RLlibAgent:
    """The policy of an RLlib training directory (``train.json`` + ``checkpoint/``) as a deterministic agent in ``env``
    (for robot ``agent`` of a PettingZoo env); ``ValueError`` without Ray, for a directory without ``train.json`` or
    checkpoint, or for a policy trained on an env that does not fit this one (naming it) or with other spaces."""

    def __init__(self, directory: Path | str, env, agent: str | None = None):
        import_ray()  # a missing extra: a one-line ValueError saying what to install
        directory = Path(directory).resolve()  # RLlib opens checkpoints by absolute URI
        record_path = directory / "train.json"
        if not record_path.is_file() or not (directory / CHECKPOINT_DIR).is_dir():
            raise ValueError(
                f"{str(directory)!r} is not an RLlib training directory (no train.json and {CHECKPOINT_DIR}/): "
                "write one with infonav train --backend rllib --output DIR"
            )
        record = json.loads(record_path.read_text())
        shared = record.get("policies") == "shared"  # the module a robot (agent) or a single-agent env acts with
        policy = SINGLE_AGENT_POLICY if agent is None else SHARED_POLICY if shared else agent
        modules = directory.joinpath(CHECKPOINT_DIR, *MODULES_PATH)
        trained_on = f"env {record.get('env_id')!r}"
        if not (modules / policy).is_dir():  # a team's policies in a single-agent env, or the reverse
            found = ", ".join(sorted(path.name for path in modules.iterdir())) if modules.is_dir() else "none"
            raise trained_elsewhere(
                f"RLlib training directory {str(directory)!r}",
                f"{trained_on} (policies: {found})",
                f"id {env_name(env)!r} (policy {policy!r})",
                agent,
            )
        from ray.rllib.core.rl_module.rl_module import RLModule

        self.module = RLModule.from_checkpoint(modules / policy)
        self.module.eval()
        self.n_actions = checked_action_count(
            f"RLlib policy {policy!r} in {str(directory)!r} ({trained_on})",
            self.module.observation_space[OBSERVATION].shape,
            self.module.action_space,
            env,
            agent,
        )

    def reset(self, seed: int | None = None) -> None:
        """Deterministic: nothing to reset."""

    def act(self, observation, info: dict) -> int:
        mask = mask_observation(info.get(ACTION_MASK), self.n_actions)
        observation = torch.as_tensor(np.asarray(observation, dtype=np.float32))[None]
        batch = {"obs": {OBSERVATION: observation, ACTION_MASK: torch.as_tensor(mask)[None]}}
        with torch.no_grad():
            logits = self.module.forward_inference(batch)["action_dist_inputs"][0].numpy()
        return int(np.argmax(np.where(mask > 0, logits, -np.inf)))
