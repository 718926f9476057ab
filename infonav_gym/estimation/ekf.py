"""Extended Kalman filters built on filterpy's ``ExtendedKalmanFilter``.

The public ``predict`` and update methods check what they are given (shapes, finiteness, a
symmetric positive-definite noise covariance) and raise ``ValueError`` naming the argument, so a
bad input never fills the state with NaN. ``check_input=False`` skips that for hot loops whose
inputs are already known good (the envs: their sensors' parameters were checked at construction).
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from scipy.linalg import block_diag

from infonav_gym.estimation.models import (
    GPS_POSE_JACOBIAN,
    range_bearing_linearized,
    range_bearing_residual,
    relative_pose_linearized,
    unicycle_jacobians,
    unicycle_motion,
)
from infonav_gym.estimation.state import (  # noqa: F401  (POSE_DIM, INITIAL_POSE_STD, block_diagonal: also from here)
    INITIAL_POSE_STD,
    POSE_DIM,
    _finite,
    _noise_covariance,
    _time_step,
    block_diagonal,
)
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import log_det_spd, mutual_information_from_log_dets


def _robot_indices(name: str, value, n_robots: int) -> np.ndarray:
    """``value`` as an int array (k,) of robot indices in [0, n_robots), or ``ValueError`` naming it."""
    indices = np.atleast_1d(np.asarray(value))
    if indices.ndim != 1 or (indices.size and indices.dtype.kind not in "iu"):
        raise ValueError(f"{name} must be a sequence of robot indices, got {value!r}")
    if np.any((indices < 0) | (indices >= n_robots)):
        raise ValueError(f"{name} must be robot indices in [0, {n_robots - 1}], got {indices.tolist()}")
    return indices.astype(int)


class PoseEKF(ExtendedKalmanFilter):
    """EKF over a planar pose ``[x, y, heading]``, optionally with mapped landmarks (EKF-SLAM).

    The state is ``[x, y, heading, l1x, l1y, l2x, ...]``: with ``landmarks`` given,
    their positions are estimated alongside the pose. Prediction runs through
    filterpy's ``predict`` (with the unicycle model in ``predict_x``); range-bearing
    updates are closed-form and equal filterpy's generic ``update``, which stays
    available for other measurement models. Headings and bearing innovations are
    wrapped, and the covariance is symmetrized after every update.

    Args:
        pose: initial pose estimate (3,).
        pose_covariance: its covariance (3, 3).
        landmarks: initial estimates of the mapped landmarks (L, 2), or None.
        landmark_covariance: their covariance, (2L, 2L) or a scalar variance [m^2].
    """

    def __init__(self, pose, pose_covariance, landmarks=None, landmark_covariance=None):
        landmarks = np.zeros((0, 2)) if landmarks is None else np.asarray(landmarks, dtype=float).reshape(-1, 2)
        _finite("landmarks", landmarks, landmarks.shape)
        super().__init__(dim_x=POSE_DIM + 2 * len(landmarks), dim_z=2)
        pose = np.asarray(pose, dtype=float)
        if pose.shape != (POSE_DIM,) or not np.all(np.isfinite(pose)):
            raise ValueError(f"pose must be 3 finite numbers [x, y, heading], got {pose!r}")
        covariance = np.asarray(pose_covariance, dtype=float)
        if covariance.shape != (POSE_DIM, POSE_DIM):
            raise ValueError(f"pose_covariance must have shape (3, 3), got {covariance.shape}")
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
        self._motion = None

    @property
    def n_landmarks(self) -> int:
        """Number of landmarks in the state."""
        return (self.dim_x - POSE_DIM) // 2

    @property
    def pose(self) -> np.ndarray:
        return self.x[:POSE_DIM].copy()

    @property
    def pose_covariance(self) -> np.ndarray:
        return self.P[:POSE_DIM, :POSE_DIM].copy()

    @property
    def landmark_positions(self) -> np.ndarray:
        """Current estimates of the mapped landmarks (L, 2)."""
        return self.x[POSE_DIM:].reshape(-1, 2).copy()

    def predict(self, control, dt: float, control_covariance, *, check_input: bool = True) -> None:
        """Propagate through the unicycle model with a noisy odometry ``control`` (speed, turn rate).

        ``F P F^T + Q`` keeps the covariance symmetric; the update symmetrizes it.

        Args:
            control: odometry ``[speed, turn_rate]`` [m/s, rad/s], finite.
            dt: time step [s], finite and >= 0.
            control_covariance: its noise covariance (2, 2), symmetric positive definite.
            check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.
        """
        if check_input:
            control = _finite("control", control, (2,))
            dt = _time_step(dt)
            control_covariance = _noise_covariance("control_covariance", control_covariance, (2, 2))
        set_pose_motion(self, control, dt, control_covariance)
        super().predict()

    def predict_x(self, u=0) -> None:
        """filterpy hook: the nonlinear state prediction (landmarks are static)."""
        control, dt = self._motion
        self.x[:POSE_DIM] = unicycle_motion(self.x[:POSE_DIM], control, dt)

    def landmark_measurement_model(self, landmarks=None) -> tuple[np.ndarray, np.ndarray]:
        """Predicted range-bearing to each landmark and its Jacobian w.r.t. the whole state.

        Args:
            landmarks: known positions (N, 2); None to use the mapped landmarks in the state.

        Returns:
            ``(predicted (N, 2), H (N, 2, dim_x))``.
        """
        mapped = landmarks is None
        positions = self.x[POSE_DIM:].reshape(-1, 2) if mapped else np.asarray(landmarks, dtype=float).reshape(-1, 2)
        predicted, H_pose, H_landmark = range_bearing_linearized(self.x, positions)
        if self.dim_x == POSE_DIM:
            return predicted, H_pose
        H = np.zeros((len(positions), 2, self.dim_x))
        H[:, :, :POSE_DIM] = H_pose
        if mapped:
            rows = np.arange(len(positions))
            columns = POSE_DIM + 2 * rows[:, None] + np.arange(2)
            H[rows[:, None, None], np.arange(2)[None, :, None], columns[:, None, :]] = H_landmark
        return predicted, H

    def update_range_bearing(self, measurement, predicted, H, R, *, check_input: bool = True) -> None:
        """Update with one range-bearing measurement, linearized at the prior; covariance symmetrized.

        Gives what filterpy's generic ``update`` gives with a wrapped-bearing
        residual (tested against it) and fills the same attributes (``y``, ``S``,
        ``SI``, ``K``, ``z``, ``x_post``, ``P_post``), without its per-call
        overhead (a general matrix inverse and deep copies) in the env's hot loop.

        Args:
            measurement: ``[range, bearing]``.
            predicted: the measurement predicted at the prior, ``[range, bearing]``.
            H: its Jacobian w.r.t. the state (2, dim_x).
            R: measurement noise covariance (2, 2), symmetric positive definite.
            check_input: check shapes, finiteness and ``R`` (``ValueError`` naming a bad argument);
                ``False`` for known-good inputs.
        """
        if check_input:
            measurement = _finite("measurement", measurement, (2,))
            predicted = _finite("predicted", predicted, (2,))
            H = _finite("H", H, (2, self.dim_x))
            R = _noise_covariance("R", R, (2, 2))
        _kalman_update(self, measurement, range_bearing_residual(measurement, predicted), H, R, 2)


def set_pose_motion(ekf: ExtendedKalmanFilter, control, dt: float, control_covariance) -> None:
    """Fill the pose block (the first 3 states) of ``ekf.F`` and ``ekf.Q`` for a unicycle step, and keep the
    step in ``ekf._motion`` for ``predict_x``."""
    F_pose, V = unicycle_jacobians(ekf.x, control, dt)
    ekf.F[:POSE_DIM, :POSE_DIM] = F_pose
    ekf.Q[:POSE_DIM, :POSE_DIM] = V @ control_covariance @ V.T
    ekf._motion = (control, dt)


def _inverse(S: np.ndarray) -> np.ndarray:
    """Inverse of a small SPD matrix (closed form for 2x2, the common case in the hot loop)."""
    if S.shape == (2, 2):
        (a, b), (_, d) = S.tolist()
        return np.array([[d, -b], [-b, a]]) / (a * d - b * b)
    return np.linalg.inv(S)


def _kalman_update(ekf: ExtendedKalmanFilter, measurement, residual, H, R, heading_indices) -> None:
    """The EKF update linearized at the prior; fills filterpy's attributes; covariance symmetrized.

    Args:
        ekf: the filter to update in place.
        measurement: the measured value (m,).
        residual: ``measurement - predicted``, angles already wrapped (m,).
        H: measurement Jacobian w.r.t. the whole state (m, dim_x).
        R: measurement noise covariance (m, m).
        heading_indices: state entries that are headings, wrapped after the update.
    """
    PHT = ekf.P @ H.T
    S = H @ PHT + R
    SI = _inverse(S)
    K = PHT @ SI
    ekf.z = np.array(measurement, dtype=float)
    ekf.y = residual
    ekf.x = ekf.x + K @ residual
    ekf.x[heading_indices] = wrap_angle(ekf.x[heading_indices])
    P = ekf.P - K @ PHT.T
    ekf.P = 0.5 * (P + P.T)
    ekf.S, ekf.SI, ekf.K = S, SI, K
    ekf.x_post, ekf.P_post = ekf.x.copy(), ekf.P.copy()
    ekf._log_likelihood = ekf._likelihood = ekf._mahalanobis = None


class JointEKF(ExtendedKalmanFilter):
    """EKF over the planar poses of N robots: state ``[x0, y0, h0, x1, y1, h1, ...]`` (3N).

    A relative-pose measurement between two robots correlates their estimates;
    this filter keeps those cross-covariances, so information is never counted
    twice. With ``cross_covariances=False`` it drops them after every update
    (each robot keeps only its own 3x3 block): the common shortcut that treats
    teammates' estimates as independent, reuses the same information again and
    again, and becomes overconfident. Prediction runs through filterpy's
    ``predict``; updates are closed-form (see ``PoseEKF``).

    Args:
        poses: initial pose estimates (N, 3).
        pose_covariances: their covariances (N, 3, 3) (the robots start uncorrelated).
        cross_covariances: keep the cross-covariances (the correct joint filter).
    """

    def __init__(self, poses, pose_covariances, cross_covariances: bool = True):
        poses = np.asarray(poses, dtype=float)
        covariances = np.asarray(pose_covariances, dtype=float)
        if poses.ndim != 2 or poses.shape[1] != POSE_DIM or len(poses) < 1 or not np.all(np.isfinite(poses)):
            raise ValueError(f"poses must be finite with shape (N, 3), N >= 1, got shape {poses.shape}")
        if covariances.shape != (len(poses), POSE_DIM, POSE_DIM):
            raise ValueError(f"pose_covariances must have shape ({len(poses)}, 3, 3), got {covariances.shape}")
        for robot, covariance in enumerate(covariances):
            log_det_spd(covariance, f"initial pose covariance of robot {robot}")
        n_robots = len(poses)
        super().__init__(dim_x=POSE_DIM * n_robots, dim_z=POSE_DIM)
        self.n_robots = n_robots
        self.cross_covariances = bool(cross_covariances)
        self.x = poses.ravel().copy()
        self.P = block_diagonal(covariances)
        self.Q = np.zeros_like(self.P)
        self._own_block = np.kron(np.eye(n_robots), np.ones((POSE_DIM, POSE_DIM)))
        self._headings = np.arange(2, self.dim_x, POSE_DIM)
        self._motion = None

    @property
    def poses(self) -> np.ndarray:
        """Estimated poses (N, 3)."""
        return self.x.reshape(-1, POSE_DIM).copy()

    def pose_covariance(self, robot: int) -> np.ndarray:
        """The (3, 3) covariance block of one robot's pose."""
        block = slice(POSE_DIM * robot, POSE_DIM * robot + POSE_DIM)
        return self.P[block, block].copy()

    def pose_covariances(self) -> np.ndarray:
        """Every robot's own covariance block (N, 3, 3)."""
        robots = np.arange(self.n_robots)
        return self._blocks()[robots, robots]

    def _blocks(self) -> np.ndarray:
        """``P`` as (N, N, 3, 3) blocks: ``[i, j]`` is the covariance of robot i's pose with robot j's."""
        n = self.n_robots
        return self.P.reshape(n, POSE_DIM, n, POSE_DIM).transpose(0, 2, 1, 3)

    def predict(self, controls, dt: float, control_covariances, *, check_input: bool = True) -> None:
        """Propagate every robot through the unicycle model with its noisy odometry ``[speed, turn_rate]``.

        Args:
            controls: odometry readings (N, 2), finite.
            dt: time step [s], finite and >= 0.
            control_covariances: their noise covariances (N, 2, 2), symmetric positive definite.
            check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.
        """
        if check_input:
            controls = _finite("controls", controls, (self.n_robots, 2))
            dt = _time_step(dt)
            control_covariances = _noise_covariance("control_covariances", control_covariances, (self.n_robots, 2, 2))
        for robot in range(self.n_robots):
            block = slice(POSE_DIM * robot, POSE_DIM * robot + POSE_DIM)
            F_pose, V = unicycle_jacobians(self.x[block], controls[robot], dt)
            self.F[block, block] = F_pose
            self.Q[block, block] = V @ control_covariances[robot] @ V.T
        self._motion = (controls, dt)
        super().predict()

    def predict_x(self, u=0) -> None:
        """filterpy hook: the nonlinear prediction of every pose."""
        controls, dt = self._motion
        poses = self.x.reshape(-1, POSE_DIM)
        self.x = np.concatenate([unicycle_motion(pose, control, dt) for pose, control in zip(poses, controls)])

    def gps_update(self, robots, fixes, noise_covariances, *, check_input: bool = True) -> None:
        """Update with position fixes ``[x, y]`` of some robots (one stacked linear update).

        Args:
            robots: indices of the robots with a fix (k,).
            fixes: their measured positions (k, 2), finite.
            noise_covariances: the fixes' noise covariances (k, 2, 2), symmetric positive definite.
            check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.
        """
        if check_input:
            robots = _robot_indices("robots", robots, self.n_robots)
            fixes = _finite("fixes", fixes, (len(robots), 2))
            noise_covariances = _noise_covariance("noise_covariances", noise_covariances, (len(robots), 2, 2))
        robots = np.asarray(robots, dtype=int)
        if robots.size == 0:
            return
        H = self._stacked_jacobian(robots, GPS_POSE_JACOBIAN[None])
        measurement = np.asarray(fixes, dtype=float).ravel()
        _kalman_update(
            self, measurement, measurement - H @ self.x, H, block_diagonal(noise_covariances), self._headings
        )
        self._drop_cross_covariances()

    def relative_pose_model(self, observers, targets) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted relative pose of each ``targets[k]`` seen from ``observers[k]``, with both Jacobians.

        Returns:
            ``(predicted (M, 3), H_observer (M, 3, 3), H_target (M, 3, 3))``.
        """
        poses = self.x.reshape(-1, POSE_DIM)
        return relative_pose_linearized(poses[observers], poses[targets])

    def relative_pose_update(
        self, observers, targets, measurements, predicted, H_observer, H_target, R, *, check_input: bool = True
    ) -> None:
        """Update with relative-pose measurements taken at the same time (one stacked update).

        Measurement ``k`` is ``[range, bearing, relative heading]`` of robot ``targets[k]``
        seen from robot ``observers[k]`` (or ``[range, bearing]``, m = 2, without the heading);
        ``predicted``, ``H_observer`` and ``H_target`` come from ``relative_pose_model`` at the
        current prior (their first m rows).

        Args:
            observers, targets: robot indices (k,).
            measurements, predicted: (k, m), m = 3 or 2.
            H_observer, H_target: (k, m, 3).
            R: noise covariances (k, m, m), independent between measurements, symmetric positive definite.
            check_input: check shapes, finiteness, indices and ``R`` (``ValueError`` naming a bad argument);
                ``False`` for known-good inputs.
        """
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
        residual = np.subtract(measurements, predicted)
        residual[:, 1:] = wrap_angle(residual[:, 1:])
        _kalman_update(self, np.ravel(measurements), residual.ravel(), H, block_diagonal(R), self._headings)
        self._drop_cross_covariances()

    def _stacked_jacobian(self, robots: np.ndarray, blocks: np.ndarray) -> np.ndarray:
        """(k m, 3N) Jacobian whose k-th row block holds ``blocks[k]`` (m, 3) in robot ``robots[k]``'s columns."""
        m = blocks.shape[1]
        H = np.zeros((len(robots), m, self.n_robots, POSE_DIM))
        H[np.arange(len(robots)), :, robots, :] = blocks
        return H.reshape(len(robots) * m, self.dim_x)

    def relative_pose_information_gains(self, observers, targets, H_observer, H_target, R):
        """Expected MI of each candidate relative-pose update, alone at the current prior [nats].

        Returns:
            ``(own, joint)``, each (M,): the MI on the *observer's own* pose,
            ``0.5 ln(det P_oo / det P_oo_post)`` with ``P_oo_post = P_oo - A S^-1 A^T``
            (``A`` the observer's rows of ``P H^T``, ``S = H P H^T + R``), and the MI on
            the joint state of all robots, ``0.5 ln(det S / det R)``.
        """
        blocks = self._blocks()
        P_oo, P_ot = blocks[observers, observers], blocks[observers, targets]
        P_to, P_tt = blocks[targets, observers], blocks[targets, targets]
        H_observer_T, H_target_T = np.swapaxes(H_observer, 1, 2), np.swapaxes(H_target, 1, 2)
        A = P_oo @ H_observer_T + P_ot @ H_target_T
        S = H_observer @ A + H_target @ (P_to @ H_observer_T + P_tt @ H_target_T) + R
        posterior = P_oo - A @ np.linalg.solve(S, np.swapaxes(A, 1, 2))
        log_dets = np.linalg.slogdet(np.concatenate([P_oo, posterior, S, R]))[1].reshape(4, -1)
        return mutual_information_from_log_dets(*log_dets[:2]), mutual_information_from_log_dets(*log_dets[2:])

    def landmark_model(self, robots, landmarks) -> tuple[np.ndarray, np.ndarray]:
        """Predicted range-bearing of known landmark ``landmarks[k]`` from robot ``robots[k]``, with its Jacobian.

        Args:
            robots: robot indices (M,).
            landmarks: known landmark positions (M, 2) [m].

        Returns:
            ``(predicted (M, 2), H_pose (M, 2, 3))``: ``[range, bearing]`` and its Jacobian w.r.t. the robot's pose.
        """
        poses = self.x.reshape(-1, POSE_DIM)[np.atleast_1d(robots)]
        predicted, H_pose, _ = range_bearing_linearized(poses.T, landmarks)
        return predicted, H_pose

    def landmark_update(self, robots, measurements, predicted, H_pose, R, *, check_input: bool = True) -> None:
        """Update with range-bearing measurements of known landmarks taken at the same time (one stacked update).

        Measurement ``k`` is ``[range, bearing]`` of a landmark seen by robot ``robots[k]``; ``predicted`` and
        ``H_pose`` come from ``landmark_model`` at the current prior. Through the cross-covariances the update
        also corrects the teammates correlated with the observers.

        Args:
            robots: robot indices (k,).
            measurements, predicted: (k, 2).
            H_pose: (k, 2, 3).
            R: noise covariances (k, 2, 2), independent between measurements, symmetric positive definite.
            check_input: check shapes, finiteness, indices and ``R`` (``ValueError`` naming a bad argument);
                ``False`` for known-good inputs.
        """
        if check_input:
            robots = _robot_indices("robots", robots, self.n_robots)
            k = len(robots)
            measurements = _finite("measurements", measurements, (k, 2))
            predicted = _finite("predicted", predicted, (k, 2))
            H_pose = _finite("H_pose", H_pose, (k, 2, POSE_DIM))
            R = _noise_covariance("R", R, (k, 2, 2))
        robots = np.atleast_1d(robots)
        if robots.size == 0:
            return
        H = self._stacked_jacobian(robots, H_pose)
        residual = np.subtract(measurements, predicted)
        residual[:, 1] = wrap_angle(residual[:, 1])
        _kalman_update(self, np.ravel(measurements), residual.ravel(), H, block_diagonal(R), self._headings)
        self._drop_cross_covariances()

    def landmark_information_gains(self, robots, H_pose, R) -> np.ndarray:
        """Expected MI of each candidate landmark update, alone at the current prior [nats] (M,).

        The measurement depends on the observer's pose only, so its MI on the joint state equals its MI on
        the observer's own pose: ``0.5 ln(det S / det R)``, ``S = H P_oo H^T + R``.
        """
        robots = np.atleast_1d(robots)
        P_oo = self._blocks()[robots, robots]
        S = H_pose @ P_oo @ np.swapaxes(H_pose, 1, 2) + R
        return mutual_information_from_log_dets(np.linalg.slogdet(S)[1], np.linalg.slogdet(R)[1])

    def _drop_cross_covariances(self) -> None:
        if not self.cross_covariances:
            self.P = self.P * self._own_block
