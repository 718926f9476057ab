"""Which straight moves keep a team's robots out of contact: with walls, obstacles and whatever teammates choose.

A team whose robots all move straight at once, each by one of M known displacements (from its true position,
over the same interval), stays out of contact if every robot takes a *clear* move: one whose swept disc keeps
``clearance_m`` from every wall and obstacle (``swept_discs_clear``) and comes within ``2 r + clearance_m`` of
no teammate for *any* of the teammate's moves. The first move (no displacement) is always clear, and a
teammate's clear moves keep away from it, so any combination of clear moves is contact-free. Numpy on arrays
with a leading copy dimension; the teammate conflicts are compiled (``clearance_kernels``).
"""

from __future__ import annotations

import numpy as np

from infonav_gym.world import clearance_kernels
from infonav_gym.world.visibility import StaticGeometry, swept_discs_clear

CLEARANCE_M = 0.05  # the gap a clear move keeps from walls, obstacles and teammates [m]


def teammate_conflicts(positions: np.ndarray, displacements: np.ndarray, contact_m: float) -> np.ndarray:
    """Which pairs of moves bring two robots closer than ``contact_m`` [m] at some time (N, R, M, R, M) bool.

    Both robots move at constant velocity over the same interval, so their offset moves straight from
    ``d = p_j - p_i`` to ``d + u_j - u_i``; the pair conflicts if that segment passes within ``contact_m`` of 0.
    A robot never conflicts with itself.

    Args:
        positions: each robot's position at the start (N, R, 2) [m].
        displacements: each robot's M possible displacements (N, R, M, 2) [m].
        contact_m: the distance between centres below which two robots touch [m].
    """
    return clearance_kernels.teammate_conflicts(
        np.ascontiguousarray(positions, dtype=float), np.ascontiguousarray(displacements, dtype=float), float(contact_m)
    )


def clear_moves(
    geometry: StaticGeometry,
    positions: np.ndarray,
    displacements: np.ndarray,
    robot_radius_m: float,
    clearance_m: float = CLEARANCE_M,
) -> np.ndarray:
    """Which of each robot's moves are clear (see the module) (N, R, M) bool; move 0 must be no displacement.

    Args:
        geometry: the static walls and obstacles of the N copies.
        positions: true positions of the R robots of each copy (N, R, 2) [m].
        displacements: each robot's M moves (N, R, M, 2) [m]; ``displacements[..., 0, :]`` is zero (staying).
        robot_radius_m: every robot's radius [m].
        clearance_m: the gap a clear move keeps [m].
    """
    n_copies, n_robots, n_moves = displacements.shape[:3]
    starts = np.broadcast_to(positions[:, :, None], displacements.shape).reshape(n_copies, -1, 2)
    clear = swept_discs_clear(
        geometry, starts, starts + displacements.reshape(n_copies, -1, 2), robot_radius_m + clearance_m
    ).reshape(n_copies, n_robots, n_moves)
    clear &= ~teammate_conflicts(positions, displacements, 2 * robot_radius_m + clearance_m).any(axis=(3, 4))
    clear[..., 0] = True
    return clear
