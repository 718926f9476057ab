"""A vehicle's 3D attitude on a 2.5D terrain and the rigid transforms between frames.

Frames: the body frame has x forward, y left, z up. ``rotation_matrix(roll, pitch, yaw)``
is ``Rz(yaw) Ry(pitch) Rx(roll)``, each a right-handed rotation about the named axis, so a
positive pitch lowers the nose and a positive roll raises the left side. Transforms are
(4, 4) homogeneous matrices; ``A_from_B`` maps points of frame B into frame A.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.world.terrain import Terrain

WHEELBASE_M = 2.5  # front to rear axle of the XUV-sized vehicle [m]
TRACK_M = 1.8  # left to right wheels [m]


def rotation_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (3, 3)."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def rigid_transform(rotation, translation) -> np.ndarray:
    """The (4, 4) transform ``x -> rotation @ x + translation``."""
    transform = np.eye(4)
    transform[:3, :3] = rotation
    transform[:3, 3] = translation
    return transform


def invert_transform(transform: np.ndarray) -> np.ndarray:
    """Inverse of a rigid (4, 4) transform, in closed form."""
    rotation = transform[:3, :3].T
    return rigid_transform(rotation, -rotation @ transform[:3, 3])


def transform_points(transform: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points`` (N, 3) mapped by the rigid ``transform``."""
    return points @ transform[:3, :3].T + transform[:3, 3]


def rotation_angle(rotation: np.ndarray) -> float:
    """Angle [rad] of a (3, 3) rotation matrix, in [0, pi]; accurate near 0 (unlike ``arccos`` of the trace)."""
    axis = (rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0], rotation[1, 0] - rotation[0, 1])
    return math.atan2(0.5 * math.hypot(*axis), 0.5 * (rotation[0, 0] + rotation[1, 1] + rotation[2, 2] - 1.0))


def transform_error(estimate: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """``(translation error [m], rotation error [rad])`` of a (4, 4) ``estimate`` against ``truth``."""
    translation = float(np.linalg.norm(estimate[:3, 3] - truth[:3, 3]))
    return translation, rotation_angle(estimate[:3, :3].T @ truth[:3, :3])


def terrain_attitude(
    terrain: Terrain, vehicle_pose, wheelbase_m: float = WHEELBASE_M, track_m: float = TRACK_M
) -> tuple[float, float]:
    """``(roll, pitch)`` [rad] of a vehicle at ``[x, y, heading]`` standing on ``terrain``.

    The ground is sampled under the front and rear axle midpoints and the left and right
    wheel midpoints; pitch follows the front-rear height difference over the wheelbase and
    roll the left-right difference over the track.
    """
    x, y, heading = (float(value) for value in vehicle_pose)
    forward = np.array([math.cos(heading), math.sin(heading)])
    left = np.array([-forward[1], forward[0]])
    center = np.array([x, y])
    front, rear, left_side, right_side = terrain.height_at(
        np.array(
            [
                center + forward * wheelbase_m / 2,
                center - forward * wheelbase_m / 2,
                center + left * track_m / 2,
                center - left * track_m / 2,
            ]
        )
    )
    pitch = -math.atan2(front - rear, wheelbase_m)
    roll = math.atan2(left_side - right_side, track_m)
    return roll, pitch
