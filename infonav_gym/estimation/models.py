"""Motion and measurement models with their Jacobians.

Poses are ``[x, y, heading]`` in metres and radians; headings are wrapped to [-pi, pi).
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.geometry import wrap_angle  # re-exported: models.wrap_angle is public


def unicycle_motion(pose, control, dt: float) -> np.ndarray:
    """Pose after driving ``control = [speed, turn_rate]`` for ``dt`` seconds (Euler step)."""
    x, y, heading = pose
    speed, turn_rate = control
    step = speed * dt
    return np.array([x + step * math.cos(heading), y + step * math.sin(heading), wrap_angle(heading + turn_rate * dt)])


def unicycle_jacobians(pose, control, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians of ``unicycle_motion`` w.r.t. the pose (3, 3) and the control (3, 2)."""
    cos_h, sin_h = math.cos(pose[2]), math.sin(pose[2])
    step = control[0] * dt
    F = np.array([[1.0, 0.0, -step * sin_h], [0.0, 1.0, step * cos_h], [0.0, 0.0, 1.0]])
    V = np.array([[dt * cos_h, 0.0], [dt * sin_h, 0.0], [0.0, dt]])
    return F, V


def range_bearing(pose, landmarks) -> np.ndarray:
    """Range [m] and bearing [rad] from ``pose`` to each landmark: (N, 2) -> (N, 2); batched, from each of the poses
    (..., 3) to its landmarks (..., N, 2) -> (..., N, 2)."""
    landmarks, pose = np.atleast_2d(landmarks), np.asarray(pose)
    dx, dy = landmarks[..., 0] - pose[..., None, 0], landmarks[..., 1] - pose[..., None, 1]
    return np.stack([np.hypot(dx, dy), wrap_angle(np.arctan2(dy, dx) - pose[..., None, 2])], axis=-1)


def range_bearing_linearized(pose, landmarks) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``range_bearing`` and its Jacobians w.r.t. the pose (N, 2, 3) and the landmark position (N, 2, 2), on the
    batched kernels; a pose stack (3, N) sees one landmark each. ``ValueError`` if a landmark is on the sensor."""
    from infonav_gym.estimation import batched  # numba: only when a linearization is asked for

    poses, landmarks = np.atleast_2d(np.asarray(pose, dtype=float)[:3].T), np.atleast_2d(landmarks)
    positions = landmarks[None] if len(poses) == 1 else landmarks[:, None]
    predicted, H = batched.landmark_measurement_model(poses, positions, check_input=False)
    H_pose = H.reshape(-1, 2, 3)
    return predicted.reshape(-1, 2), H_pose, -H_pose[:, :, :2]


GPS_POSE_JACOBIAN = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # a position fix [x, y] w.r.t. the pose


def relative_pose(observer, target) -> np.ndarray:
    """Range [m], bearing [rad] and relative heading ``target heading - observer heading`` [rad] (N, 3) of ``target``
    poses seen from ``observer`` poses, both (N, 3) (or (3,))."""
    observer, target = np.atleast_2d(observer), np.atleast_2d(target)
    dx, dy = target[:, 0] - observer[:, 0], target[:, 1] - observer[:, 1]
    bearing = wrap_angle(np.arctan2(dy, dx) - observer[:, 2])
    return np.stack([np.hypot(dx, dy), bearing, wrap_angle(target[:, 2] - observer[:, 2])], axis=-1)


def relative_pose_linearized(observer, target) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``relative_pose`` and its Jacobians w.r.t. the observer's pose (N, 3, 3) and the target's pose (N, 3, 3), on the
    batched kernels. ``ValueError`` if a target is on its observer (no bearing)."""
    from infonav_gym.estimation import batched

    observer, target = np.atleast_2d(observer), np.atleast_2d(target)
    pairs = np.zeros((len(observer), 1), dtype=int)
    models = batched.relative_pose_model(np.hstack([observer, target]), pairs, pairs + 1, check_input=False)
    return tuple(model[:, 0] for model in models)


def angular_residual(measured, predicted, angle_rows) -> np.ndarray:
    """Innovation ``measured - predicted`` with the rows in ``angle_rows`` wrapped to [-pi, pi)."""
    residual = np.subtract(measured, predicted)
    residual[angle_rows] = wrap_angle(residual[angle_rows])
    return residual
