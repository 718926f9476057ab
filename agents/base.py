"""The agent protocol shared by every baseline."""

from __future__ import annotations

import contextlib
from typing import Any, Protocol, runtime_checkable

import numpy as np

# Torch threads for PPO's small MLPs. On a 2-core CPU a second thread gains nothing for 64 x 64 networks
# (CartPole PPO at 5600 vs 5450 steps/s) and, when another process holds the other core, makes training
# about 20x slower (the threads spin-wait on each other).
TORCH_THREADS = 1


@contextlib.contextmanager
def torch_threads(n_threads: int = TORCH_THREADS):
    """Run the block with ``torch.set_num_threads(n_threads)``; restore the caller's setting after."""
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(n_threads)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


@runtime_checkable
class Agent(Protocol):
    """Chooses actions from what an env returns; keeps no reference to the env itself."""

    def reset(self, seed: int | None = None) -> None:
        """Start a new episode; ``seed`` makes any randomness of the agent reproducible."""

    def act(self, observation: Any, info: dict) -> int:
        """The action for this step, from the last observation and info."""


def valid_actions(info: dict, n_actions: int) -> np.ndarray:
    """Indices of the valid actions per ``info["action_mask"]`` (all of them if there is no mask)."""
    mask = info.get("action_mask")
    if mask is None:
        return np.arange(n_actions)
    mask = np.asarray(mask)
    if mask.shape != (n_actions,):
        raise ValueError(f'info["action_mask"] must have shape ({n_actions},), got {mask.shape}')
    return np.flatnonzero(mask)


def usable_mask(mask, n_actions: int) -> np.ndarray:
    """``mask`` (or None) as (n_actions,) bool; all True when none is valid, as ``MaskablePPO`` takes it."""
    if mask is None:
        return np.ones(n_actions, dtype=bool)
    valid = np.broadcast_to(np.asarray(mask, dtype=bool), (n_actions,))
    return valid if valid.any() else np.ones(n_actions, dtype=bool)


def env_name(env) -> str:
    """The env's registered id (Gymnasium) or ``metadata["name"]`` (PettingZoo), else its class name."""
    spec = getattr(env, "spec", None)
    return spec.id if spec is not None else env.metadata.get("name", type(env.unwrapped).__name__)


def trained_elsewhere(policy: str, trained_for: str, env_has: str, agent: str | None = None) -> ValueError:
    """The error of a trained ``policy`` used in an env (robot ``agent``'s part of it) it does not fit."""
    robot = "" if agent is None else f" ({agent})"
    return ValueError(f"{policy} was trained for {trained_for}, but the env{robot} has {env_has}")


def checked_action_count(policy: str, observation_shape: tuple, action_space, env, agent: str | None = None) -> int:
    """The env's number of actions, once a trained ``policy``'s spaces are seen to match the env's (or robot's);
    ``ValueError`` naming both where they differ."""
    env_obs = env.observation_space if agent is None else env.observation_space(agent)
    env_actions = env.action_space if agent is None else env.action_space(agent)
    if tuple(observation_shape) != env_obs.shape or action_space != env_actions:
        trained_for = f"observations {tuple(observation_shape)} and actions {action_space}"
        raise trained_elsewhere(policy, trained_for, f"{env_obs.shape} and {env_actions}", agent)
    return int(env_actions.n)
