"""``mrclam_cooperative_localization_v0``: the team's windows of the logs, the joint EKF's readings against filterpy
and finite differences, the outage, the config's errors; on the synthetic exact dataset every test session names
(``conftest.py``), and on Dataset 6 when present."""

from __future__ import annotations

import math
import os
import warnings

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter
from test_mrclam_env import DATASET6, needs_dataset6

from infonav_gym import make_env
from infonav_gym.datasets import DatasetNotFound, mrclam
from infonav_gym.datasets.mrclam_logs import DATASET_VARIABLE
from infonav_gym.datasets.noise_model import shipped_noise_model
from infonav_gym.envs.mrclam_cooperative_localization.scenario import reading_model
from infonav_gym.geometry import wrap_angle

ENV_ID = "mrclam_cooperative_localization_v0"


def greedy_actions(infos: dict) -> dict:
    return {agent: int(np.argmax(info["action_information_gain"])) for agent, info in infos.items()}


def test_each_robots_mask_is_what_it_measured_in_the_step_and_never_itself():
    env = make_env(ENV_ID, max_cycles=12, outage_to_s=10.0, outage_from_s=10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dataset = mrclam.load(os.environ[DATASET_VARIABLE])
    targets = [*dataset.landmark_ids, *dataset.robots]
    _, infos = env.reset(seed=2)
    step_s = env.unwrapped.vector.config["time_step_s"]
    for _ in range(12):
        for k, (robot, (agent, info)) in enumerate(zip(dataset.robots, infos.items())):
            start = dataset.start_time + info["log_time_s"]
            rows = np.concatenate([dataset.landmark_measurements[robot], dataset.robot_measurements[robot]])
            rows = rows[(rows[:, 0] >= start - 0.01) & (rows[:, 0] < start + step_s - 0.01)]  # the 0.02 s ticks
            assert info["action_mask"][0] == 1 and agent == f"robot_{k}"
            assert {targets[k] for k in np.flatnonzero(info["action_mask"][1:])} == {int(s) for s in rows[:, 1]}
            assert robot not in {targets[k] for k in np.flatnonzero(info["action_mask"][1:])}
        _, _, _, _, infos = env.step(greedy_actions(infos))


def test_the_reading_jacobians_are_the_derivatives_of_range_and_bearing():
    rng = np.random.default_rng(0)
    landmarks = rng.uniform(-3, 3, (2, 2))
    x = rng.uniform(-2, 2, 9)

    def model(state, robot, target):
        predicted, H = np.empty(2), np.empty((2, 9))
        assert reading_model(state, robot, target, landmarks, predicted, H)
        return predicted, H

    for robot, target in ((0, 1), (2, 0), (1, 2 + 0), (0, 2 + 2)):  # landmarks, then robots 0..2 after the two
        predicted, H = model(x, robot, target)
        numeric = np.empty((2, 9))
        for k in range(9):
            step = np.zeros(9)
            step[k] = 1e-6
            difference = model(x + step, robot, target)[0] - model(x - step, robot, target)[0]
            numeric[:, k] = [difference[0], wrap_angle(difference[1])] / np.float64(2e-6)
        np.testing.assert_allclose(H, numeric, atol=1e-6)
        own = slice(3 * robot, 3 * robot + 3)
        dx, dy = (landmarks[target] if target < 2 else x[3 * (target - 2) : 3 * (target - 2) + 2]) - x[own][:2]
        assert predicted == pytest.approx([math.hypot(dx, dy), wrap_angle(math.atan2(dy, dx) - x[own][2])])


def test_a_reading_at_the_steps_start_is_filterpys_update_and_its_reward_the_expected_gain():
    env = make_env(ENV_ID, max_cycles=30, outage_to_s=10.0)
    vector = env.unwrapped.vector
    _, infos = env.reset(seed=1)
    checked = 0
    for _ in range(30):
        decision, state = vector.decision, vector.state
        offsets, readings = decision.offsets[0], decision.readings[0]
        valid = decision.action_mask[0, 0, 1:] & (offsets[0] == 0)  # robot_0's readings at the step's first tick
        if not valid.any():
            _, _, _, _, infos = env.step(dict.fromkeys(infos, 0))
            continue
        target = int(np.flatnonzero(valid)[0])
        x, P = state.x[0].copy(), state.P[0].copy()
        predicted, H = np.empty(2), np.empty((2, len(x)))
        reading_model(x, 0, target, vector.env_scenario.windows.landmarks, predicted, H)
        ekf = ExtendedKalmanFilter(dim_x=len(x), dim_z=2)
        ekf.x, ekf.P, ekf.R = x.copy(), P.copy(), decision.noise[0, 0, target]
        ekf.update(
            readings[0, target],
            HJacobian=lambda _, H=H: H,
            Hx=lambda _, predicted=predicted: predicted,
            residual=lambda a, b: np.array([a[0] - b[0], wrap_angle(a[1] - b[1])]),
        )
        agents = list(infos)
        expected = infos[agents[0]]["action_information_gain"][1 + target]
        actions = {agent: 1 + target if agent == agents[0] else 0 for agent in agents}
        _, rewards, _, _, infos = env.step(actions)
        if infos[agents[0]]["gated"]:
            continue
        own_prior, own_post = np.linalg.det(P[:3, :3]), np.linalg.det(ekf.P[:3, :3])
        assert rewards[agents[0]] == pytest.approx(0.5 * math.log(own_prior / own_post), rel=1e-9)
        assert rewards[agents[0]] == pytest.approx(expected, rel=1e-9)  # the posterior does not depend on the reading
        team = infos[agents[0]]["reward_team_mutual_information"]
        assert team == pytest.approx(0.5 * math.log(np.linalg.det(P) / np.linalg.det(ekf.P)), rel=1e-9)
        checked += 1
    assert checked >= 5


def test_the_outage_robot_has_no_landmark_in_its_outage_and_its_teammates_carry_it():
    env = make_env(ENV_ID, max_cycles=60, outage_robot=0, outage_from_s=5.0, outage_to_s=25.0)
    n_landmarks = len(env.unwrapped.vector.env_scenario.windows.landmarks)
    _, infos = env.reset(seed=0)
    relative = 0
    for step in range(60):
        in_outage = 5.0 <= step * 0.5 < 25.0
        assert infos["robot_0"]["landmarks_available"] == (not in_outage)
        assert infos["robot_1"]["landmarks_available"]
        if in_outage:
            assert not infos["robot_0"]["action_mask"][1 : 1 + n_landmarks].any()
            relative += infos["robot_0"]["action_mask"][1 + n_landmarks :].any()
        _, _, _, _, infos = env.step(greedy_actions(infos))
    assert relative >= 20  # it saw its teammate through most of the outage
    assert infos["robot_0"]["position_error_m"] < 0.05


def test_fusing_the_exact_logs_keeps_the_team_on_the_truth_and_fusing_nothing_does_not():
    errors = {}
    for policy in ("greedy", "none"):
        env = make_env(ENV_ID, max_cycles=80, initial_position_std_m=0.3)
        _, infos = env.reset(seed=0)
        while env.agents:
            actions = greedy_actions(infos) if policy == "greedy" else dict.fromkeys(infos, 0)
            _, _, _, _, infos = env.step(actions)
        errors[policy] = max(info["position_error_m"] for info in infos.values())
    assert errors["greedy"] < 0.02 < errors["none"]


def test_bad_configs_and_a_missing_dataset_name_what_is_wrong(tmp_path):
    with pytest.raises(ValueError, match="config key 'outage_robot' of .*: no robot_2 in a team of 2"):
        make_env(ENV_ID, outage_robot=2)
    with pytest.raises(ValueError, match="config key 'outage_to_s' of .* must not precede 'outage_from_s'"):
        make_env(ENV_ID, outage_from_s=5.0, outage_to_s=4.0)
    with pytest.raises(ValueError, match="no 101 windows of 0.5 s with every robot's ground truth"):
        make_env(ENV_ID, time_from_s=100.0)
    with pytest.raises(ValueError, match="time_step_s"):
        make_env(ENV_ID, time_step_s=0.0)
    with pytest.raises(DatasetNotFound, match="no MRCLAM dataset directory at .*nowhere"):
        make_env(ENV_ID, dataset_dir=str(tmp_path / "nowhere"))


def test_episodes_stay_inside_the_configured_time_range():
    env = make_env(ENV_ID, max_cycles=10, time_from_s=40.0, time_to_s=60.0)
    for seed in range(5):
        _, infos = env.reset(seed=seed)
        while env.agents:
            assert 40.0 <= infos["robot_0"]["log_time_s"] <= 60.0
            _, _, _, _, infos = env.step(greedy_actions(infos))


@needs_dataset6
def test_on_dataset6_greedy_beats_fusing_nothing_and_the_outage_robot_leans_on_its_teammates():
    errors = {}
    for policy in ("greedy", "none"):
        env = make_env(ENV_ID, dataset_dir=str(DATASET6), outage_from_s=0.0, outage_to_s=50.0)
        squared, relative = [], 0
        for seed in range(3):
            _, infos = env.reset(seed=seed)
            while env.agents:
                actions = greedy_actions(infos) if policy == "greedy" else dict.fromkeys(infos, 0)
                relative += actions["robot_0"] >= 1
                _, _, _, _, infos = env.step(actions)
                squared += [info["position_error_m"] ** 2 for info in infos.values()]
        errors[policy] = math.sqrt(np.mean(squared))
        if policy == "greedy":
            assert relative > 0  # in its outage robot_0 can only fuse teammates
    assert errors["greedy"] < 0.5 * errors["none"]


def test_fusing_every_reading_fuses_what_each_robot_measured_whatever_the_actions():
    env = make_env(ENV_ID, max_cycles=20, fuse_every_reading=True)
    _, infos = env.reset(seed=0)
    for _ in range(20):
        measured = {agent: int(info["action_mask"][1:].sum()) for agent, info in infos.items()}
        _, _, _, _, infos = env.step(dict.fromkeys(infos, 0))
        for agent, info in infos.items():
            assert info["fused_readings"] + info["gated"] <= measured[agent]
            assert info["fused_readings"] == measured[agent] or info["gated"]


def test_calibrated_noise_is_the_calibrations_pooled_noise_at_each_readings_range():
    env = make_env(ENV_ID, max_cycles=8, calibrated_noise=True, log_correction="shipped")
    model = shipped_noise_model().pooled
    _, infos = env.reset(seed=0)
    for _ in range(8):
        decision = env.unwrapped.vector.decision
        robot, target = np.argwhere(decision.action_mask[0, :, 1:])[0]
        expected = model.total_noise(decision.readings[0, robot, target, 0])
        np.testing.assert_allclose(decision.noise[0, robot, target], expected, rtol=1e-12)
        _, _, _, _, infos = env.step(greedy_actions(infos))
    covariance = env.unwrapped.vector.env_scenario.control_covariance[0, 1]
    np.testing.assert_allclose(covariance, np.diag(model.odometry_density() ** 2) / 0.02, rtol=1e-12)
