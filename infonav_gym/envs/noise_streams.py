"""``NoiseStreams``: one standard-normal stream per sub-env of a vector env, drawn ahead in blocks.

A numpy ``Generator`` gives the same numbers for ``standard_normal(a + b)`` as for ``standard_normal(a)`` then
``standard_normal(b)``, so drawing a block of many steps' noise at once and handing it out row by row gives
each sub-env exactly the numbers its single env draws one call at a time, while the per-copy Python call
happens once per block instead of once per step.
"""

from __future__ import annotations

import numpy as np

from infonav_gym.compiled import inline, kernel

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
        self._unused = 0  # draws every copy surely has left in its block

    def restart(self, copy: int, generator: np.random.Generator) -> None:
        """Give copy ``copy`` a new stream: a generator that serves only it (numbers are drawn ahead of use)."""
        self._generators[copy] = generator
        self._next[copy] = self._blocks.shape[1]
        self._unused = 0

    def reserve(self, draws: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """``(blocks, next_draw)`` with ``draws`` (<= the block) unused draws in every copy's block: a kernel takes
        up to that many per copy with ``taken`` (copy ``c``'s next draw is ``blocks[c, next_draw[c]]``).

        Raises:
            RuntimeError: for a copy that has no stream yet (``restart`` it first).
        """
        if self._unused < draws:
            block_draws = self._blocks.shape[1]
            self._refill(np.flatnonzero(self._next + draws > block_draws))
            self._unused = block_draws - int(self._next.max())
        self._unused -= draws
        return self._blocks, self._next

    def take(self, copies: np.ndarray) -> np.ndarray:
        """The next draw of each of ``copies`` (n, width), distinct copies (see ``reserve``)."""
        return self.take_many(copies, np.ones((len(copies), 1), dtype=bool))[:, 0]

    def take_many(self, copies: np.ndarray, used: np.ndarray) -> np.ndarray:
        """The next draw of each ``used`` slot (n, M) of ``copies`` (distinct), in slot order: (n, M, width), zeros
        where not used. What a copy's single env draws in one ``standard_normal((k, width))`` call for its k used
        slots, or in k calls of ``width`` in slot order (M at most a block's draws; see ``reserve``)."""
        return slot_draws(*self.reserve(used.shape[1]), copies, used)

    def _refill(self, copies: np.ndarray) -> None:
        """Move each copy's unused draws to the front of its block and fill the rest from its generator."""
        block_draws = self._blocks.shape[1]
        unused_draws = block_draws - np.minimum(self._next[copies], block_draws)
        for copy, unused in zip(copies.tolist(), unused_draws.tolist()):
            generator = self._generators[copy]
            if generator is None:
                raise RuntimeError(f"NoiseStreams: copy {copy} has no generator yet; restart() it first")
            if unused:
                self._blocks[copy, :unused] = self._blocks[copy, block_draws - unused :].copy()
            generator.standard_normal(out=self._blocks[copy, unused:])
            self._next[copy] = 0


@kernel
def slot_draws(blocks, next_draw, copies, used):
    """``NoiseStreams.take_many`` from the ``blocks`` (N, B, width), advancing each copy's ``next_draw`` (N,)."""
    draws = np.zeros(used.shape + blocks.shape[2:])
    for k in range(len(copies)):
        for slot in range(used.shape[1]):
            if used[k, slot]:  # element by element: an array into a slice compiles numba's shape-error formatting
                draw = taken(blocks, next_draw, copies[k])
                for i in range(len(draw)):
                    draws[k, slot, i] = draw[i]
    return draws


@inline
def taken(blocks, next_draw, copy):
    """Copy ``copy``'s next draw (width,) of a ``NoiseStreams.reserve``d stream, in a kernel; its stream moves on."""
    row = next_draw[copy]
    next_draw[copy] = row + 1
    return blocks[copy, row]
