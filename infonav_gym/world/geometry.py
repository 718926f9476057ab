"""Plane geometry shared by the scenario and terrain builders."""

from __future__ import annotations

import numpy as np


def distance_to_loop(point, loop) -> float:
    """Shortest distance [m] from ``point`` (2,) to the closed polyline ``loop`` (W, 2); one vertex is a point."""
    starts = np.asarray(loop, dtype=float).reshape(-1, 2)
    point = np.asarray(point, dtype=float)
    direction = np.roll(starts, -1, axis=0) - starts
    length_sq = np.einsum("ij,ij->i", direction, direction)
    along = np.einsum("ij,ij->i", point - starts, direction)
    t = np.clip(np.divide(along, length_sq, out=np.zeros_like(along), where=length_sq > 0), 0, 1)
    return float(np.min(np.linalg.norm(starts + t[:, None] * direction - point, axis=1)))
