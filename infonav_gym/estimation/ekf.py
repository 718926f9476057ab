"""The scalar reference: ``PoseEKF`` and ``JointEKF`` configure filterpy's ``ExtendedKalmanFilter`` (which performs
every predict and update, Joseph form) with the unicycle, range-bearing, relative-pose and position-fix models; the
envs, planners and replay run ``batched``, tested against it. A bad argument (shape, finiteness, SPD noise) raises
``ValueError`` naming it before the state could fill with NaN; ``check_input=False`` skips the checks.
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from scipy.linalg import block_diag

from infonav_gym.estimation import batched
from infonav_gym.estimation.models import (
    GPS_POSE_JACOBIAN,
    angular_residual,
    relative_pose_linearized,
    unicycle_jacobians,
    unicycle_motion,
)
from infonav_gym.estimation.state import POSE_DIM, _finite, _noise_covariance, _time_step, block_diagonal
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import log_det_spd


def _robot_indices(name: str, value, n_robots: int) -> np.ndarray:
    """``value`` as an int array (k,) of robot indices in [0, n_robots), or ``ValueError`` naming it."""
    indices = np.atleast_1d(np.asarray(value))
    if indices.ndim != 1 or (indices.size and indices.dtype.kind not in "iu"):
        raise ValueError(f"{name} must be a sequence of robot indices, got {value!r}")
    if np.any((indices < 0) | (indices >= n_robots)):
        raise ValueError(f"{name} must be robot indices in [0, {n_robots - 1}], got {indices.tolist()}")
    return indices.astype(int)


class _UnicycleEKF(ExtendedKalmanFilter):
    """filterpy's EKF over states that start with robot poses: the unicycle step of each pose in ``predict_x`` (the
    rest static), headings wrapped after each update."""

    def _predict(self, controls, dt: float, control_covariances) -> None:
        """filterpy's predict with each robot's unicycle step in F and Q."""
        for robot, (control, covariance) in enumerate(zip(controls, control_covariances)):
            block = slice(POSE_DIM * robot, POSE_DIM * robot + POSE_DIM)
            F_pose, V = unicycle_jacobians(self.x[block], control, dt)
            self.F[block, block] = F_pose
            self.Q[block, block] = V @ covariance @ V.T
        self._motion = (controls, dt)
        super().predict()

    def predict_x(self, u=0) -> None:
        """filterpy hook: the nonlinear prediction of every pose."""
        controls, dt = self._motion
        for robot, control in enumerate(controls):
            block = slice(POSE_DIM * robot, POSE_DIM * robot + POSE_DIM)
            self.x[block] = unicycle_motion(self.x[block], control, dt)

    def _update(self, measurement, predicted, H, R, angle_rows) -> None:
        """filterpy's update with the innovation's ``angle_rows`` wrapped; the headings wrapped after it."""
        residual = lambda measured, hx: angular_residual(measured, hx, angle_rows)  # noqa: E731
        self.update(np.ravel(measurement), lambda _: H, lambda _: np.ravel(predicted), R=R, residual=residual)
        self.x[self._headings] = wrap_angle(self.x[self._headings])


class PoseEKF(_UnicycleEKF):
    """EKF over a planar pose ``[x, y, heading]``, optionally with mapped landmarks (EKF-SLAM): the state is
    ``[x, y, heading, l1x, l1y, l2x, ...]``, headings and bearing innovations wrapped.

    Args:
        pose, pose_covariance: initial pose estimate (3,) and its covariance (3, 3).
        landmarks, landmark_covariance: initial estimates of the mapped landmarks (L, 2) or None, and their covariance
            (2L, 2L) or one variance [m^2].
    """

    def __init__(self, pose, pose_covariance, landmarks=None, landmark_covariance=None):
        landmarks = np.zeros((0, 2)) if landmarks is None else np.asarray(landmarks, dtype=float).reshape(-1, 2)
        _finite("landmarks", landmarks, landmarks.shape)
        super().__init__(dim_x=POSE_DIM + 2 * len(landmarks), dim_z=2)
        pose = _finite("pose", pose, (POSE_DIM,))
        covariance = _finite("pose_covariance", pose_covariance, (POSE_DIM, POSE_DIM))
        if len(landmarks):
            if landmark_covariance is None:
                raise ValueError("landmark_covariance is required when landmarks are mapped")
            if np.ndim(landmark_covariance) == 0:
                landmark_covariance = float(landmark_covariance) * np.eye(2 * len(landmarks))
            covariance = block_diag(covariance, landmark_covariance)
        log_det_spd(covariance, "initial covariance")
        self.x = np.concatenate([pose, landmarks.ravel()])
        self.P = covariance.copy()
        self.Q = np.zeros_like(self.P)
        self._headings = [2]

    def predict(self, control, dt: float, control_covariance, *, check_input: bool = True) -> None:
        """Propagate through the unicycle model with a noisy odometry ``control = [speed, turn_rate]`` [m/s, rad/s]
        over ``dt`` >= 0 [s], its noise covariance ``control_covariance`` (2, 2)."""
        if check_input:
            control = _finite("control", control, (2,))
            dt = _time_step(dt)
            control_covariance = _noise_covariance("control_covariance", control_covariance, (2, 2))
        self._predict([control], dt, [control_covariance])

    def landmark_measurement_model(self, landmarks=None) -> tuple[np.ndarray, np.ndarray]:
        """Predicted range-bearing to each landmark, known positions (N, 2) or (None) those mapped in the state, and its
        Jacobian w.r.t. the whole state: ``(predicted (N, 2), H (N, 2, dim_x))``."""
        positions = None if landmarks is None else np.asarray(landmarks, dtype=float).reshape(1, -1, 2)
        predicted, H = batched.landmark_measurement_model(self.x[None], positions, check_input=False)
        return predicted[0], H[0]

    def update_range_bearing(self, measurement, predicted, H, R, *, check_input: bool = True) -> None:
        """filterpy's update with one ``[range, bearing]`` measurement, linearized at the prior (``predicted``, ``H``
        (2, dim_x)), noise ``R`` (2, 2), the bearing wrapped."""
        if check_input:
            measurement = _finite("measurement", measurement, (2,))
            predicted = _finite("predicted", predicted, (2,))
            H = _finite("H", H, (2, self.dim_x))
            R = _noise_covariance("R", R, (2, 2))
        self._update(measurement, predicted, H, R, 1)


class JointEKF(_UnicycleEKF):
    """EKF over the planar poses of N robots: state ``[x0, y0, h0, x1, y1, h1, ...]`` (3N).

    A relative-pose measurement correlates two robots' estimates; this filter keeps those cross-covariances, so
    information is never counted twice. ``cross_covariances=False`` drops them after every update (each robot keeps its
    own 3x3 block): the common shortcut that treats teammates as independent, reuses information, grows overconfident.

    Args:
        poses, pose_covariances: initial pose estimates (N, 3) and their covariances (N, 3, 3) (uncorrelated).
        cross_covariances: keep the cross-covariances (the correct joint filter).
    """

    def __init__(self, poses, pose_covariances, cross_covariances: bool = True):
        poses = np.asarray(poses, dtype=float)
        if poses.ndim != 2 or poses.shape[1] != POSE_DIM or len(poses) < 1 or not np.all(np.isfinite(poses)):
            raise ValueError(f"poses must be finite with shape (N, 3), N >= 1, got shape {poses.shape}")
        covariances = _finite("pose_covariances", pose_covariances, (len(poses), POSE_DIM, POSE_DIM))
        for robot, covariance in enumerate(covariances):
            log_det_spd(covariance, f"initial pose covariance of robot {robot}")
        super().__init__(dim_x=poses.size, dim_z=POSE_DIM)
        self.n_robots = len(poses)
        self.cross_covariances = bool(cross_covariances)
        self.x = poses.ravel().copy()
        self.P = block_diagonal(covariances)
        self.Q = np.zeros_like(self.P)
        self._own_block = np.kron(np.eye(self.n_robots), np.ones((POSE_DIM, POSE_DIM)))
        self._headings = np.arange(2, self.dim_x, POSE_DIM)

    @property
    def poses(self) -> np.ndarray:
        """Estimated poses (N, 3)."""
        return self.x.reshape(-1, POSE_DIM).copy()

    def pose_covariance(self, robot: int) -> np.ndarray:
        """The (3, 3) covariance block of one robot's pose."""
        block = slice(POSE_DIM * robot, POSE_DIM * robot + POSE_DIM)
        return self.P[block, block].copy()

    def predict(self, controls, dt: float, control_covariances, *, check_input: bool = True) -> None:
        """Propagate every robot through the unicycle model with its noisy odometry ``[speed, turn_rate]`` (N, 2) over
        ``dt`` >= 0 [s], their noise covariances ``control_covariances`` (N, 2, 2)."""
        if check_input:
            controls = _finite("controls", controls, (self.n_robots, 2))
            dt = _time_step(dt)
            control_covariances = _noise_covariance("control_covariances", control_covariances, (self.n_robots, 2, 2))
        self._predict(controls, dt, control_covariances)

    def gps_update(self, robots, fixes, noise_covariances, *, check_input: bool = True) -> None:
        """Update with the position fixes ``[x, y]`` (k, 2) of ``robots`` (k,), their noise covariances (k, 2, 2),
        as one stacked linear update."""
        if check_input:
            robots = _robot_indices("robots", robots, self.n_robots)
            fixes = _finite("fixes", fixes, (len(robots), 2))
            noise_covariances = _noise_covariance("noise_covariances", noise_covariances, (len(robots), 2, 2))
        robots = np.asarray(robots, dtype=int)
        if robots.size == 0:
            return
        H = self._stacked_jacobian(robots, np.broadcast_to(GPS_POSE_JACOBIAN, (len(robots), 2, POSE_DIM)))
        self._update(fixes, H @ self.x, H, block_diagonal(noise_covariances), [])

    def relative_pose_model(self, observers, targets) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted relative pose of each ``targets[k]`` seen from ``observers[k]``, with both Jacobians:
        ``(predicted (M, 3), H_observer (M, 3, 3), H_target (M, 3, 3))``."""
        poses = self.x.reshape(-1, POSE_DIM)
        return relative_pose_linearized(poses[observers], poses[targets])

    def relative_pose_update(
        self, observers, targets, measurements, predicted, H_observer, H_target, R, *, check_input: bool = True
    ) -> None:
        """One stacked update with simultaneous relative-pose measurements (k, m): row ``k`` is ``[range, bearing,
        relative heading]`` (m = 3) or ``[range, bearing]`` (m = 2) of robot ``targets[k]`` seen by ``observers[k]``;
        ``predicted``, Jacobians (k, m, 3): ``relative_pose_model``'s first m rows; ``R`` (k, m, m): their own noise."""
        if check_input:
            observers = _robot_indices("observers", observers, self.n_robots)
            targets = _robot_indices("targets", targets, self.n_robots)
            k = len(observers)
            if len(targets) != k:
                raise ValueError(f"observers and targets must pair up, got {k} observers and {len(targets)} targets")
            m = np.shape(measurements)[-1] if np.ndim(measurements) == 2 and np.shape(measurements)[-1] == 2 else 3
            measurements = _finite("measurements", measurements, (k, m))
            predicted = _finite("predicted", predicted, (k, m))
            H_observer = _finite("H_observer", H_observer, (k, m, POSE_DIM))
            H_target = _finite("H_target", H_target, (k, m, POSE_DIM))
            R = _noise_covariance("R", R, (k, m, m))
        observers, targets = np.atleast_1d(observers), np.atleast_1d(targets)
        if np.any(observers == targets):
            raise ValueError(f"a robot cannot observe its own relative pose (observers {observers}, targets {targets})")
        H = self._stacked_jacobian(observers, H_observer) + self._stacked_jacobian(targets, H_target)
        m = np.shape(measurements)[1]
        self._update(measurements, predicted, H, block_diagonal(R), np.arange(len(H)) % m != 0)

    def _stacked_jacobian(self, robots: np.ndarray, blocks) -> np.ndarray:
        """(k m, 3N) Jacobian whose k-th row block holds ``blocks[k]`` (m, 3) in robot ``robots[k]``'s columns."""
        return batched._slot_jacobians(robots[None], np.asarray(blocks)[None], self.dim_x).reshape(-1, self.dim_x)

    def _update(self, measurement, predicted, H, R, angle_rows) -> None:
        """``_UnicycleEKF._update``; without ``cross_covariances`` each robot keeps only its own block."""
        super()._update(measurement, predicted, H, R, angle_rows)
        if not self.cross_covariances:
            self.P = self.P * self._own_block
