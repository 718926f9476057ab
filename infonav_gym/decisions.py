"""Decisions over floating-point values that do not flip on rounding: near-ties count as ties, the lowest index wins.

Two CPUs may round values equal in exact arithmetic a few units in the last place apart, in either order; an
argmax would follow the machine. Values within ``DECISION_RTOL`` of the best (floor ``DECISION_ATOL`` near 0)
count as equal to it: rounding moves a step's values by about 1e-14 relative, 1e-9 keeps a wide margin.
"""

from __future__ import annotations

import numpy as np

DECISION_RTOL = 1e-9  # values within this fraction of the best count as tied with it
DECISION_ATOL = 1e-12  # absolute floor of the tie band, for values at or near 0 (in the values' unit)


def tie_threshold(best):
    """The smallest value that counts as tied with ``best``: ``best - (DECISION_RTOL |best| + DECISION_ATOL)``.

    An infinite ``best`` (every value invalid, as -inf) is its own threshold.
    """
    best = np.asarray(best, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(best), best - (DECISION_RTOL * np.abs(best) + DECISION_ATOL), best)


def is_positive(values):
    """Whether ``values`` exceed 0 by more than the tie band's floor (a gain of a few ulps is no gain)."""
    return np.asarray(values) > DECISION_ATOL


def argmax_tied(values, axis: int = -1):
    """The index of the largest value along ``axis``, the lowest index among values tied with it.

    NaN counts as -inf. Returns an int for a 1-D input, else an int array without ``axis``.
    """
    values = np.moveaxis(np.asarray(values, dtype=float), axis, -1)
    index = _first_tied(values, np.ones(values.shape, dtype=bool))
    return int(index) if np.ndim(index) == 0 else index


def top_k_tied(values, k: int, axis: int = -1) -> np.ndarray:
    """The indices of the ``k`` largest values along ``axis``, best first, each pick by ``argmax_tied``'s rule.

    Shape: ``values``' with ``axis`` of length ``min(k, n)``.
    """
    values = np.moveaxis(np.asarray(values, dtype=float), axis, -1)
    untaken = np.ones(values.shape, dtype=bool)
    picks = []
    for _ in range(min(int(k), values.shape[-1])):
        index = _first_tied(values, untaken)
        np.put_along_axis(untaken, index[..., None], False, axis=-1)
        picks.append(index)
    return np.moveaxis(np.stack(picks, axis=-1) if picks else np.zeros((*values.shape[:-1], 0), int), -1, axis)


def descending_tied(values) -> np.ndarray:
    """The indices of 1-D ``values`` from largest to smallest, a run of values each tied with the one before it
    (``tie_threshold``) in index order: an order that last-digit differences between CPUs do not reshuffle."""
    values = np.asarray(values, dtype=float)
    order = np.argsort(-values, kind="stable")
    ordered = values[order]
    new_run = np.concatenate(([True], ordered[1:] < tie_threshold(ordered[:-1])))
    return order[np.lexsort((order, np.cumsum(new_run)))]


def _first_tied(values: np.ndarray, eligible: np.ndarray) -> np.ndarray:
    """The lowest index along the last axis of an ``eligible`` value tied with the best eligible one."""
    values = np.where(eligible & ~np.isnan(values), values, -np.inf)
    best = np.max(values, axis=-1, keepdims=True)
    return np.argmax(eligible & (values >= tie_threshold(best)), axis=-1)
