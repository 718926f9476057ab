"""``infonav/MRCLAMLocalization-v0``: the logs as episodes, the EKF against filterpy, the gate, the config's errors; on
the synthetic exact dataset every test session names (``conftest.py``), and on Dataset 6 when present."""

from __future__ import annotations

import math
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter
from mrclam_exact import LANDMARKS, write_dataset

from infonav_gym import make_env
from infonav_gym.datasets import DatasetNotFound, mrclam
from infonav_gym.datasets.mrclam_logs import DATASET_VARIABLE
from infonav_gym.datasets.noise_model import shipped_noise_model
from infonav_gym.envs.vector_infos import reward_terms_of
from infonav_gym.experiments.cli import main
from infonav_gym.geometry import wrap_angle
from infonav_gym.registry import available_envs

ENV_ID = "infonav/MRCLAMLocalization-v0"
DATASET6 = Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets" / "MRCLAM_Dataset6"
needs_dataset6 = pytest.mark.skipif(not DATASET6.is_dir(), reason=f"MRCLAM Dataset 6 is not at {DATASET6}")


def test_the_mask_is_what_the_robot_measured_at_that_time_and_the_none_action_is_always_valid():
    env = make_env(ENV_ID, horizon=20)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dataset = mrclam.load(os.environ[DATASET_VARIABLE])
    subjects = {row: subject for row, subject in enumerate(dataset.landmark_ids)}
    _, info = env.reset(seed=3)
    for _ in range(20):
        rows = dataset.landmark_measurements[info["robot"]]
        at = np.abs(rows[:, 0] - dataset.start_time - info["time_s"]) <= 0.01  # within the 0.02 s tick
        measured = {int(subject) for subject in rows[at, 1]}
        assert info["action_mask"][0] == 1
        assert {subjects[k] for k in np.flatnonzero(info["action_mask"][1:])} == measured
        _, _, _, _, info = env.step(int(np.flatnonzero(info["action_mask"])[-1]))


def test_a_fused_reading_is_filterpys_ekf_update_and_its_reward_the_expected_gain():
    env = make_env(ENV_ID, horizon=10)
    _, info = env.reset(seed=1)
    state = env.unwrapped.vector.state
    for _ in range(10):
        action = int(np.argmax(np.where(info["action_mask"], info["action_information_gain"], -1.0)))
        x, P = state.x[0].copy(), state.P[0].copy()
        decision = env.unwrapped.vector.decision
        H, predicted = decision.H[0, action - 1], decision.predicted[0, action - 1]
        ekf = ExtendedKalmanFilter(dim_x=3, dim_z=2)
        ekf.x, ekf.P, ekf.R = x.copy(), P.copy(), decision.R[0, action - 1]
        ekf.update(
            decision.readings[0, action - 1],
            HJacobian=lambda _, H=H: H,
            Hx=lambda _, predicted=predicted: predicted,
            residual=lambda a, b: np.array([a[0] - b[0], wrap_angle(a[1] - b[1])]),
        )
        expected = info["action_information_gain"][action]
        _, reward, _, _, info = env.step(action)
        assert not info["gated"]
        assert reward == pytest.approx(0.5 * math.log(np.linalg.det(P) / np.linalg.det(ekf.P)), rel=1e-9)
        assert reward == pytest.approx(expected, rel=1e-9)  # the posterior does not depend on the reading
        # the next prior is the posterior predicted through the odometry: its pose moved, its covariance grew
        assert np.linalg.det(state.P[0]) > np.linalg.det(ekf.P)


def test_fusing_the_exact_logs_keeps_the_estimate_on_the_truth_and_fusing_nothing_does_not():
    errors = {}
    for policy in ("greedy", "none"):
        env = make_env(ENV_ID, horizon=60, initial_position_std_m=0.3)
        _, info = env.reset(seed=0)
        for _ in range(60):
            gains = np.where(info["action_mask"], info["action_information_gain"], -1.0)
            _, _, _, truncated, info = env.step(int(np.argmax(gains)) if policy == "greedy" else 0)
        errors[policy] = info["position_error_m"]
        assert truncated
    assert errors["greedy"] < 0.02 < errors["none"]


def test_a_reading_beyond_the_gate_is_not_fused_and_earns_nothing():
    env = make_env(ENV_ID, horizon=5, gate_nis=1e-3, initial_position_std_m=0.5)
    _, info = env.reset(seed=2)
    before = env.unwrapped.vector.state.P[0].copy()
    _, reward, _, _, info = env.step(int(np.flatnonzero(info["action_mask"])[-1]))
    assert info["gated"] and reward == 0.0 and reward_terms_of(info)["mutual_information"] == 0.0
    assert np.linalg.det(env.unwrapped.vector.state.P[0]) > np.linalg.det(before)  # only predicted


def test_seeds_draw_robots_and_windows_inside_the_configured_robots_and_times():
    env = make_env(ENV_ID, horizon=10, robots="2", time_from_s=30.0, time_to_s=90.0)
    starts = set()
    for seed in range(8):
        _, info = env.reset(seed=seed)
        starts.add(info["time_s"])
        for _ in range(10):
            assert info["robot"] == 2 and 30.0 <= info["time_s"] <= 90.0
            _, _, _, _, info = env.step(0)
    assert len(starts) > 4
    robots = {make_env(ENV_ID, horizon=10).reset(seed=seed)[1]["robot"] for seed in range(12)}
    assert robots == {1, 2}


@pytest.mark.parametrize(
    ("config", "message"),
    [
        ({"robots": "7"}, r"config key 'robots' of MRCLAMLocalizationEnv: no robot \[7\]; has \[1, 2\]"),
        ({"robots": "one"}, r"config key 'robots' of MRCLAMLocalizationEnv must list subject numbers"),
        ({"time_from_s": 100.0, "time_to_s": 110.0}, r"no robot of \[1, 2\] has 101 measurement times"),
        ({"horizon": 10**4}, r"no robot of \[1, 2\] has 10001 measurement times"),
        ({"gate_nis": 0.0}, r"gate_nis"),
    ],
)
def test_config_values_that_leave_no_episode_are_one_line_errors(config, message):
    with pytest.raises(ValueError, match=message):
        make_env(ENV_ID, **config)


def test_a_missing_or_malformed_dataset_is_a_one_line_error_naming_the_path(tmp_path, monkeypatch):
    with pytest.raises(DatasetNotFound, match=rf"no MRCLAM dataset directory at {tmp_path / 'absent'} \(set config"):
        make_env(ENV_ID, dataset_dir=str(tmp_path / "absent"))
    broken = write_dataset(tmp_path / "broken", duration_s=30.0)
    with (broken / "Robot1_Odometry.dat").open("a") as file:
        file.write("1.0 2.0\n")
    with pytest.raises(ValueError, match=r"Robot1_Odometry\.dat, line \d+: malformed line") as error:
        make_env(ENV_ID, dataset_dir=str(broken))
    assert "\n" not in str(error.value)
    monkeypatch.setenv(DATASET_VARIABLE, str(tmp_path / "absent"))
    with pytest.warns(UserWarning, match=rf"{ENV_ID} left out: .*no MRCLAM dataset directory"):
        assert ENV_ID not in {entry.id for entry in available_envs()}


def test_a_calibration_corrects_the_logs_and_a_missing_one_is_a_one_line_error(tmp_path):
    raw, corrected = (make_env(ENV_ID, log_correction=correction) for correction in ("", "shipped"))
    raw_logs, corrected_logs = (env.unwrapped.vector.env_scenario.logs for env in (raw, corrected))
    np.testing.assert_array_equal(raw_logs.landmarks, corrected_logs.landmarks)
    # the shipped model moves the logs onto the ground truth's clock and removes the readings' mean errors
    assert not np.array_equal(raw_logs.robots[0].readings, corrected_logs.robots[0].readings)
    missing = tmp_path / "model.json"
    with pytest.raises(ValueError, match=rf"noise model file {missing} does not exist \(config keys 'dataset_dir' and"):
        make_env(ENV_ID, log_correction=str(missing))


@pytest.mark.parametrize("broken", ["absent", "truncated"])
def test_the_command_line_says_a_bad_dataset_in_one_line_and_exits_2(broken, tmp_path, capsys):
    directory = tmp_path / broken
    if broken == "truncated":
        write_dataset(directory, duration_s=30.0)
        odometry = directory / "Robot2_Odometry.dat"
        odometry.write_text(odometry.read_text()[:-30])  # cut inside its last row
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--env", ENV_ID, "--episodes", "1", "--config", f"dataset_dir={directory}"])
    error = capsys.readouterr().err.strip()
    assert exit_info.value.code == 2 and "\n" not in error
    expected = f"no MRCLAM dataset directory at {directory}" if broken == "absent" else "Robot2_Odometry.dat, line"
    assert expected in error


def test_the_landmark_map_and_the_action_space_come_from_the_dataset():
    env = make_env(ENV_ID)
    assert env.action_space.n == 1 + len(LANDMARKS)
    assert env.observation_space.shape == (10 + 4 * len(LANDMARKS),)
    np.testing.assert_allclose(env.unwrapped.vector.env_scenario.logs.landmarks, list(LANDMARKS.values()))


@needs_dataset6
def test_on_dataset6_fusing_the_greedy_choice_beats_dead_reckoning():
    rmse = {}
    for policy in ("greedy", "none"):
        env, squares = make_env(ENV_ID, dataset_dir=str(DATASET6)), []
        for seed in range(5):
            _, info = env.reset(seed=seed)
            for _ in range(100):
                gains = np.where(info["action_mask"], info["action_information_gain"], -1.0)
                _, _, _, _, info = env.step(int(np.argmax(gains)) if policy == "greedy" else 0)
                squares.append(info["position_error_m"] ** 2)
        rmse[policy] = math.sqrt(np.mean(squares))
    assert rmse["greedy"] < rmse["none"]


def test_fusing_every_reading_is_filterpys_stacked_update_whatever_the_action(tmp_path):
    everywhere = write_dataset(tmp_path / "all_around", field_of_view_rad=2 * math.pi)  # every landmark at a time
    env = make_env(ENV_ID, horizon=30, fuse_every_reading=True, dataset_dir=str(everywhere))
    _, info = env.reset(seed=2)
    vector, several = env.unwrapped.vector, 0
    for _ in range(30):
        decision, state = vector.decision, vector.state
        measured = np.flatnonzero(info["action_mask"][1:])
        x, P = state.x[0].copy(), state.P[0].copy()
        ekf = ExtendedKalmanFilter(dim_x=3, dim_z=2 * len(measured))
        ekf.x, ekf.P = x.copy(), P.copy()
        ekf.R = np.kron(np.eye(len(measured)), decision.R[0, 0]) if len(measured) else np.zeros((0, 0))
        H = decision.H[0, measured].reshape(-1, 3)
        predicted = decision.predicted[0, measured].ravel()

        def residual(a, b):
            difference = a - b
            difference[1::2] = wrap_angle(difference[1::2])
            return difference

        if len(measured):
            ekf.update(
                decision.readings[0, measured].ravel(), lambda _, H=H: H, lambda _, z=predicted: z, residual=residual
            )
        _, reward, _, _, info = env.step(0)  # the action does not matter: every reading is fused
        if info["gated"] or not len(measured):
            continue
        assert info["fused_readings"] == len(measured)
        assert reward == pytest.approx(0.5 * math.log(np.linalg.det(P) / np.linalg.det(ekf.P)), rel=1e-9)
        several += len(measured) >= 2
    assert several >= 3


def test_calibrated_noise_is_the_calibrations_pooled_noise_at_each_readings_range():
    with pytest.raises(ValueError, match="config key 'calibrated_noise' of .* takes the noise of 'log_correction'"):
        make_env(ENV_ID, calibrated_noise=True)
    env = make_env(ENV_ID, horizon=10, calibrated_noise=True, log_correction="shipped")
    model = shipped_noise_model().pooled
    _, info = env.reset(seed=0)
    for _ in range(10):
        decision = env.unwrapped.vector.decision
        for k in np.flatnonzero(info["action_mask"][1:]):
            np.testing.assert_allclose(decision.R[0, k], model.total_noise(decision.readings[0, k, 0]), rtol=1e-12)
        _, _, _, _, info = env.step(0)
    covariance = env.unwrapped.vector.env_scenario.control_covariances[0]
    np.testing.assert_allclose(covariance, np.diag(model.odometry_density() ** 2) / 0.02, rtol=1e-12)
