"""The rule of thumb of range sensing: fuse the reading of the nearest target (the smallest range error)."""

from __future__ import annotations

import numpy as np

from infonav_gym.decisions import argmax_tied

RANGE_KEY = "action_range_m"  # the info key of each action's measured range [m] (0: no reading)


class NearestAgent:
    """The valid action whose reading has the smallest measured range (``info["action_range_m"]``; near-ties: lowest
    index); ``noop_action`` when no reading is valid."""

    def __init__(self, noop_action: int = 0):
        self.noop_action = noop_action

    def reset(self, seed: int | None = None) -> None:
        """Stateless and deterministic: nothing to reset."""

    def act(self, observation, info: dict) -> int:
        try:
            ranges = np.asarray(info[RANGE_KEY], dtype=float)
        except KeyError:
            raise ValueError(f'NearestAgent needs info["{RANGE_KEY}"] from the env') from None
        usable = (ranges > 0) & np.asarray(info.get("action_mask", np.ones(ranges.shape)), dtype=bool)
        return argmax_tied(np.where(usable, -ranges, -np.inf)) if usable.any() else self.noop_action
