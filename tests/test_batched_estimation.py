"""The batched EKF core's behaviour beside the filterpy oracle (``test_batched_filterpy``): unobserved copies, the
branch cut, the unchecked path, its input checks."""

import math

import numpy as np
import pytest
from conftest import select_candidates

import infonav_gym  # noqa: F401  (registers the envs)
from infonav_gym.estimation import batched
from infonav_gym.information import log_det_spd

P_TOLERANCE = 1e-10
COPIES = (1, 4, 9)


def random_states(rng, n_copies: int, n_robots: int = 1, n_landmarks: int = 0) -> np.ndarray:
    """Poses in a 20 m square with any heading, then landmark estimates in the same square (N, 3R + 2L)."""
    poses = np.concatenate(
        [rng.uniform(-10, 10, (n_copies, n_robots, 2)), rng.uniform(-math.pi, math.pi, (n_copies, n_robots, 1))], -1
    )
    landmarks = rng.uniform(-10, 10, (n_copies, 2 * n_landmarks))
    return np.concatenate([poses.reshape(n_copies, -1), landmarks], axis=1)


def random_covariances(rng, n_copies: int, n: int, scale: float = 0.1) -> np.ndarray:
    """Random symmetric positive-definite (N, n, n), fully correlated."""
    A = rng.standard_normal((n_copies, n, n))
    return scale * (A @ np.swapaxes(A, 1, 2) / n + 0.05 * np.eye(n))


def random_controls(rng, shape) -> np.ndarray:
    return np.stack([rng.uniform(-1, 2, shape), rng.uniform(-1, 1, shape)], axis=-1)


def random_mask(rng, shape) -> np.ndarray:
    """Random bools, with at least one False and one True when there is room for both."""
    mask = rng.random(shape) < 0.6
    mask.flat[0] = False
    if mask.size > 1:
        mask.flat[-1] = True
    return mask


def landmark_noise(predicted: np.ndarray) -> np.ndarray:
    """Range-bearing noise growing with the range, as the env's sensor: (..., 2) -> (..., 2, 2)."""
    R = np.zeros((*predicted.shape[:-1], 2, 2))
    R[..., 0, 0] = (0.1 + 0.01 * predicted[..., 0]) ** 2
    R[..., 1, 1] = math.radians(2.0) ** 2
    return R


# ---------------------------------------------------------------------------------------------- pose filter


def landmark_case(seed: int, n_copies: int, mapping: bool, n_landmarks: int):
    """Random states and covariances, the landmarks (None: in the state), and the batched model at that prior."""
    rng = np.random.default_rng(seed)
    x = random_states(rng, n_copies, n_landmarks=n_landmarks if mapping else 0)
    P = random_covariances(rng, n_copies, x.shape[1])
    landmarks = None if mapping else rng.uniform(-10, 10, (n_copies, n_landmarks, 2))
    predicted, H = batched.landmark_measurement_model(x, landmarks)
    return rng, x, P, landmarks, predicted, H, landmark_noise(predicted)


def test_landmark_model_takes_one_known_map_for_every_copy():
    rng = np.random.default_rng(5)
    x, landmarks = random_states(rng, 3), rng.uniform(-10, 10, (4, 2))
    predicted, H = batched.landmark_measurement_model(x, landmarks)
    for actual, expected in zip((predicted, H), batched.landmark_measurement_model(x, np.stack([landmarks] * 3))):
        np.testing.assert_array_equal(actual, expected)


@pytest.mark.parametrize("n_copies", COPIES)
@pytest.mark.parametrize("mapping", [False, True])
def test_range_bearing_update_skips_unobserved_copies_and_brings_its_expected_gain(n_copies, mapping):
    n_landmarks = 6
    rng, x, P, landmarks, predicted, H, R = landmark_case(7 * n_copies + mapping, n_copies, mapping, n_landmarks)
    chosen = np.where(random_mask(rng, n_copies), rng.integers(0, n_landmarks, n_copies), -1)
    observed, chosen_predicted, chosen_H, chosen_R = select_candidates(chosen, predicted, H, R)
    measurements = chosen_predicted + rng.normal(0, [0.2, 0.1], (n_copies, 2))
    measurements[:, 1] = (measurements[:, 1] + math.pi) % (2 * math.pi) - math.pi
    x_new, P_new = batched.range_bearing_update(x, P, measurements, chosen_predicted, chosen_H, chosen_R, observed)
    np.testing.assert_array_equal(x_new[~observed], x[~observed])
    np.testing.assert_array_equal(P_new[~observed], P[~observed])
    if observed.any():  # the realized MI of each update is its expected gain at the prior
        realized = 0.5 * (log_det_spd(P[observed]) - log_det_spd(P_new[observed]))
        prior_gains = batched.landmark_information_gains(P, H, R)[observed, chosen[observed]]
        np.testing.assert_allclose(realized, prior_gains, rtol=0, atol=P_TOLERANCE)


def test_innovations_are_wrapped_across_the_branch_cut():
    """A bearing (and a relative heading) measured just past +-pi from its prediction is a small innovation."""
    rng = np.random.default_rng(13)
    x, P = random_states(rng, 2), random_covariances(rng, 2, 3)
    predicted = np.array([[5.0, math.pi - 0.01], [4.0, -math.pi + 0.02]])
    measurements = np.array([[5.1, -math.pi + 0.01], [4.1, math.pi - 0.02]])
    H, R = rng.standard_normal((2, 2, 3)), landmark_noise(predicted)
    x_new, _ = batched.range_bearing_update(x, P, measurements, predicted, H, R)
    assert np.all(np.abs(x_new - x)[:, 2] < 0.1)  # no 2 pi jump reached the heading
    _, xj, Pj = joint_case(17, 1, 2)
    relative_predicted = np.array([[[3.0, math.pi - 0.01, -math.pi + 0.01]]])
    relative_measured = np.array([[[3.1, -math.pi + 0.02, math.pi - 0.02]]])
    H_observer, H_target = rng.standard_normal((2, 1, 1, 3, 3))
    R_relative = np.diag([0.01, 0.001, 0.001])[None, None]
    arguments = ([[0]], [[1]], relative_measured, relative_predicted, H_observer, H_target, R_relative)
    xj_new, _ = batched.relative_pose_update(xj, Pj, *arguments)
    assert np.all(np.abs(xj_new - xj)[:, 2::3] < 0.1)


def test_unchecked_fast_path_equals_the_checked_call():
    rng = np.random.default_rng(11)
    x, P = random_states(rng, 5, n_landmarks=3), random_covariances(rng, 5, 9)
    controls, noise = random_controls(rng, 5), np.diag([0.05**2, 0.02**2])
    for checked, unchecked in zip(
        batched.predict_pose(x, P, controls, 0.5, noise),
        batched.predict_pose(x, P, controls, 0.5, noise, check_input=False),
    ):
        np.testing.assert_array_equal(checked, unchecked)
    predicted, H = batched.landmark_measurement_model(x)
    observed, rows, jacobians, R = select_candidates(
        np.array([0, -1, 2, 1, -1]), predicted, H, landmark_noise(predicted)
    )
    arguments = (x, P, rows + 0.01, rows, jacobians, R, observed)
    for checked, unchecked in zip(
        batched.range_bearing_update(*arguments), batched.range_bearing_update(*arguments, check_input=False)
    ):
        np.testing.assert_array_equal(checked, unchecked)


def test_updates_and_predictions_leave_their_inputs_alone():
    rng = np.random.default_rng(19)
    x, P = random_states(rng, 4, 2), random_covariances(rng, 4, 6)
    x_before, P_before = x.copy(), P.copy()
    batched.predict_team(x, P, random_controls(rng, (4, 2)), 0.5, np.eye(2) * 0.01, check_input=False)
    batched.gps_update(x, P, x.reshape(4, 2, 3)[..., :2] + 0.1, np.eye(2) * 0.01, np.ones((4, 2), dtype=bool))
    observers, targets = np.array([[0, 1]] * 4), np.array([[1, 0]] * 4)
    predicted, H_observer, H_target = batched.relative_pose_model(x, observers, targets)
    R = np.broadcast_to(np.eye(3) * 0.01, (4, 2, 3, 3))
    batched.relative_pose_update(x, P, observers, targets, predicted + 0.01, predicted, H_observer, H_target, R)
    predicted, H = batched.landmark_measurement_model(x[:, :3], rng.uniform(-10, 10, (3, 2)))
    batched.range_bearing_update(
        x[:, :3], P[:, :3, :3], predicted[:, 0] + 0.01, predicted[:, 0], H[:, 0], R[:, 0, :2, :2]
    )
    np.testing.assert_array_equal(x, x_before)
    np.testing.assert_array_equal(P, P_before)


# ---------------------------------------------------------------------------------------------- team filter


def joint_case(seed: int, n_copies: int, n_robots: int):
    rng = np.random.default_rng(seed)
    x = random_states(rng, n_copies, n_robots)
    return rng, x, random_covariances(rng, n_copies, 3 * n_robots)


def test_joint_gain_is_the_expected_information_gain_of_the_stacked_jacobian():
    rng, x, P = joint_case(3, 2, 3)
    observers, targets = np.array([[0, 2], [1, 0]]), np.array([[1, 0], [2, 2]])
    _, H_observer, H_target = batched.relative_pose_model(x, observers, targets)
    R = np.broadcast_to(np.diag([0.01, 0.001, 0.002]), (2, 2, 3, 3))
    _, joint = batched.relative_pose_information_gains(P, observers, targets, H_observer, H_target, R)
    H = np.zeros((2, 2, 3, 9))
    for copy in range(2):
        for slot in range(2):
            o, t = observers[copy, slot], targets[copy, slot]
            H[copy, slot, :, 3 * o : 3 * o + 3] = H_observer[copy, slot]
            H[copy, slot, :, 3 * t : 3 * t + 3] = H_target[copy, slot]
    np.testing.assert_allclose(joint, batched.landmark_information_gains(P, H, R), rtol=0, atol=P_TOLERANCE)


def _pose_case():
    rng = np.random.default_rng(0)
    x, P = random_states(rng, 2, n_landmarks=1), random_covariances(rng, 2, 5)
    return x, P


def _team_case():
    rng = np.random.default_rng(1)
    x, P = random_states(rng, 2, 3), random_covariances(rng, 2, 9)
    return x, P


X, P = _pose_case()
XJ, PJ = _team_case()
ODOMETRY = np.diag([0.05**2, 0.02**2])
NAN_STATE = np.where(np.arange(5) == 1, np.nan, X)
NOT_SPD = -np.eye(2)
RB_ARGS = {
    "measurements": np.ones((2, 2)),
    "predicted": np.ones((2, 2)),
    "H": np.ones((2, 2, 5)),
    "R": np.broadcast_to(np.eye(2) * 0.01, (2, 2, 2)),
    "observed": np.array([True, False]),
}
OBSERVERS, TARGETS = np.array([[0, 1], [2, 0]]), np.array([[1, 2], [1, 2]])
REL_ARGS = {
    "observers": OBSERVERS,
    "targets": TARGETS,
    "measurements": np.ones((2, 2, 3)),
    "predicted": np.ones((2, 2, 3)),
    "H_observer": np.ones((2, 2, 3, 3)),
    "H_target": np.ones((2, 2, 3, 3)),
    "R": np.broadcast_to(np.eye(3) * 0.01, (2, 2, 3, 3)),
    "observed": np.ones((2, 2), dtype=bool),
}


@pytest.mark.parametrize(
    "call, message",
    [
        (
            lambda: batched.predict_pose(X[0], P, np.zeros((2, 2)), 0.5, ODOMETRY),
            r"x must be a stack of states \(N, n\)",
        ),
        (lambda: batched.predict_pose(NAN_STATE, P, np.zeros((2, 2)), 0.5, ODOMETRY), "x must be finite"),
        (
            lambda: batched.predict_pose(X, P[:, :3, :3], np.zeros((2, 2)), 0.5, ODOMETRY),
            r"P must have shape \(2, 5, 5\)",
        ),
        (lambda: batched.predict_pose(X, -P, np.zeros((2, 2)), 0.5, ODOMETRY), "P is not positive definite"),
        (lambda: batched.predict_pose(X, P, np.zeros((3, 2)), 0.5, ODOMETRY), r"controls must have shape \(2, 2\)"),
        (lambda: batched.predict_pose(X, P, np.full((2, 2), np.inf), 0.5, ODOMETRY), "controls must be finite"),
        (lambda: batched.predict_pose(X, P, np.zeros((2, 2)), -0.5, ODOMETRY), "dt must be a finite time step >= 0"),
        (lambda: batched.predict_pose(X, P, np.zeros((2, 2)), 0.5, NOT_SPD), "control_covariance is not positive"),
        (
            lambda: batched.predict_pose(X, P, np.zeros((2, 2)), 0.5, np.eye(3)),
            r"control_covariance must have shape \(2, 2, 2\) \(or broadcast to it\), got \(3, 3\)",
        ),
        (
            lambda: batched.predict_team(X, P, np.zeros((2, 1, 2)), 0.5, ODOMETRY),
            "joint states must hold only robot poses",
        ),
        (
            lambda: batched.predict_team(XJ, PJ, np.zeros((2, 2, 2)), 0.5, ODOMETRY),
            r"controls must have shape \(2, 3, 2\)",
        ),
        (lambda: batched.landmark_measurement_model(X[:, :4]), r"x must be \[pose, l1x, l1y, ...\]"),
        (
            lambda: batched.landmark_measurement_model(X, np.zeros((3, 4, 2))),
            r"landmarks must have shape \(K, 2\) or \(2, K, 2\), got \(3, 4, 2\)",
        ),
        (lambda: batched.landmark_measurement_model(X, [[np.nan, 0.0]]), "landmarks must be finite"),
        (lambda: batched.landmark_measurement_model(X, X[:, None, :2]), "a target coincides with the sensor position"),
        (
            lambda: batched.landmark_information_gains(P, np.ones((2, 3, 2, 4)), np.ones((2, 3, 2, 2))),
            r"H must have shape \(2, K, m, 5\)",
        ),
        (
            lambda: batched.landmark_information_gains(
                P, np.ones((2, 3, 2, 5)), np.broadcast_to(NOT_SPD, (2, 3, 2, 2))
            ),
            "R is not positive definite",
        ),
        (lambda: batched.pose_log_dets(PJ, 4), r"n_robots must be an int in \[1, 3\]"),
        (lambda: batched.pose_log_dets(PJ[0], 1), r"P must be a stack of covariances \(N, n, n\)"),
        (lambda: batched.relative_pose_model(XJ, OBSERVERS, OBSERVERS), r"observers\[0, 0\] = targets\[0, 0\] = 0"),
        (lambda: batched.relative_pose_model(XJ, OBSERVERS, TARGETS + 1), r"targets must hold indices in \[0, 2\]"),
        (
            lambda: batched.relative_pose_model(np.zeros((1, 6)), np.array([[0]]), np.array([[1]])),
            "a target coincides with the sensor position",
        ),
        (lambda: batched.relative_pose_model(XJ, OBSERVERS[0], TARGETS[0]), r"observers must have shape \(2, M\)"),
        (lambda: batched.relative_pose_model(XJ, OBSERVERS * 1.0, TARGETS), "observers must be an int array"),
        (
            lambda: batched.gps_update(XJ, PJ, np.zeros((2, 3, 2)), np.eye(2), np.ones((2, 3))),
            r"has_fix must be a bool array of shape \(2, 3\), got float64",
        ),
        (
            lambda: batched.gps_update(XJ, PJ, np.zeros((2, 2, 2)), np.eye(2), np.ones((2, 3), dtype=bool)),
            r"fixes must have shape \(2, 3, 2\)",
        ),
        (
            lambda: batched.gps_update(XJ, PJ, np.zeros((2, 3, 2)), NOT_SPD, np.ones((2, 3), dtype=bool)),
            "noise_covariances is not positive definite",
        ),
    ],
)
def test_bad_inputs_raise_value_errors_naming_them(call, message):
    with pytest.raises(ValueError, match=message):
        call()


@pytest.mark.parametrize(
    "key, value, message",
    [
        ("observed", np.array([1, 0]), r"observed must be a bool array of shape \(2,\), got int64"),
        ("measurements", np.ones((2, 3)), r"measurements must have shape \(2, 2\)"),
        ("predicted", np.full((2, 2), np.nan), "predicted must be finite"),
        ("H", np.ones((2, 2, 3)), r"H must have shape \(2, 2, 5\)"),
        ("R", np.broadcast_to(NOT_SPD, (2, 2, 2)), "R is not positive definite"),
    ],
)
def test_range_bearing_update_refuses_bad_inputs(key, value, message):
    with pytest.raises(ValueError, match=message):
        batched.range_bearing_update(X, P, **{**RB_ARGS, key: value})


@pytest.mark.parametrize(
    "key, value, message",
    [
        ("targets", OBSERVERS, r"observers\[0, 0\] = targets\[0, 0\] = 0"),
        ("observers", np.array([[0, 3], [2, 0]]), r"observers must hold indices in \[0, 2\]"),
        ("observed", np.ones((2, 3), dtype=bool), r"observed must be a bool array of shape \(2, 2\)"),
        ("measurements", np.ones((2, 2, 4)), r"measurements must have shape \(2, 2, 3\)"),
        ("H_target", np.ones((2, 2, 2, 3)), r"H_target must have shape \(2, 2, 3, 3\)"),
        ("R", np.broadcast_to(-np.eye(3), (2, 2, 3, 3)), "R is not positive definite"),
    ],
)
def test_relative_pose_update_refuses_bad_inputs(key, value, message):
    with pytest.raises(ValueError, match=message):
        batched.relative_pose_update(XJ, PJ, **{**REL_ARGS, key: value})


LANDMARK_ARGS = {
    "robots": OBSERVERS,
    "measurements": np.ones((2, 2, 2)),
    "predicted": np.ones((2, 2, 2)),
    "H_pose": np.ones((2, 2, 2, 3)),
    "R": np.broadcast_to(np.eye(2) * 0.01, (2, 2, 2, 2)),
    "observed": np.array([[True, True], [False, True]]),
}


@pytest.mark.parametrize(
    "key, value, message",
    [
        ("robots", np.array([0, 1]), r"robots must have shape \(2, M\), got \(2,\)"),
        ("robots", np.array([[0, 3], [2, 0]]), r"robots must hold indices in \[0, 2\]"),
        ("observed", np.ones((2, 2)), r"observed must be a bool array of shape \(2, 2\), got float64"),
        ("measurements", np.ones((2, 2, 3)), r"measurements must have shape \(2, 2, 2\)"),
        ("H_pose", np.full((2, 2, 2, 3), np.nan), "H_pose must be finite"),
        ("R", np.broadcast_to(NOT_SPD, (2, 2, 2, 2)), "R is not positive definite"),
    ],
)
def test_team_landmark_update_refuses_bad_inputs(key, value, message):
    with pytest.raises(ValueError, match=message):
        batched.team_landmark_update(XJ, PJ, **{**LANDMARK_ARGS, key: value})


def test_an_unobserved_slot_may_pair_a_robot_with_itself():
    """Placeholder pairs of slots that take no measurement are not checked as pairs (nor used)."""
    observed = np.array([[True, False], [False, False]])
    arguments = {**REL_ARGS, "targets": np.array([[1, 1], [2, 2]]), "observed": observed}
    x_new, P_new = batched.relative_pose_update(XJ, PJ, **arguments)
    np.testing.assert_array_equal(P_new[1], PJ[1])
    assert not np.allclose(P_new[0], PJ[0])


def test_posterior_covariance_is_filterpys_and_a_zero_row_with_unit_noise_is_no_measurement():
    from filterpy.kalman import ExtendedKalmanFilter

    rng = np.random.default_rng(11)
    P = random_covariances(rng, 4, 6)
    H = rng.normal(0.0, 1.0, (4, 3, 6))
    R = random_covariances(rng, 4, 3)
    posterior = batched.posterior_covariance(P, H, R)
    for copy in range(4):
        ekf = ExtendedKalmanFilter(dim_x=6, dim_z=3)
        ekf.x, ekf.P = np.zeros((6, 1)), P[copy].copy()
        ekf.update(np.zeros((3, 1)), lambda x, H=H[copy]: H, lambda x, H=H[copy]: H @ x, R=R[copy])
        np.testing.assert_allclose(posterior[copy], ekf.P, rtol=0, atol=P_TOLERANCE)
    padded_H = np.concatenate([H, np.zeros((4, 2, 6))], axis=1)
    padded_R = np.zeros((4, 5, 5))
    padded_R[:, :3, :3], padded_R[:, 3:, 3:] = R, np.eye(2)
    np.testing.assert_allclose(batched.posterior_covariance(P, padded_H, padded_R), posterior, rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match=r"H must have shape \(4, m, 6\)"):
        batched.posterior_covariance(P, H[:, :, :5], R)
