"""``NoiseStreams``: one standard-normal stream per sub-env of a vector env, drawn ahead in blocks.

A numpy ``Generator`` gives the same numbers for ``standard_normal(a + b)`` as for ``standard_normal(a)`` then
``standard_normal(b)``, so drawing a block of many steps' noise at once and handing it out row by row gives
each sub-env exactly the numbers its single env draws one call at a time, while the per-copy Python call
happens once per block instead of once per step.
"""

from __future__ import annotations

import numpy as np

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

    def take_many(self, copies: np.ndarray, counts: np.ndarray) -> np.ndarray:
        """The next ``counts[k]`` draws of each of ``copies`` (distinct), in copy order: (sum(counts), width).

        What ``counts[k]`` calls of ``take`` give copy ``copies[k]``, in one indexing (``counts`` <= the block).

        Raises:
            RuntimeError: for a copy that has no stream yet (``restart`` it first).
        """
        self._refill(copies[self._next[copies] + counts > self._blocks.shape[1]])
        starts = self._next[copies]
        ends = np.cumsum(counts)
        rows = np.repeat(starts - (ends - counts), counts) + np.arange(ends[-1] if len(ends) else 0)
        draws = self._blocks[np.repeat(copies, counts), rows]
        self._next[copies] += counts
        return draws

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
