"""``FirstCopyView``: sub-env 0 of a native vector env replayed in its single env, for ``render()``.

A vector env keeps its state on stacked arrays, not in drawable objects. With a ``render_mode`` it keeps a
single env in step with sub-env 0 instead: every episode of sub-env 0 starts the single env from a copy of
the same generator, and each of its actions is replayed there, so (the vector env having the single env's
numbers) the single env draws exactly what sub-env 0 does. It costs one single-env step per vector step,
only when rendering.
"""

from __future__ import annotations

import copy

import gymnasium as gym
import numpy as np


class FirstCopyView:
    """A single env that follows sub-env 0 of a vector env; ``render()`` draws it.

    Args:
        single: the single env, built with the vector env's ``render_mode`` and config.
    """

    def __init__(self, single: gym.Env):
        self._single = single

    def restart(self, np_random: np.random.Generator) -> None:
        """Sub-env 0 starts an episode from ``np_random`` (before drawing from it): start the same one."""
        self._single.np_random = copy.deepcopy(np_random)
        self._single.reset()

    def step(self, action) -> None:
        """Sub-env 0 took ``action``."""
        self._single.step(action)

    def render(self):
        return self._single.render()

    def close(self) -> None:
        self._single.close()
