"""The reference of an env whose one action observes everything at once (``traits.everything_action``: register
every return of a scan): take it whenever it is valid."""

from __future__ import annotations

import numpy as np


class EverythingAgent:
    """``action`` (the env's ``everything_action``) whenever the mask allows it, else ``noop_action``."""

    def __init__(self, action: int, noop_action: int = 0):
        self.action, self.noop_action = int(action), int(noop_action)

    def reset(self, seed: int | None = None) -> None:
        """Stateless and deterministic: nothing to reset."""

    def act(self, observation, info: dict) -> int:
        mask = np.asarray(info.get("action_mask", ()), dtype=bool)
        return self.action if mask.size == 0 or mask[self.action] else self.noop_action
