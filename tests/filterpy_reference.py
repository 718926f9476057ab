"""Raw filterpy ``ExtendedKalmanFilter`` configured here with the unicycle, range-bearing and relative-pose models in
closed form, so nothing of the package stands on the oracle's side: the reference of the batched EKF's tests.

filterpy predicts ``F P F^T + Q`` and updates in Joseph form ``(I - K H) P (I - K H)^T + K R K^T``.
"""

import math

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter


def wrap(angle):
    return (np.asarray(angle) + math.pi) % (2 * math.pi) - math.pi


def filterpy_filter(x, P) -> ExtendedKalmanFilter:
    ekf = ExtendedKalmanFilter(dim_x=len(x), dim_z=2)
    ekf.x, ekf.P = np.array(x, dtype=float), np.array(P, dtype=float)
    return ekf


def filterpy_predict(ekf: ExtendedKalmanFilter, controls, control_covariances, dt: float) -> None:
    """Every pose (the first 3R entries) through the Euler unicycle step; F and Q = V C V^T in closed form."""
    n = len(ekf.x)
    F, Q, moved = np.eye(n), np.zeros((n, n)), ekf.x.copy()
    for robot, ((speed, turn_rate), C) in enumerate(zip(controls, control_covariances)):
        i = 3 * robot
        heading = ekf.x[i + 2]
        moved[i : i + 3] = ekf.x[i : i + 3] + [speed * dt * math.cos(heading), speed * dt * math.sin(heading), 0]
        moved[i + 2] = wrap(heading + turn_rate * dt)
        F[i, i + 2], F[i + 1, i + 2] = -speed * dt * math.sin(heading), speed * dt * math.cos(heading)
        V = np.array([[dt * math.cos(heading), 0.0], [dt * math.sin(heading), 0.0], [0.0, dt]])
        Q[i : i + 3, i : i + 3] = V @ C @ V.T
    ekf.F, ekf.Q = F, Q

    def predict_x(u=0):
        ekf.x = moved

    ekf.predict_x = predict_x
    ekf.predict()


def filterpy_update(ekf, measured, predicted, H, R, angle_rows, n_robots: int, cross_covariances=True) -> None:
    """filterpy's update with the angle rows of the innovation wrapped; then headings wrapped, and without
    ``cross_covariances`` only each robot's own blocks kept (``JointEKF``'s shortcut)."""

    def residual(z, hz):
        y = np.subtract(z, hz)
        y[angle_rows] = wrap(y[angle_rows])
        return y

    ekf.update(np.asarray(measured), lambda x: H, lambda x: np.asarray(predicted), R=R, residual=residual)
    headings = 3 * np.arange(n_robots) + 2
    ekf.x[headings] = wrap(ekf.x[headings])
    if not cross_covariances:
        ekf.P = ekf.P * np.kron(np.eye(n_robots), np.ones((3, 3)))


def range_bearing(state, robot: int, landmark, mapped_column=None):
    """Range-bearing of ``landmark`` from robot ``robot``'s pose in ``state``, and its Jacobian (2, n)."""
    x, y, heading = state[3 * robot : 3 * robot + 3]
    dx, dy = landmark[0] - x, landmark[1] - y
    q = dx * dx + dy * dy
    d = math.sqrt(q)
    H = np.zeros((2, len(state)))
    H[:, 3 * robot : 3 * robot + 3] = [[-dx / d, -dy / d, 0.0], [dy / q, -dx / q, -1.0]]
    if mapped_column is not None:
        H[:, mapped_column : mapped_column + 2] = [[dx / d, dy / d], [-dy / q, dx / q]]
    return np.array([d, wrap(math.atan2(dy, dx) - heading)]), H


def relative_pose(state, observer: int, target: int):
    """Range, bearing and relative heading of ``target`` seen from ``observer``, and its Jacobian (3, n)."""
    xo, yo, ho = state[3 * observer : 3 * observer + 3]
    xt, yt, ht = state[3 * target : 3 * target + 3]
    dx, dy = xt - xo, yt - yo
    q = dx * dx + dy * dy
    d = math.sqrt(q)
    H = np.zeros((3, len(state)))
    H[:, 3 * observer : 3 * observer + 3] = [[-dx / d, -dy / d, 0.0], [dy / q, -dx / q, -1.0], [0.0, 0.0, -1.0]]
    H[:, 3 * target : 3 * target + 3] = [[dx / d, dy / d, 0.0], [-dy / q, dx / q, 0.0], [0.0, 0.0, 1.0]]
    return np.array([d, wrap(math.atan2(dy, dx) - ho), wrap(ht - ho)]), H


def block_diagonal(blocks) -> np.ndarray:
    k, m, _ = np.shape(blocks)
    matrix = np.zeros((k * m, k * m))
    for index, block in enumerate(blocks):
        matrix[index * m : index * m + m, index * m : index * m + m] = block
    return matrix


def stacked(models) -> tuple[np.ndarray, np.ndarray]:
    """The stacked predictions (k m,) and Jacobians (k m, n) of ``(z, H)`` pairs."""
    return np.concatenate([z for z, _ in models]), np.concatenate([H for _, H in models])


def angle_rows(k: int, m: int) -> list[int]:
    """The angle rows of k stacked measurements of m rows each, the range first: all rows but each range's."""
    return [m * slot + row for slot in range(k) for row in range(1, m)]


def gps_jacobian(robots, n: int) -> np.ndarray:
    """The Jacobian (2k, n) of the position fixes ``[x, y]`` of ``robots`` (k,)."""
    robots = np.asarray(robots)
    H = np.zeros((2 * robots.size, n))
    H[np.arange(2 * robots.size), (3 * robots[:, None] + [0, 1]).ravel()] = 1.0
    return H


def pose_blocks(P: np.ndarray) -> np.ndarray:
    """Each robot's (3, 3) pose block of a joint covariance (R, 3, 3)."""
    return np.array([P[3 * k : 3 * k + 3, 3 * k : 3 * k + 3] for k in range(len(P) // 3)])
