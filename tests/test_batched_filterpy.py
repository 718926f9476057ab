"""The compiled batched EKF core against filterpy's ``ExtendedKalmanFilter``, step for step along random episodes.

Each copy has its own filterpy filter, fed the same controls and measurements; the models (unicycle,
range-bearing, relative pose) and their Jacobians are written in closed form in ``filterpy_reference``, so nothing
of the package stands on the oracle's side. filterpy predicts ``F P F^T + Q`` and updates in Joseph form
``(I - K H) P (I - K H)^T + K R K^T``; the core's ``P - K H P`` must agree to 1e-10, its states to 1e-12.
"""

import math

import numpy as np
import pytest
from conftest import select_candidates
from filterpy_reference import (
    angle_rows,
    block_diagonal,
    filterpy_filter,
    filterpy_predict,
    filterpy_update,
    gps_jacobian,
    range_bearing,
    relative_pose,
    stacked,
)

from infonav_gym.estimation import batched

X_TOLERANCE = 1e-12
P_TOLERANCE = 1e-10
STEPS = 40
DT = 0.25  # [s]


def random_spd(rng, n: int, scale: float) -> np.ndarray:
    A = rng.standard_normal((n, n))
    return scale * (A @ A.T / n + 0.1 * np.eye(n))


def random_noise(rng, shape: tuple[int, ...], m: int) -> np.ndarray:
    """Random measurement noise covariances (*shape, m, m)."""
    return np.stack([random_spd(rng, m, 0.01) for _ in range(math.prod(shape))]).reshape(*shape, m, m)


def filterpy_filters(x, P) -> list:
    return [filterpy_filter(state, covariance) for state, covariance in zip(x, P)]


def assert_equal_to_filterpy(x, P, filters, step: int) -> None:
    np.testing.assert_allclose(x, [ekf.x for ekf in filters], rtol=0, atol=X_TOLERANCE, err_msg=f"x, step {step}")
    np.testing.assert_allclose(P, [ekf.P for ekf in filters], rtol=0, atol=P_TOLERANCE, err_msg=f"P, step {step}")


def random_controls(rng, shape) -> np.ndarray:
    return np.stack([rng.uniform(-0.5, 2.0, shape), rng.uniform(-1.0, 1.0, shape)], axis=-1)


@pytest.mark.parametrize("n_landmarks", [0, 5])  # 0: known landmarks; 5: mapped in the state (EKF-SLAM)
def test_pose_filter_episodes_equal_filterpy(n_landmarks):
    """Odometry predictions, range-bearing updates of a random landmark (or none), information gains."""
    rng = np.random.default_rng(3 + n_landmarks)
    n_copies, n_candidates, n = 6, 5, 3 + 2 * n_landmarks
    truth = rng.uniform(-8, 8, (n_copies, n_candidates, 2))  # the landmarks
    pose = np.concatenate([rng.uniform(-2, 2, (n_copies, 2)), rng.uniform(-math.pi, math.pi, (n_copies, 1))], 1)
    x = np.concatenate([pose, (truth + rng.normal(0, 0.5, truth.shape)).reshape(n_copies, -1)[:, : n - 3]], 1)
    P = np.stack([random_spd(rng, n, 0.05) for _ in range(n_copies)])
    filters = filterpy_filters(x, P)
    known = None if n_landmarks else truth
    observations = np.zeros(n_copies, dtype=int)
    for step in range(STEPS):
        controls, noise = random_controls(rng, n_copies), random_spd(rng, 2, 0.01)
        x, P = batched.predict_pose(x, P, controls, DT, noise)
        for copy, ekf in enumerate(filters):
            filterpy_predict(ekf, controls[copy : copy + 1], noise[None], DT)
        assert_equal_to_filterpy(x, P, filters, step)
        predicted, H = batched.landmark_measurement_model(x, known)
        R = np.broadcast_to(np.diag([0.1**2, math.radians(3.0) ** 2]), (n_copies, n_candidates, 2, 2)).copy()
        gains = batched.landmark_information_gains(P, H, R)
        chosen = np.where(rng.random(n_copies) < 0.8, rng.integers(0, n_candidates, n_copies), -1)
        observed, rows, jacobians, noises = select_candidates(chosen, predicted, H, R)
        measured = rows + rng.normal(0, [0.1, 0.05], (n_copies, 2))
        x, P = batched.range_bearing_update(x, P, measured, rows, jacobians, noises, observed)
        for copy, ekf in enumerate(filters):
            if not observed[copy]:
                continue
            landmark = chosen[copy]
            expected, expected_H = range_bearing(
                ekf.x, 0, ekf.x[3 + 2 * landmark : 5 + 2 * landmark] if n_landmarks else truth[copy, landmark],
                3 + 2 * landmark if n_landmarks else None,
            )  # fmt: skip
            np.testing.assert_allclose(predicted[copy, landmark], expected, rtol=0, atol=X_TOLERANCE)
            np.testing.assert_allclose(H[copy, landmark], expected_H, rtol=0, atol=X_TOLERANCE)
            prior_log_det = np.linalg.slogdet(ekf.P)[1]
            filterpy_update(ekf, measured[copy], expected, expected_H, R[copy, landmark], [1], 1)
            realized = 0.5 * (prior_log_det - np.linalg.slogdet(ekf.P)[1])  # the MI the update brought
            assert gains[copy, landmark] == pytest.approx(realized, abs=P_TOLERANCE)
        assert_equal_to_filterpy(x, P, filters, step)
        observations += observed
    assert np.all((observations > STEPS / 2) & (observations < STEPS))  # observed often, and skipped sometimes


@pytest.mark.parametrize("cross_covariances", [True, False])
def test_team_filter_episodes_equal_filterpy(cross_covariances):
    """Team predictions; relative-pose, GPS and landmark updates of random robots, each a stacked update."""
    rng = np.random.default_rng(7 + cross_covariances)
    n_copies, n_robots = 5, 3
    n = 3 * n_robots
    poses = np.concatenate(
        [rng.uniform(-6, 6, (n_copies, n_robots, 2)), rng.uniform(-math.pi, math.pi, (n_copies, n_robots, 1))], -1
    )
    x = poses.reshape(n_copies, n)
    P = np.zeros((n_copies, n, n))
    for robot in range(n_robots):
        block = slice(3 * robot, 3 * robot + 3)
        P[:, block, block] = [random_spd(rng, 3, 0.1) for _ in range(n_copies)]
    filters = filterpy_filters(x, P)
    robots = np.broadcast_to(np.arange(n_robots), (n_copies, n_robots))
    landmarks = rng.uniform(-10, 10, (n_copies, n_robots, 2))
    kept = {"cross_covariances": cross_covariances}
    for step in range(STEPS):
        controls = random_controls(rng, (n_copies, n_robots))
        noise = np.stack([random_spd(rng, 2, 0.01) for _ in range(n_robots)])
        x, P = batched.predict_team(x, P, controls, DT, noise)
        for copy, ekf in enumerate(filters):
            filterpy_predict(ekf, controls[copy], noise, DT)
        assert_equal_to_filterpy(x, P, filters, step)

        targets = (robots + rng.integers(1, n_robots, robots.shape)) % n_robots
        observed = rng.random(robots.shape) < 0.5
        m = 3 - step % 2  # range, bearing and relative heading, or range and bearing (the MRCLAM replay's)
        predicted, H_observer, H_target = (part[:, :, :m] for part in batched.relative_pose_model(x, robots, targets))
        R = random_noise(rng, (n_copies, n_robots), m)
        measured = predicted + rng.normal(0, 0.05, predicted.shape)
        args = (robots, targets, measured, predicted, H_observer, H_target, R, observed)
        x, P = batched.relative_pose_update(x, P, *args, **kept)
        for copy, ekf in enumerate(filters):
            slots = np.flatnonzero(observed[copy])
            if slots.size:
                models = [(z[:m], J[:m]) for z, J in (relative_pose(ekf.x, k, targets[copy, k]) for k in slots)]
                expected, expected_H = stacked(models)
                np.testing.assert_allclose(predicted[copy, slots].ravel(), expected, rtol=0, atol=X_TOLERANCE)
                angles = angle_rows(len(slots), m)
                measurement = measured[copy, slots].ravel()
                R_stacked = block_diagonal(R[copy, slots])
                filterpy_update(ekf, measurement, expected, expected_H, R_stacked, angles, n_robots, **kept)
        assert_equal_to_filterpy(x, P, filters, step)

        has_fix = rng.random(robots.shape) < 0.3
        fixes = x.reshape(n_copies, n_robots, 3)[..., :2] + rng.normal(0, 0.3, (n_copies, n_robots, 2))
        gps_noise = np.stack([random_spd(rng, 2, 0.05) for _ in range(n_robots)])
        x, P = batched.gps_update(x, P, fixes, gps_noise, has_fix, **kept)
        for copy, ekf in enumerate(filters):
            fixed = np.flatnonzero(has_fix[copy])
            if fixed.size:
                H = gps_jacobian(fixed, n)
                R_stacked = block_diagonal(gps_noise[fixed])
                filterpy_update(ekf, fixes[copy, fixed].ravel(), H @ ekf.x, H, R_stacked, [], n_robots, **kept)
        assert_equal_to_filterpy(x, P, filters, step)

        sees = rng.random(robots.shape) < 0.5
        predicted, H = batched.landmark_measurement_model(x.reshape(-1, 3), landmarks.reshape(-1, 1, 2))
        predicted, H_pose = predicted.reshape(n_copies, n_robots, 2), H.reshape(n_copies, n_robots, 2, 3)
        R = np.broadcast_to(np.diag([0.2**2, math.radians(2.0) ** 2]), (n_copies, n_robots, 2, 2))
        measured = predicted + rng.normal(0, 0.05, predicted.shape)
        x, P = batched.team_landmark_update(x, P, robots, measured, predicted, H_pose, R, sees, **kept)
        for copy, ekf in enumerate(filters):
            slots = np.flatnonzero(sees[copy])
            if slots.size:
                expected, expected_H = stacked([range_bearing(ekf.x, slot, landmarks[copy, slot]) for slot in slots])
                angles = angle_rows(len(slots), 2)
                measurement = measured[copy, slots].ravel()
                R_stacked = block_diagonal(R[copy, slots])
                filterpy_update(ekf, measurement, expected, expected_H, R_stacked, angles, n_robots, **kept)
        assert_equal_to_filterpy(x, P, filters, step)
    if not cross_covariances:
        cross = P * (1 - np.kron(np.eye(n_robots), np.ones((3, 3))))
        assert not cross.any()


@pytest.mark.parametrize("cross_covariances", [True, False])
def test_relative_pose_gains_equal_the_mi_of_filterpys_update(cross_covariances):
    """``joint``: the MI of the update on the whole state, ``own``: on the observer's pose, as filterpy has them."""
    rng = np.random.default_rng(11)
    n_copies, n_robots = 4, 4
    n = 3 * n_robots
    x = np.concatenate([rng.uniform(-6, 6, (n_copies, n_robots, 2)), rng.uniform(-3, 3, (n_copies, n_robots, 1))], -1)
    x = x.reshape(n_copies, n)
    P = np.stack([random_spd(rng, n, 0.1) for _ in range(n_copies)])
    if not cross_covariances:
        P = P * np.kron(np.eye(n_robots), np.ones((3, 3)))
    observers = np.broadcast_to(np.arange(n_robots), (n_copies, n_robots))
    targets = (observers + rng.integers(1, n_robots, observers.shape)) % n_robots
    predicted, H_observer, H_target = batched.relative_pose_model(x, observers, targets)
    R = random_noise(rng, (n_copies, n_robots), 3)
    own, joint = batched.relative_pose_information_gains(P, observers, targets, H_observer, H_target, R)
    pose_log_dets = batched.pose_log_dets(P, n_robots)
    for copy in range(n_copies):
        for slot in range(n_robots):
            ekf = filterpy_filters(x[copy : copy + 1], P[copy : copy + 1])[0]
            expected, H = relative_pose(ekf.x, slot, targets[copy, slot])
            filterpy_update(ekf, expected, expected, H, R[copy, slot], [1, 2], n_robots)
            block = slice(3 * slot, 3 * slot + 3)
            realized_joint = 0.5 * (np.linalg.slogdet(P[copy])[1] - np.linalg.slogdet(ekf.P)[1])
            own_log_dets = np.linalg.slogdet([P[copy, block, block], ekf.P[block, block]])[1]
            realized_own = 0.5 * (own_log_dets[0] - own_log_dets[1])
            assert joint[copy, slot] == pytest.approx(realized_joint, abs=P_TOLERANCE)
            assert own[copy, slot] == pytest.approx(realized_own, abs=P_TOLERANCE)
            assert pose_log_dets[copy, slot] == pytest.approx(own_log_dets[0], abs=P_TOLERANCE)
