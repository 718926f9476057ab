"""Geometry shared by every floor: angles, rigid transforms, distances to polylines.

Transforms are (4, 4) homogeneous matrices; ``A_from_B`` maps points of frame B into frame A. Body frame: x
forward, y left, z up; rotations right-handed.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import contiguous, inline, inner_kernel, kernel


def wrap_angle(angle):
    """Map an angle (a float or an ndarray of them) to [-pi, pi) [rad]."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


wrap_angle_kernel = inner_kernel(wrap_angle)  # the same formula compiled, for one float inside other kernels


def rotation_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (3, 3)."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
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


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` along the last axis of broadcastable (..., 3) arrays (``np.cross`` without its overhead)."""
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def rotation_angle(rotation: np.ndarray) -> float:
    """Angle [rad] of a (3, 3) rotation matrix, in [0, pi]; accurate near 0 (unlike ``arccos`` of the trace)."""
    axis = (rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0], rotation[1, 0] - rotation[0, 1])
    return math.atan2(0.5 * math.hypot(*axis), 0.5 * (rotation[0, 0] + rotation[1, 1] + rotation[2, 2] - 1.0))


def transform_error(estimate: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """``(translation error [m], rotation error [rad])`` of a (4, 4) ``estimate`` against ``truth``."""
    return float(np.linalg.norm(estimate[:3, 3] - truth[:3, 3])), rotation_angle(estimate[:3, :3].T @ truth[:3, :3])


class ClosedLoop:
    """Closed polylines (each (W, 2) [m]) whose edges (``starts``, ``directions``) prepared once serve many points."""

    def __init__(self, *loops):
        starts = [np.asarray(loop, dtype=float).reshape(-1, 2) for loop in loops]
        self.starts = np.concatenate(starts)
        self.directions = np.concatenate([np.concatenate((start[1:], start[:1])) - start for start in starts])

    def distances(self, points) -> np.ndarray:
        """Shortest distance [m] from each of ``points`` (M, 2) to the nearest loop (M,)."""
        return loop_distances(contiguous(np.asarray(points, dtype=float)), self.starts, self.directions)


@kernel
def loop_distances(points, starts, directions):
    """``ClosedLoop.distances`` to the edges ``starts + t directions`` (E, 2): ``loop_distance`` of each point."""
    distances = np.empty(len(points))
    for p in range(len(points)):
        distances[p] = loop_distance(points[p, 0], points[p, 1], starts, directions)
    return distances


@inline
def loop_distance(x, y, starts, directions):
    """Distance [m] from ``(x, y)`` to the edges ``starts + t directions`` (E, 2), ``t`` in [0, 1]; NaN in, NaN out."""
    nearest = np.inf
    for e in range(len(starts)):
        start_x, start_y, direction_x, direction_y = starts[e, 0], starts[e, 1], directions[e, 0], directions[e, 1]
        length_sq = direction_x * direction_x + direction_y * direction_y
        t = 0.0
        if not length_sq <= 0.0:
            along = (x - start_x) * direction_x + (y - start_y) * direction_y
            t = along / length_sq  # clipped to [0, 1] below; NaN stays NaN
            t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        gap_x = start_x + t * direction_x - x
        gap_y = start_y + t * direction_y - y
        squared = gap_x * gap_x + gap_y * gap_y
        if squared < nearest or math.isnan(squared):
            nearest = squared
    return math.sqrt(nearest)
