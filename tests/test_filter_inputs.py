"""PoseEKF / JointEKF refuse NaN / inf inputs and non-positive-definite or non-symmetric noise with a ValueError.

Each bad call leaves the filter as it was (no NaN creeps into the state); ``check_input=False``
(the envs' hot path) gives the same numbers as the checked call on good inputs.
"""

import math

import numpy as np
import pytest

from infonav_gym.estimation import JointEKF, PoseEKF

NAN, INF = math.nan, math.inf
Q_ODOMETRY = np.diag([0.05**2, 0.02**2])
R_RANGE_BEARING = np.diag([0.1**2, math.radians(2.0) ** 2])
R_RELATIVE = np.diag([0.05**2, math.radians(1.0) ** 2, math.radians(3.0) ** 2])
NOT_SYMMETRIC = np.array([[0.01, 0.002], [0.0, 0.01]])
NOT_POSITIVE_DEFINITE = np.array([[0.01, 0.0], [0.0, -0.01]])
SINGULAR = np.array([[0.01, 0.01], [0.01, 0.01]])


def pose_ekf() -> PoseEKF:
    return PoseEKF([1.0, 2.0, 0.3], np.diag([0.1, 0.1, 0.01]))


def joint_ekf() -> JointEKF:
    poses = np.array([[0.0, 0.0, 0.1], [6.0, 1.0, -0.4], [2.0, -5.0, 2.5]])
    return JointEKF(poses, np.repeat(np.diag([0.1, 0.1, 0.01])[None], 3, axis=0))


def range_bearing_args(ekf: PoseEKF) -> dict:
    predicted, H = ekf.landmark_measurement_model(np.array([[5.0, 4.0]]))
    return {"measurement": predicted[0] + [0.05, -0.01], "predicted": predicted[0], "H": H[0], "R": R_RANGE_BEARING}


def relative_args(ekf: JointEKF) -> dict:
    predicted, H_observer, H_target = ekf.relative_pose_model([0], [1])
    return {
        "observers": [0],
        "targets": [1],
        "measurements": predicted + [0.05, 0.02, -0.03],
        "predicted": predicted,
        "H_observer": H_observer,
        "H_target": H_target,
        "R": R_RELATIVE[None],
    }


def assert_refused_and_unchanged(ekf, method: str, kwargs: dict, message: str):
    x, P = ekf.x.copy(), ekf.P.copy()
    with pytest.raises(ValueError, match=message):
        getattr(ekf, method)(**kwargs)
    np.testing.assert_array_equal(ekf.x, x)
    np.testing.assert_array_equal(ekf.P, P)


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        ({"control": [NAN, 0.1]}, r"control must be finite"),
        ({"control": [1.0, INF]}, r"control must be finite"),
        ({"control": [1.0]}, r"control must have shape \(2,\)"),
        ({"dt": NAN}, "dt must be a finite time step >= 0"),
        ({"dt": -0.5}, "dt must be a finite time step >= 0"),
        ({"dt": INF}, "dt must be a finite time step >= 0"),
        ({"control_covariance": np.diag([NAN, 0.1])}, "control_covariance must be finite"),
        ({"control_covariance": np.diag([INF, 0.1])}, "control_covariance must be finite"),
        ({"control_covariance": NOT_SYMMETRIC}, "control_covariance is not symmetric"),
        ({"control_covariance": NOT_POSITIVE_DEFINITE}, "control_covariance is not positive definite"),
        ({"control_covariance": SINGULAR}, "control_covariance is not positive definite"),
    ],
)
def test_pose_ekf_predict_refuses_bad_inputs(bad, message):
    kwargs = {"control": [1.0, 0.1], "dt": 0.5, "control_covariance": Q_ODOMETRY, **bad}
    assert_refused_and_unchanged(pose_ekf(), "predict", kwargs, message)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("measurement", [NAN, 0.1], "measurement must be finite"),
        ("measurement", [INF, 0.1], "measurement must be finite"),
        ("measurement", [5.0, 0.1, 0.0], r"measurement must have shape \(2,\)"),
        ("predicted", [5.0, NAN], "predicted must be finite"),
        ("H", np.full((2, 3), NAN), "H must be finite"),
        ("H", np.zeros((2, 5)), r"H must have shape \(2, 3\)"),
        ("R", np.diag([NAN, 0.1]), "R must be finite"),
        ("R", np.diag([INF, 0.1]), "R must be finite"),
        ("R", NOT_SYMMETRIC, "R is not symmetric"),
        ("R", NOT_POSITIVE_DEFINITE, "R is not positive definite"),
        ("R", np.zeros((2, 2)), "R is not positive definite"),
    ],
)
def test_pose_ekf_range_bearing_update_refuses_bad_inputs(key, value, message):
    ekf = pose_ekf()
    kwargs = {**range_bearing_args(ekf), key: value}
    assert_refused_and_unchanged(ekf, "update_range_bearing", kwargs, message)


def test_pose_ekf_refuses_non_finite_initial_landmarks():
    with pytest.raises(ValueError, match="landmarks must be finite"):
        PoseEKF([0.0, 0.0, 0.0], np.eye(3), landmarks=[[1.0, NAN]], landmark_covariance=1.0)


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        ({"controls": np.array([[1.0, 0.0], [NAN, 0.0], [1.0, 0.0]])}, "controls must be finite"),
        ({"controls": np.zeros((2, 2))}, r"controls must have shape \(3, 2\)"),
        ({"dt": INF}, "dt must be a finite time step >= 0"),
        ({"control_covariances": np.stack([Q_ODOMETRY, NOT_SYMMETRIC, Q_ODOMETRY])}, "is not symmetric"),
        ({"control_covariances": np.stack([Q_ODOMETRY, Q_ODOMETRY, SINGULAR])}, "is not positive definite"),
        ({"control_covariances": np.full((3, 2, 2), INF)}, "control_covariances must be finite"),
    ],
)
def test_joint_ekf_predict_refuses_bad_inputs(bad, message):
    kwargs = {"controls": np.ones((3, 2)), "dt": 0.5, "control_covariances": np.repeat(Q_ODOMETRY[None], 3, 0), **bad}
    assert_refused_and_unchanged(joint_ekf(), "predict", kwargs, message)


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        ({"fixes": [[0.1, NAN]]}, "fixes must be finite"),
        ({"fixes": [[0.1, 0.2], [0.3, 0.4]]}, r"fixes must have shape \(1, 2\)"),
        ({"noise_covariances": [np.diag([INF, 0.01])]}, "noise_covariances must be finite"),
        ({"noise_covariances": [np.diag([1e-2, -1e-2])]}, "noise_covariances is not positive definite"),
        ({"noise_covariances": [NOT_SYMMETRIC]}, "noise_covariances is not symmetric"),
        ({"robots": [3]}, r"robots must be robot indices in \[0, 2\]"),
        ({"robots": [0.5]}, "robots must be a sequence of robot indices"),
    ],
)
def test_joint_ekf_gps_update_refuses_bad_inputs(bad, message):
    kwargs = {"robots": [0], "fixes": [[0.1, -0.1]], "noise_covariances": [np.eye(2) * 0.01], **bad}
    assert_refused_and_unchanged(joint_ekf(), "gps_update", kwargs, message)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("measurements", np.array([[NAN, 0.0, 0.0]]), "measurements must be finite"),
        ("measurements", np.array([[5.0, INF, 0.0]]), "measurements must be finite"),
        ("predicted", np.zeros((2, 3)), r"predicted must have shape \(1, 3\)"),
        ("H_observer", np.full((1, 3, 3), NAN), "H_observer must be finite"),
        ("H_target", np.full((1, 3, 3), INF), "H_target must be finite"),
        ("R", np.diag([NAN, 1e-4, 1e-3])[None], "R must be finite"),
        ("R", np.diag([1e-2, 1e-4, 0.0])[None], "R is not positive definite"),
        ("R", (R_RELATIVE + np.triu(np.full((3, 3), 1e-3), 1))[None], "R is not symmetric"),
        ("targets", [5], r"targets must be robot indices in \[0, 2\]"),
        ("targets", [1, 2], "observers and targets must pair up"),
    ],
)
def test_joint_ekf_relative_pose_update_refuses_bad_inputs(key, value, message):
    ekf = joint_ekf()
    kwargs = {**relative_args(ekf), key: value}
    assert_refused_and_unchanged(ekf, "relative_pose_update", kwargs, message)


def test_unchecked_hot_path_equals_the_checked_call_bit_for_bit():
    checked, unchecked = pose_ekf(), pose_ekf()
    checked.predict([1.0, 0.1], 0.5, Q_ODOMETRY)
    unchecked.predict(np.array([1.0, 0.1]), 0.5, Q_ODOMETRY, check_input=False)
    checked.update_range_bearing(**range_bearing_args(checked))
    unchecked.update_range_bearing(**range_bearing_args(unchecked), check_input=False)
    np.testing.assert_array_equal(checked.x, unchecked.x)
    np.testing.assert_array_equal(checked.P, unchecked.P)
    joint_checked, joint_unchecked = joint_ekf(), joint_ekf()
    for ekf, check in ((joint_checked, True), (joint_unchecked, False)):
        ekf.predict(np.ones((3, 2)), 0.5, np.repeat(Q_ODOMETRY[None], 3, 0), check_input=check)
        ekf.gps_update(np.array([0]), np.array([[0.6, 0.0]]), np.eye(2)[None] * 0.01, check_input=check)
        ekf.relative_pose_update(**relative_args(ekf), check_input=check)
    np.testing.assert_array_equal(joint_checked.x, joint_unchecked.x)
    np.testing.assert_array_equal(joint_checked.P, joint_unchecked.P)
    assert np.all(np.isfinite(joint_checked.P))


def test_joint_ekf_relative_update_without_the_heading_is_checked_too():
    """Range and bearing only (m = 2), as the MRCLAM replay uses it."""
    ekf = joint_ekf()
    full = relative_args(ekf)
    kwargs = {**full, "measurements": full["measurements"][:, :2], "predicted": full["predicted"][:, :2]}
    kwargs.update(H_observer=full["H_observer"][:, :2], H_target=full["H_target"][:, :2], R=R_RELATIVE[None, :2, :2])
    ekf.relative_pose_update(**kwargs)
    assert np.all(np.isfinite(ekf.P))
    bad = {**kwargs, "R": np.full((1, 2, 2), NAN)}
    assert_refused_and_unchanged(ekf, "relative_pose_update", bad, "R must be finite")
