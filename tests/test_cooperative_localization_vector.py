"""CooperativeLocalizationVectorEnv: copy i equals the parallel env seeded seed + i (its teams, estimators, rewards).

Autoreset, seeding, bad input and rendering: ``test_team_vector_envs.py``, for every team vector env.
"""

import filterpy_reference as oracle
import numpy as np
import pytest
from gymnasium import spaces
from team_vector_checks import record_relative_measurements, run_against_parallel_envs

import infonav_gym
from infonav_gym.envs.cooperative_localization import CooperativeLocalizationVectorEnv, scenario
from infonav_gym.information import mutual_information
from infonav_gym.multi import cooperative_localization_v0
from infonav_gym.registry import PARALLEL, env_entry, make_vector_env, register, unregister
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.relative_pose import (
    RELATIVE_POSE_SENSORS,
    noise_covariances,
    noisy_relative_poses,
    relative_poses_with_noise,
)

TEAM_ID = "cooperative_localization_v0"


@pytest.mark.parametrize("estimator", ["joint", "independent"])
@pytest.mark.parametrize("seed, n_copies", [(0, 3), (11, 2)])
def test_copies_equal_the_parallel_env_seeded_seed_plus_i_through_autoresets(estimator, seed, n_copies):
    """max_cycles 50 reaches robot_1's DGPS outage at 21 s (step 42); 2 episodes and the resets between them."""
    config = {"max_cycles": 50, "estimator": estimator}
    ended = run_against_parallel_envs(TEAM_ID, config, n_copies, seed, "random", 2 * 50 + 2)
    assert ended == {"terminated": 0, "truncated": 2 * n_copies}


@pytest.mark.parametrize(
    "config",
    [
        {"max_cycles": 30, "team_reward": 0.5},
        {"max_cycles": 30, "team_reward": 1.0, "observe_gains": True},
        {"max_cycles": 30, "scenario": "convoy", "n_robots": 3},
        {"max_cycles": 30, "n_robots": 3, "robot_sensors": ["gps", "vision", "laser"], "estimator": "independent"},
    ],
    ids=["team_reward", "observe_gains", "convoy", "vision"],
)
def test_greedy_copies_equal_the_parallel_env_on_other_teams_and_rewards(config):
    assert run_against_parallel_envs(TEAM_ID, config, 2, 5, "greedy", 31) == {"terminated": 0, "truncated": 2}


def test_a_team_without_relative_sensors_has_only_the_no_op():
    config = {"max_cycles": 5, "n_robots": 2, "robot_sensors": ["gps", "gps"]}
    assert run_against_parallel_envs(TEAM_ID, config, 2, 1, "random", 6) == {"terminated": 0, "truncated": 2}
    vector = CooperativeLocalizationVectorEnv(2, **config)
    _, info = vector.reset(seed=0)
    assert not info["action_mask"][..., 1:].any() and not info["action_information_gain"].any()


def test_the_masks_and_gains_vary_so_the_comparison_means_something():
    vector = CooperativeLocalizationVectorEnv(4, max_cycles=20)
    _, info = vector.reset(seed=3)
    masks = info["action_mask"][..., 1:]
    assert 0 < masks.sum() < masks.size
    assert np.all(info["action_information_gain"][..., 1:][masks == 1] > 0)
    assert np.all(info["action_information_gain"][..., 1:][masks == 0] == 0)


@pytest.mark.parametrize(
    "config, message",
    [({"n_robots": 9}, r"n_robots"), ({"estimator": "kalman"}, r"estimator")],
)
def test_a_bad_config_is_a_value_error_naming_it(config, message):
    with pytest.raises(ValueError, match=message):
        CooperativeLocalizationVectorEnv(2, **config)


# ----------------------------------------------------------------------------- the vector API and the registry


def test_spaces_agents_and_registration():
    env = make_vector_env(TEAM_ID, num_envs=5, max_cycles=7)
    team = cooperative_localization_v0.parallel_env()
    assert type(env) is CooperativeLocalizationVectorEnv and env.num_envs == 5 and env.max_cycles == 7
    assert env.agents == team.possible_agents
    assert env.single_observation_space == team.observation_space("robot_0")
    assert env.single_action_space == team.action_space("robot_0") == spaces.Discrete(5)
    assert env.observation_space.shape == (5, 4, 30) and env.action_space == spaces.MultiDiscrete(np.full((5, 4), 5))
    env.close()
    assert env_entry(TEAM_ID).load_vector() is CooperativeLocalizationVectorEnv
    assert infonav_gym.make_vector_env is make_vector_env


def test_make_vector_env_makes_a_gymnasium_envs_native_vector_env_too():
    env = make_vector_env("infonav/LandmarkSelection-v0", 2, horizon=5)
    assert type(env).__name__ == "LandmarkSelectionVectorEnv" and env.num_envs == 2 and env.config["horizon"] == 5


def test_make_vector_env_refuses_an_env_without_a_native_vector_env():
    register("toy/Unbatched-v0", "toy.unbatched:UnbatchedEnv")  # imported only when made
    try:
        with pytest.raises(ValueError, match=r"env 'toy/Unbatched-v0' has no native vector env"):
            make_vector_env("toy/Unbatched-v0", 2)
    finally:
        unregister("toy/Unbatched-v0")
    with pytest.raises(ValueError, match="unknown env id 'nowhere'"):
        make_vector_env("nowhere", 2)


def test_a_parallel_env_may_register_a_vector_entry_point_that_make_vector_env_calls():
    made = []

    def vector_factory(num_envs: int, **config):
        made.append((num_envs, config))
        return "the vector env"

    register("toy/Team-v0", env_entry(TEAM_ID).entry_point, PARALLEL, vector_factory)
    try:
        assert make_vector_env("toy/Team-v0", 3, max_cycles=2) == "the vector env"
        assert made == [(3, {"max_cycles": 2})]
    finally:
        unregister("toy/Team-v0")


def test_the_sensors_given_their_standard_normals_measure_what_they_draw():
    """What the vector env's noise streams feed: the same numbers as the parallel env's sensors draw."""
    positions = np.array([[1.0, 2.0], [-3.0, 0.5]])
    gps = GPSSensor(0.3)
    expected = gps.measure(positions, np.random.default_rng(1))
    np.testing.assert_array_equal(
        gps.measure_with_noise(positions, np.random.default_rng(1).standard_normal((2, 2))), expected
    )
    truth = np.array([[4.0, 0.3, -0.2], [12.0, -3.1, 3.1]])
    parameters = np.stack([RELATIVE_POSE_SENSORS[name].noise_parameters() for name in ("laser", "vision")])
    expected = noisy_relative_poses(truth, parameters, np.random.default_rng(2))
    noise = np.random.default_rng(2).standard_normal((2, 3))
    np.testing.assert_array_equal(relative_poses_with_noise(truth, parameters, noise), expected)
    assert not np.allclose(expected, truth) and np.all(np.abs(expected[:, 1:]) <= np.pi)


# ----------------------------------------------------------------------------- the filter against filterpy's


@pytest.mark.parametrize("estimator", ["joint", "independent"])
def test_the_filter_equals_filterpys_ekf_update_for_update(estimator, monkeypatch):
    """Along a whole episode (DGPS on schedule, lost by robot_1 at 21 s and under canopies, relative-pose updates)
    the env's EKF equals raw filterpy fed the same readings (x 1e-12, P 1e-10), and each reward its MI."""
    priors, readings, fixes = [], [], []
    start_episode = scenario.start_episode

    def recorded(function, sink):
        return lambda *args: sink.append(function(*args)) or sink[-1]

    monkeypatch.setattr(scenario, "start_episode", recorded(start_episode, priors))
    measurements = record_relative_measurements(monkeypatch)
    env = cooperative_localization_v0.parallel_env(estimator=estimator, team_reward=0.5, max_cycles=80)
    vector = env.vector
    for sensor, sink in ((vector.env_scenario.odometry, readings), (vector.env_scenario.gps, fixes)):
        measure = sensor.measure_with_noise
        monkeypatch.setattr(
            type(sensor), "measure_with_noise", lambda _, *args, m=measure, s=sink: recorded(m, s)(*args)
        )
    _, infos = env.reset(seed=3)
    poses, covariances = priors[-1][1:3]
    ekf = oracle.filterpy_filter(poses.ravel(), oracle.block_diagonal(covariances))
    kept = {"cross_covariances": estimator == "joint"}
    n_robots, dt = len(env.possible_agents), env.config["time_step_s"]
    odometry_covariances = np.repeat(vector.env_scenario.odometry.noise_covariance()[None], n_robots, axis=0)
    gps_covariances = np.repeat(vector.env_scenario.gps.noise_covariance()[None], n_robots, axis=0)

    def fuse_gps(infos):
        robots = np.flatnonzero([infos[agent]["gps_available"] for agent in env.possible_agents])
        if robots.size:
            H = oracle.gps_jacobian(robots, 3 * n_robots)
            R = oracle.block_diagonal(gps_covariances[robots])
            oracle.filterpy_update(ekf, fixes[-1][0][robots].ravel(), H @ ekf.x, H, R, [], n_robots, **kept)
        return robots.size

    counts = np.array([0, fuse_gps(infos)])  # relative observations, DGPS fixes
    rng = np.random.default_rng(3)
    while env.agents:
        actions = {}
        for agent in env.agents:
            valid = np.flatnonzero(infos[agent]["action_mask"])
            actions[agent] = int(rng.choice(valid)) if rng.random() < 0.8 else int(rng.integers(n_robots + 1))
        prior_P = ekf.P.copy()
        _, rewards, _, _, infos = env.step(actions)
        chosen = np.array([infos[agent]["chosen_action"] for agent in env.possible_agents])
        observers = np.flatnonzero(chosen)
        if observers.size:
            targets = chosen[observers] - 1
            predicted, H = oracle.stacked(
                [oracle.relative_pose(ekf.x, observer, target) for observer, target in zip(observers, targets)]
            )
            pairs = vector.env_scenario.pair_index[observers, chosen[observers]]
            R = oracle.block_diagonal(noise_covariances(vector.env_scenario.pairs.noise[pairs], predicted[0::3]))
            measured = measurements[-1][0][observers].ravel()
            oracle.filterpy_update(
                ekf, measured, predicted, H, R, oracle.angle_rows(observers.size, 3), n_robots, **kept
            )
        own = 0.5 * (
            np.linalg.slogdet(oracle.pose_blocks(prior_P))[1] - np.linalg.slogdet(oracle.pose_blocks(ekf.P))[1]
        )
        team = mutual_information(prior_P, ekf.P) if observers.size else 0.0
        for robot, agent in enumerate(env.possible_agents):
            assert rewards[agent] == pytest.approx(0.5 * own[robot] + 0.5 * team, abs=1e-10)
        oracle.filterpy_predict(ekf, readings[-1][0], odometry_covariances, dt)
        counts += [observers.size, fuse_gps(infos)]
        x, P = vector.joint_state()
        np.testing.assert_allclose(x[0], ekf.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(P[0], ekf.P, rtol=0, atol=1e-10)
    assert len(readings) == 80 and np.all(counts > 60)
    assert not infos["robot_1"]["gps_available"]  # its DGPS was lost at 21 s
