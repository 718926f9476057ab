"""Uniformly random choice among the valid actions."""

from __future__ import annotations

import numpy as np

from agents.base import valid_actions


class RandomAgent:
    """Picks uniformly among the actions ``info["action_mask"]`` allows (any action if none is valid), from its own
    generator (``seed``; ``reset(seed)`` re-seeds it); ``noop_action`` only when nothing else is valid."""

    def __init__(self, n_actions: int, seed: int | None = None, noop_action: int | None = None):
        if n_actions < 1:
            raise ValueError(f"n_actions must be >= 1, got {n_actions}")
        if noop_action is not None and not 0 <= noop_action < n_actions:
            raise ValueError(f"noop_action must be in [0, {n_actions - 1}] or None, got {noop_action}")
        self.n_actions = int(n_actions)
        self.noop_action = noop_action
        self.np_random = np.random.default_rng(seed)

    def reset(self, seed: int | None = None) -> None:
        if seed is not None:
            self.np_random = np.random.default_rng(seed)

    def act(self, observation, info: dict) -> int:
        choices = valid_actions(info, self.n_actions)
        if self.noop_action is not None and choices.size > 1:
            choices = choices[choices != self.noop_action]
        if choices.size == 0:
            return int(self.np_random.integers(self.n_actions))
        return int(choices[self.np_random.integers(choices.size)])
