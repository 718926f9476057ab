"""Which straight moves keep a team's robots out of contact: with walls, obstacles and whatever teammates choose.

Each robot moves straight by one of M displacements over the same interval. A *clear* move's swept disc keeps
``clearance_m`` off walls and obstacles and comes within ``2 r + clearance_m`` of no teammate for any of its
moves. Move 0 (none) is always clear, so any combination of clear moves is contact-free.
"""

from __future__ import annotations

import numpy as np

from infonav_gym.world import clearance_kernels
from infonav_gym.world.visibility import StaticGeometry, swept_discs_clear

CLEARANCE_M = 0.05  # the gap a clear move keeps from walls, obstacles and teammates [m]


def teammate_conflicts(positions: np.ndarray, displacements: np.ndarray, contact_m: float) -> np.ndarray:
    """Which pairs of moves (``displacements`` (N, R, M, 2) from ``positions`` (N, R, 2) [m]) bring two robots'
    centres closer than ``contact_m`` at some time (N, R, M, R, M): their offset moves straight from
    ``p_j - p_i`` to ``p_j - p_i + u_j - u_i``. Never a robot with itself."""
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
    """Which of each robot's moves ``displacements`` (N, R, M, 2) [m] from ``positions`` (N, R, 2) are clear (the
    module) (N, R, M) bool; move 0 must be zero."""
    starts = np.broadcast_to(positions[:, :, None], displacements.shape).reshape(len(displacements), -1, 2)
    ends = starts + displacements.reshape(starts.shape)
    clear = swept_discs_clear(geometry, starts, ends, robot_radius_m + clearance_m).reshape(displacements.shape[:3])
    clear &= ~teammate_conflicts(positions, displacements, 2 * robot_radius_m + clearance_m).any(axis=(3, 4))
    clear[..., 0] = True
    return clear
