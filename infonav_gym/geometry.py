"""Geometry shared by every floor: angles, rigid transforms, distances to polylines.

Transforms are (4, 4) homogeneous matrices; ``A_from_B`` maps points of frame B into frame A.
``rotation_matrix(roll, pitch, yaw)`` is ``Rz(yaw) Ry(pitch) Rx(roll)``, each a right-handed
rotation about the named axis (body frame: x forward, y left, z up).
"""

from __future__ import annotations

import math

import numpy as np


def wrap_angle(angle):
    """Map an angle (a float or an ndarray of them) to [-pi, pi) [rad]."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


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


def distance_to_loop(point, loop) -> float:
    """Shortest distance [m] from ``point`` (2,) to the closed polyline ``loop`` (W, 2); one vertex is a point."""
    return ClosedLoop(loop).distance(point)


class ClosedLoop:
    """A closed polyline (W, 2) [m] whose edges are prepared once, for many ``distance`` queries.

    Plain Python floats: a scenario's rejection sampling asks a few dozen distances to a loop of a few
    vertices, where numpy's per-call overhead is most of the time.
    """

    def __init__(self, loop):
        starts = np.asarray(loop, dtype=float).reshape(-1, 2)
        directions = np.roll(starts, -1, axis=0) - starts
        length_sq = np.einsum("ij,ij->i", directions, directions)
        self._edges = list(zip(*starts.T.tolist(), *directions.T.tolist(), length_sq.tolist()))

    def distance(self, point) -> float:
        """Shortest distance [m] from ``point`` (2,) to the loop."""
        point_x, point_y = float(point[0]), float(point[1])
        nearest_sq = math.inf
        for start_x, start_y, direction_x, direction_y, length_sq in self._edges:
            t = 0.0
            if length_sq > 0:
                t = ((point_x - start_x) * direction_x + (point_y - start_y) * direction_y) / length_sq
                t = min(max(t, 0.0), 1.0)
            gap_x, gap_y = start_x + t * direction_x - point_x, start_y + t * direction_y - point_y
            nearest_sq = min(nearest_sq, gap_x * gap_x + gap_y * gap_y)
        return math.sqrt(nearest_sq)
