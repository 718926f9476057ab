"""``NoiseStreams``: one standard-normal stream per sub-env of a vector env, drawn ahead in blocks.

A numpy ``Generator`` gives the same numbers for ``standard_normal(a + b)`` as for ``standard_normal(a)`` then
``standard_normal(b)``, so drawing a block of many steps' noise at once and handing it out row by row gives
each sub-env exactly the numbers its single env draws one call at a time, while the per-copy Python call
happens once per block instead of once per step.
"""

from __future__ import annotations

import numpy as np

from infonav_gym.compiled import kernel

BLOCK_DRAWS = 64  # draws of ``width`` numbers fetched per copy at a time


class NoiseStreams:
    """Per-copy standard normals: ``take(copies)`` gives each copy its generator's next ``width`` numbers.

    Args:
        n_copies: N >= 1.
        width: numbers per draw (the ``size`` of the single env's ``standard_normal`` call).
        block_draws: draws fetched ahead per copy.
    """

    def __init__(self, n_copies: int, width: int, block_draws: int = BLOCK_DRAWS):
        self._generators: list[np.random.Generator | None] = [None] * n_copies
        self._blocks = np.zeros((n_copies, block_draws, width))
        self._next = np.full(n_copies, block_draws)

    def restart(self, copy: int, generator: np.random.Generator) -> None:
        """Give copy ``copy`` a new stream: a generator that serves only it (numbers are drawn ahead of use)."""
        self._generators[copy] = generator
        self._next[copy] = self._blocks.shape[1]

    def take(self, copies: np.ndarray) -> np.ndarray:
        """The next draw of each of ``copies`` (n, width), distinct copies; exhausted blocks are refilled first.

        Raises:
            RuntimeError: for a copy that has no stream yet (``restart`` it first).
        """
        self._refill(copies[self._next[copies] >= self._blocks.shape[1]])
        draws = self._blocks[copies, self._next[copies]]
        self._next[copies] += 1
        return draws

    def take_many(self, copies: np.ndarray, used: np.ndarray) -> np.ndarray:
        """The next draw of each ``used`` slot (n, M) of ``copies`` (distinct), in slot order: (n, M, width), zeros
        where not used. What a copy's single env draws in one ``standard_normal((k, width))`` call for its k used
        slots, or in k calls of ``width`` in slot order (at most a block's draws per copy).

        Raises:
            RuntimeError: for a copy that has no stream yet (``restart`` it first).
        """
        self._refill(copies[self._next[copies] + used.sum(axis=1) > self._blocks.shape[1]])
        return slot_draws(self._blocks, self._next, copies, used)

    def _refill(self, copies: np.ndarray) -> None:
        """Move each copy's unused draws to the front of its block and fill the rest from its generator."""
        block_draws, width = self._blocks.shape[1:]
        for copy in copies.tolist():
            generator = self._generators[copy]
            if generator is None:
                raise RuntimeError(f"NoiseStreams: copy {copy} has no generator yet; restart() it first")
            unused = block_draws - min(self._next[copy], block_draws)
            self._blocks[copy, :unused] = self._blocks[copy, block_draws - unused :].copy()
            self._blocks[copy, unused:] = generator.standard_normal((block_draws - unused, width))
            self._next[copy] = 0


@kernel
def slot_draws(blocks, next_draw, copies, used):
    """``NoiseStreams.take_many`` from the ``blocks`` (N, B, width), advancing each copy's ``next_draw`` (N,)."""
    draws = np.zeros(used.shape + blocks.shape[2:])
    for k in range(len(copies)):
        for slot in range(used.shape[1]):
            if used[k, slot]:
                draws[k, slot] = blocks[copies[k], next_draw[copies[k]]]
                next_draw[copies[k]] += 1
    return draws
