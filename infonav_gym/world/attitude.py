"""A vehicle's 3D attitude on a 2.5D terrain (body x forward, y left, z up: ``geometry.rotation_matrix``)."""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.world.terrain import Terrain

WHEELBASE_M = 2.5  # front to rear axle of the XUV-sized vehicle [m]
TRACK_M = 1.8  # left to right wheels [m]


def terrain_attitude(
    terrain: Terrain, vehicle_pose, wheelbase_m: float = WHEELBASE_M, track_m: float = TRACK_M
) -> tuple[float, float]:
    """``(roll, pitch)`` [rad] of a vehicle at ``[x, y, heading]`` on ``terrain``: the front-rear height difference
    over the wheelbase, the left-right one over the track."""
    x, y, heading = (float(value) for value in vehicle_pose)
    forward = np.array([math.cos(heading), math.sin(heading)])
    left = np.array([-forward[1], forward[0]])
    half_axes = np.array([forward * wheelbase_m / 2, left * track_m / 2])  # to the front axle, to the left wheels
    front, left_side, rear, right_side = terrain.height_at(np.array([x, y]) + np.concatenate([half_axes, -half_axes]))
    return math.atan2(left_side - right_side, track_m), -math.atan2(front - rear, wheelbase_m)
