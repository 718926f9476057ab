"""The paper's selection rule: observe what brings the most information now."""

from __future__ import annotations

import numpy as np

from infonav_gym.decisions import argmax_tied


class GreedyEntropyAgent:
    """Argmax of ``info["action_information_gain"]`` over the valid actions (near-ties: lowest index; none valid: 0)."""

    def reset(self, seed: int | None = None) -> None:
        """Stateless and deterministic: nothing to reset."""

    def act(self, observation, info: dict) -> int:
        try:
            gains = info["action_information_gain"]
        except KeyError:
            raise ValueError('GreedyEntropyAgent needs info["action_information_gain"] from the env') from None
        mask = info.get("action_mask")
        if mask is None:
            return argmax_tied(gains)
        return argmax_tied(np.where(mask, gains, -np.inf)) if np.any(mask) else 0
