"""cooperative_exploration_v0: determinism, bad input, gains against rewards, episode ends (PettingZoo's own tests:
``test_parallel_envs``)."""

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import math  # noqa: E402
import pickle  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from conftest import assert_identical, greedy_actions, map_footprints, random_valid_actions  # noqa: E402
from gymnasium import spaces  # noqa: E402

from infonav_gym.envs.cooperative_exploration import N_MOTIONS, NOOP_ACTION  # noqa: E402
from infonav_gym.envs.cooperative_exploration.exploration_team import (
    exploration_observation_bounds,
    exploration_observations,
)  # noqa: E402
from infonav_gym.envs.cooperative_exploration.terrain_map import TerrainMapModel  # noqa: E402
from infonav_gym.envs.vector_infos import reward_terms_of
from infonav_gym.experiments.evaluation import evaluate  # noqa: E402
from infonav_gym.multi import cooperative_exploration_v0  # noqa: E402
from infonav_gym.world.exploration_scenarios import BASE_CLEARANCE_M, exploration_field  # noqa: E402

ID = "cooperative_exploration_v0"


def test_same_seed_gives_bit_identical_episodes_and_other_seeds_other_worlds():
    envs = [cooperative_exploration_v0.parallel_env(max_cycles=80) for _ in range(2)]
    first = [env.reset(seed=7) for env in envs]
    assert_identical(first[0], first[1], "reset")
    rng, steps, infos = np.random.default_rng(3), 0, first[0][1]
    while envs[0].agents:
        actions = greedy_actions(envs[0], infos) if steps % 2 else random_valid_actions(envs[0], infos, rng)
        transitions = [env.step(actions) for env in envs]
        assert_identical(transitions[0], transitions[1], f"step {steps}")
        infos, steps = transitions[0][4], steps + 1
    assert steps > 10 and not envs[1].agents
    other, _ = envs[0].reset(seed=8)
    replay, _ = envs[1].reset(seed=7)
    assert not np.array_equal(other["robot_0"], first[0][0]["robot_0"])
    assert_identical(replay, first[0][0])


def test_masks_and_gains_follow_the_action_layout():
    env = cooperative_exploration_v0.parallel_env()
    _, infos = env.reset(seed=0)
    n_landmarks, n = env.config["n_landmarks"], len(env.possible_agents)
    for robot, info in enumerate(infos.values()):
        mask = info["action_mask"].reshape(1 + n_landmarks + n, N_MOTIONS)
        gains = info["action_information_gain"].reshape(mask.shape)
        assert info["action_mask"].dtype == np.int8 and mask[0].all() and gains[0, 0] == 0.0
        assert np.all(mask == mask[:, :1] * mask[:1]), "every valid observation goes with every valid motion"
        assert not mask[1 + n_landmarks + robot].any(), "a robot never observes itself"
        assert np.all(gains[mask == 0] == 0.0) and np.all(gains[1:][mask[1:] == 1] > 0.0)
        assert info["coverage"] == 0.0 and not info["lost"] and info["observations_left"] == 100
    assert infos["robot_0"]["gps_available"] and not infos["robot_2"]["gps_available"]


@pytest.mark.parametrize("team_reward", [0.0, 0.7])
def test_a_lone_standing_observation_brings_exactly_its_expected_gain(team_reward):
    env = cooperative_exploration_v0.parallel_env(team_reward=team_reward)
    _, infos = env.reset(seed=5)
    checked = 0
    for step in range(40):
        observer = env.agents[step % len(env.agents)]
        standing = infos[observer]["action_information_gain"][::N_MOTIONS]  # each observation with motion "stay"
        valid = infos[observer]["action_mask"][::N_MOTIONS]
        actions = greedy_actions(env, infos) if step % 3 else dict.fromkeys(env.agents, NOOP_ACTION)
        actions[observer] = NOOP_ACTION
        if step % 3 == 0 and valid[1:].any():
            actions[observer] = N_MOTIONS * int(np.argmax(np.where(valid, standing, -1)))
        expected = infos[observer]["action_information_gain"][actions[observer]]
        _, rewards, _, _, infos = env.step(actions)
        if step % 3 == 0 and actions[observer] != NOOP_ACTION:
            terms = reward_terms_of(infos[observer])
            own = (1.0 - team_reward) * terms["own_pose_information"]
            assert math.isclose(own, expected, rel_tol=1e-9), (own, expected)
            costs = terms["sensing_cost"] + terms["motion_cost"] + terms["lost_penalty"]
            assert math.isclose(rewards[observer], own + team_reward * terms["team_map_information"] + costs)
            checked += 1
        if not env.agents:
            break
    assert checked >= 5


def test_driving_scans_the_map_and_a_full_map_is_a_success():
    env = cooperative_exploration_v0.parallel_env(coverage_target=0.02)
    _, infos = env.reset(seed=1)
    _, rewards, terminations, truncations, infos = env.step(greedy_actions(env, infos))
    info = infos["robot_0"]
    assert info["reward_team_map_information"] > 0.0 and info["coverage"] >= 0.02
    assert info["success"] and not info["failed"] and all(terminations.values()) and not any(truncations.values())
    assert env.agents == []


def test_a_robot_beyond_the_position_bound_is_lost_and_the_team_fails():
    env = cooperative_exploration_v0.parallel_env(max_position_std_m=0.2, lost_penalty=3.0)
    _, infos = env.reset(seed=2)
    while env.agents:
        _, rewards, terminations, truncations, infos = env.step(greedy_actions(env, infos))
    lost = [agent for agent, info in infos.items() if info["lost"]]
    assert lost and all(not infos[agent]["gps_available"] for agent in lost)
    assert all(info["failed"] and not info["success"] for info in infos.values())
    assert all(info["reward_lost_penalty"] == -3.0 for info in infos.values())
    assert all(terminations.values()) and not any(truncations.values())
    assert all(info["position_std_m"] > 0.2 for agent, info in infos.items() if agent in lost)


@pytest.mark.parametrize("bad_action", [-1, 45, 2.5, "a", True])
def test_an_action_outside_the_space_raises_and_changes_nothing(bad_action):
    env = cooperative_exploration_v0.parallel_env()
    _, infos = env.reset(seed=0)
    vector = env.vector
    before = (*vector.joint_state(), vector.true_poses, vector.map_variances)
    with pytest.raises(ValueError, match="not in the action space"):
        env.step({**greedy_actions(env, infos), "robot_2": bad_action})
    assert_identical(before, (*vector.joint_state(), vector.true_poses, vector.map_variances))


def test_masked_actions_are_noops_by_default_and_errors_on_request():
    env = cooperative_exploration_v0.parallel_env()
    env.reset(seed=0)
    n_landmarks = env.config["n_landmarks"]
    own_slot = {agent: N_MOTIONS * (1 + n_landmarks + robot) + 1 for robot, agent in enumerate(env.agents)}
    twin = pickle.loads(pickle.dumps(env))
    masked = env.step(own_slot)
    noop = twin.step(dict.fromkeys(twin.agents, NOOP_ACTION))
    for agent in env.possible_agents:
        assert masked[4][agent]["invalid_action"] and masked[4][agent]["chosen_action"] == NOOP_ACTION
        assert masked[1][agent] == noop[1][agent]
        np.testing.assert_array_equal(masked[0][agent], noop[0][agent])
    strict = cooperative_exploration_v0.parallel_env(invalid_action="raise")
    strict.reset(seed=0)
    before = (*strict.vector.joint_state(), strict.vector.true_poses)
    action = own_slot["robot_0"]
    with pytest.raises(ValueError, match=f"action {action} of robot_0 is not valid now"):
        strict.step({**dict.fromkeys(strict.agents, NOOP_ACTION), "robot_0": action})
    assert_identical(before, (*strict.vector.joint_state(), strict.vector.true_poses))


@pytest.mark.parametrize(
    "config, message",
    [
        ({"n_robot": 3}, "unknown config key 'n_robot'.*Did you mean 'n_robots'"),
        ({"team_reward": 1.5}, "'team_reward'"),
        ({"n_robots": 1}, "'n_robots'"),
        ({"laser_range_m": -1.0}, "'laser_range_m'"),
        ({"vision_range_m": 2000.0}, "'vision_range_m'"),
        ({"field_size_m": 10.0}, "'field_size_m'"),
        ({"n_landmarks": -1}, "'n_landmarks'"),
        ({"map_cells_per_side": 1}, "'map_cells_per_side'"),
        ({"coverage_target": 0.0}, "'coverage_target'"),
        ({"max_position_std_m": 0.05}, "'max_position_std_m'.*initial_position_std_m"),
        ({"covered_std_m": 2.0}, "'map_prior_std_m'.*covered_std_m"),
        ({"robot_speeds_mps": [1.0, 1.0]}, "robot_speeds_mps.*one speed"),
        ({"robot_speeds_mps": [1.0, 1.0, 0.0, 1.0]}, "robot_speeds_mps.*in \\(0, 50\\]"),
        ({"robot_sensors": ["gps", "sonar", "laser", "laser"]}, "unknown sensor 'sonar'"),
        ({"gps_outages": [(7, 0.0, 1.0)]}, "robots 0..3"),
        ({"gps_std_m": 0.0}, "'gps_std_m'"),
        ({"turn_time_s": 1.0}, "'time_step_s'.*turn_time_s"),
    ],
)
def test_bad_config_raises_a_clear_error(config, message):
    with pytest.raises(ValueError, match=message):
        cooperative_exploration_v0.parallel_env(**config)


def test_greedy_and_random_run_in_the_evaluation_harness_and_differ():
    results = evaluate(ID, ["random", "greedy"], episodes=2, seed=0, env_kwargs={"max_cycles": 60})
    summaries = {name: result["summary"] for name, result in results["agents"].items()}
    assert set(summaries["greedy"]) >= {"success_rate", "final_coverage", "map_information", "pose_information"}
    assert summaries["greedy"]["success_rate"]["interval"] == "wilson"
    random_episodes, greedy_episodes = (results["agents"][name]["episodes"] for name in ("random", "greedy"))
    assert all(0.0 <= episode["final_coverage"] <= 1.0 for episode in random_episodes + greedy_episodes)
    assert [e["map_information"] for e in random_episodes] != [e["map_information"] for e in greedy_episodes]


def test_the_terrain_map_fuses_scans_in_information_form_and_gains_are_their_entropy_reduction():
    model = TerrainMapModel.square(
        10.0, 5, prior_std_m=1.0, scan_radius_m=2.5, scan_std_m=0.1, terrain_slope=0.5, covered_std_m=0.3
    )
    np.testing.assert_allclose(model.centers[:6], [[1, 1], [3, 1], [5, 1], [7, 1], [9, 1], [1, 3]])
    variances = model.prior_variances() * np.linspace(0.2, 1.0, model.n_cells)
    footprints = map_footprints(model, np.array([[4.0, 4.0], [5.0, 6.0]]))
    assert footprints.sum(axis=1).tolist() == [4, 6]  # centres within 2.5 m: (3|5, 3|5); (3|5|7, 5|7)
    noise = model.scan_noise_variances(np.array([0.0, 2.0]))
    np.testing.assert_allclose(noise, [0.01, 0.01 + 1.0])
    positions = np.array([[[4.0, 4.0], [5.0, 6.0], [5.0, 5.0]]])
    fused, information = model.fused(variances[None], positions, noise[None, [0, 1, 1]], np.array([[1, 1, 0]], bool))
    expected = 1.0 / (1.0 / variances + footprints[0] / noise[0] + footprints[1] / noise[1])
    np.testing.assert_allclose(fused[0], expected, rtol=1e-14)
    assert math.isclose(information[0], 0.5 * np.sum(np.log(variances / expected)), rel_tol=1e-12)
    alone, entropy_reduction = model.fused(variances[None], positions[:, :1], noise[None, :1], np.ones((1, 1), bool))
    entropy_reduction = entropy_reduction[0]
    assert math.isclose(entropy_reduction, 0.5 * np.sum(np.log(variances / alone[0])), rel_tol=1e-12)
    gain = model.scan_gains(variances[None], np.array([[[4.0, 4.0]]]), noise[None, :1])
    assert math.isclose(gain[0, 0], entropy_reduction, rel_tol=1e-12)
    positions = np.random.default_rng(0).uniform(-1.0, 11.0, (3, 4, 2))  # also off the field, on cell boundaries
    positions[0, 0] = [5.0, 3.5]
    many = map_footprints(model, positions)
    expected = 0.5 * np.sum(many * np.log1p(variances / noise[1]), axis=-1)
    np.testing.assert_allclose(
        model.scan_gains(np.tile(variances, (3, 1)), positions, np.full((3, 4), noise[1])), expected, rtol=1e-14
    )
    scanning = np.array([[1, 1, 0, 1], [0, 0, 0, 0], [1, 0, 1, 1]], bool)
    noises = np.linspace(0.01, 1.0, 12).reshape(3, 4)
    fused, information = model.fused(np.tile(variances, (3, 1)), positions, noises, scanning)
    expected = 1.0 / (1.0 / variances + np.sum((many & scanning[..., None]) / noises[..., None], axis=1))
    np.testing.assert_array_equal(fused, expected)  # the same operations: bit for bit
    np.testing.assert_allclose(information, 0.5 * np.sum(np.log(variances / expected), axis=-1), rtol=1e-13, atol=1e-15)
    assert model.coverage(fused[0]) == np.mean(fused[0] <= 0.09) and model.coverage(model.prior_variances()) == 0.0


def test_the_exploration_field_is_drawn_from_its_generator_with_a_clear_base():
    scenario = exploration_field(np.random.default_rng(3))
    again = exploration_field(np.random.default_rng(3))
    np.testing.assert_array_equal(scenario.landmarks, again.landmarks)
    assert scenario.obstacles == again.obstacles and scenario.gps_denied_zones == again.gps_denied_zones
    starts = np.array([route.start_pose for route in scenario.routes])
    base = starts[:, :2].mean(axis=0)
    assert len(starts) == 4 and np.allclose(np.diff(starts[:, 2]), 0.0)
    assert np.all(np.linalg.norm(scenario.landmarks - base, axis=1) > BASE_CLEARANCE_M)
    for zone in scenario.gps_denied_zones + scenario.obstacles:
        assert math.dist(zone.center, base) > BASE_CLEARANCE_M + zone.radius
    with pytest.raises(ValueError, match="n_landmarks"):
        exploration_field(np.random.default_rng(0), n_landmarks=-2)


@pytest.mark.render
def test_rgb_array_frames_show_the_team_and_the_map():
    env = cooperative_exploration_v0.parallel_env(render_mode="rgb_array", render_size_px=300)
    _, infos = env.reset(seed=0)
    first = env.render()
    for _ in range(3):
        _, _, _, _, infos = env.step(greedy_actions(env, infos))
    second = env.render()
    assert first.dtype == np.uint8 and first.ndim == 3 and max(first.shape[:2]) == 300
    assert not np.array_equal(first, second)
    env.close()


def test_observations_are_the_team_landmark_extra_and_map_features_clipped_to_the_space():
    rng = np.random.default_rng(5)
    n_copies, n_robots, n_landmarks, n_cells = 3, 3, 2, 5
    n_team = 10 + 5 * n_robots
    team = rng.normal(0, 3, (n_copies, n_robots, n_team)).astype(np.float32)
    valid = rng.random((n_copies, n_robots, n_landmarks)) < 0.5
    seen = np.stack([rng.uniform(0, 2e4, valid.shape), rng.uniform(-4, 4, valid.shape)], axis=-1)
    seen[0, 0, 0, 1] = np.nan
    speeds, budget, coverage = rng.uniform(0, 2, n_robots), rng.random((n_copies, n_robots)), rng.random(n_copies)
    cells = rng.uniform(-0.2, 1.3, (n_copies, n_cells))
    low, high = exploration_observation_bounds(np.full(n_team, -2.0), np.full(n_team, 2.0), n_landmarks, n_cells)
    observed = exploration_observations(
        team, valid, seen, speeds, budget, coverage, cells, spaces.Box(low, high, dtype=np.float32)
    )
    landmarks = np.stack([valid, seen[..., 0], np.cos(seen[..., 1]), np.sin(seen[..., 1])], axis=-1)
    extras = np.stack([np.broadcast_to(speeds, budget.shape), budget, np.repeat(coverage[:, None], n_robots, 1)], -1)
    map_cells = np.repeat(cells[:, None], n_robots, axis=1)
    parts = [team, landmarks.reshape(n_copies, n_robots, -1), extras, map_cells]
    expected = np.clip(np.concatenate(parts, axis=-1).astype(np.float32), low, high)
    assert observed.dtype == np.float32
    np.testing.assert_array_equal(observed, expected)
    assert np.isnan(observed[0, 0, n_team + 2]) and (observed[~np.isnan(observed)] <= 1e4).all()
