"""Compiled teammate conflicts of ``world.clearance``: the closest approach of two straight moves, pair by pair.

The operations and their order are ``teammate_conflicts``'s numpy expressions (``sqrt(dx * dx + dy * dy)`` for a
norm, ``min(max(t, 0), 1)`` for a clip; a NaN compares false), so the conflicts are the same booleans.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import kernel


@kernel
def teammate_conflicts(positions, displacements, contact_m):
    """Which pairs of moves bring two robots closer than ``contact_m`` [m] (N, R, M, R, M) bool (see
    ``clearance.teammate_conflicts``): positions (N, R, 2) [m], displacements (N, R, M, 2) [m]."""
    n_copies, n_robots, n_moves = displacements.shape[0], displacements.shape[1], displacements.shape[2]
    conflicts = np.zeros((n_copies, n_robots, n_moves, n_robots, n_moves), dtype=np.bool_)
    reach = np.empty(n_robots)
    contact_sq = contact_m * contact_m
    for copy in range(n_copies):
        for robot in range(n_robots):
            longest = -np.inf
            for move in range(n_moves):
                dx, dy = displacements[copy, robot, move, 0], displacements[copy, robot, move, 1]
                longest = max(longest, dx * dx + dy * dy)
            reach[robot] = math.sqrt(longest)
        for i in range(n_robots):
            for j in range(n_robots):
                offset_x = positions[copy, j, 0] - positions[copy, i, 0]
                offset_y = positions[copy, j, 1] - positions[copy, i, 1]
                gap = math.sqrt(offset_x * offset_x + offset_y * offset_y)
                if i == j or not gap < contact_m + reach[i] + reach[j]:  # farther apart: they can never meet
                    continue
                for move_i in range(n_moves):
                    for move_j in range(n_moves):
                        relative_x = displacements[copy, j, move_j, 0] - displacements[copy, i, move_i, 0]
                        relative_y = displacements[copy, j, move_j, 1] - displacements[copy, i, move_i, 1]
                        length_sq = relative_x * relative_x + relative_y * relative_y
                        along = -(offset_x * relative_x + offset_y * relative_y)
                        t = along / (length_sq if length_sq > 0.0 else 1.0)
                        if t < 0.0:
                            t = 0.0
                        elif t > 1.0:
                            t = 1.0
                        closest_x, closest_y = offset_x + t * relative_x, offset_y + t * relative_y
                        conflicts[copy, i, move_i, j, move_j] = (
                            closest_x * closest_x + closest_y * closest_y < contact_sq
                        )
    return conflicts
