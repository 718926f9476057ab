"""cooperative_localization_v0: PettingZoo's API tests in the convoy scenario, determinism, bad input, rewards, GPS."""

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import math  # noqa: E402
import pickle  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from conftest import assert_identical, greedy_actions, random_valid_actions  # noqa: E402
from pettingzoo.test import api_test, parallel_api_test  # noqa: E402

from infonav_gym.envs.vector_infos import reward_terms_of
from infonav_gym.information import mutual_information  # noqa: E402
from infonav_gym.multi import cooperative_exploration_v0, cooperative_localization_v0  # noqa: E402
from infonav_gym.multi.team import KNOWN_SENSORS  # noqa: E402

SCENARIO_CASES = [{}, {"scenario": "convoy", "n_robots": 3}]
scenarios = pytest.mark.parametrize("config", SCENARIO_CASES, ids=["team_field", "convoy"])


def test_pettingzoo_api_tests_pass_in_the_convoy_scenario():
    """The default config is covered by ``test_parallel_envs`` (every registered team env); here the other scenario."""
    config = SCENARIO_CASES[1]
    parallel_api_test(cooperative_localization_v0.parallel_env(**config), num_cycles=300)
    api_test(cooperative_localization_v0.env(**config), num_cycles=100)


@scenarios
def test_same_seed_gives_bit_identical_episodes_over_every_step(config):
    """PettingZoo's seed test stops after one step; this one compares a whole episode."""
    envs = [cooperative_localization_v0.parallel_env(max_cycles=150, **config) for _ in range(2)]
    first = [env.reset(seed=7) for env in envs]
    assert_identical(first[0], first[1], "reset")
    rng, steps = np.random.default_rng(3), 0
    infos = first[0][1]
    while envs[0].agents:
        actions = random_valid_actions(envs[0], infos, rng)
        transitions = [env.step(actions) for env in envs]
        assert_identical(transitions[0], transitions[1], f"step {steps}")
        infos, steps = transitions[0][4], steps + 1
    assert steps == 150 and not envs[1].agents


def test_different_seeds_give_different_worlds_and_reset_replays_an_episode():
    env = cooperative_localization_v0.parallel_env()
    a, _ = env.reset(seed=1)
    b, _ = env.reset(seed=2)
    assert not np.array_equal(a["robot_0"], b["robot_0"])
    replay, _ = env.reset(seed=1)
    assert_identical(a, replay)


def test_infos_carry_masks_gains_gps_errors_and_entropies():
    env = cooperative_localization_v0.parallel_env()
    _, infos = env.reset(seed=0)
    for agent, info in infos.items():
        assert info["action_mask"].dtype == np.int8 and info["action_mask"].shape == (5,)
        assert info["action_mask"][0] == 1 and info["action_mask"][1 + int(agent[-1])] == 0
        assert np.all(info["action_information_gain"][info["action_mask"] == 0] == 0.0)
        assert np.all(info["action_information_gain"][1:][info["action_mask"][1:] == 1] > 0.0)
        for key in ("gps_available", "position_error_m", "heading_error_rad", "pose_entropy", "pose_std"):
            assert key in info
    assert infos["robot_0"]["gps_available"] and not infos["robot_2"]["gps_available"]
    assert np.all(infos["robot_3"]["action_mask"][1:] <= 1)


def test_a_lone_observation_brings_exactly_its_expected_gain_on_the_observers_pose():
    env = cooperative_localization_v0.parallel_env(team_reward=0.0)
    _, infos = env.reset(seed=5)
    checked = 0
    for _ in range(60):
        greedy = greedy_actions(env, infos)
        observer = next((agent for agent, action in greedy.items() if action > 0), None)
        actions = dict.fromkeys(env.agents, 0)
        if observer is not None:
            actions[observer] = greedy[observer]
            expected = infos[observer]["action_information_gain"][greedy[observer]]
        _, rewards, _, _, infos = env.step(actions)
        if observer is not None:
            assert math.isclose(rewards[observer], expected, rel_tol=1e-9), (rewards[observer], expected)
            checked += 1
        else:
            assert all(reward == 0.0 for reward in rewards.values())
    assert checked >= 20


def test_team_reward_mixes_the_joint_mutual_information_into_rewards_and_gains():
    gains, outcomes, actions = {}, {}, None
    for weight in (0.0, 0.5, 1.0):
        env = cooperative_localization_v0.parallel_env(team_reward=weight)
        _, infos = env.reset(seed=6)
        actions = actions or greedy_actions(env, infos)
        gains[weight] = np.array([infos[agent]["action_information_gain"] for agent in env.agents])
        _, rewards, _, _, infos = env.step(actions)
        outcomes[weight] = (rewards, infos)
    np.testing.assert_allclose(gains[0.5], 0.5 * (gains[0.0] + gains[1.0]), rtol=1e-12)
    assert not np.allclose(gains[0.0], gains[1.0])
    for weight, (rewards, infos) in outcomes.items():
        for agent, reward in rewards.items():
            terms = reward_terms_of(infos[agent])
            own, team = terms["own_mutual_information"], terms["team_mutual_information"]
            assert math.isclose(reward, (1 - weight) * own + weight * team, rel_tol=1e-12)
            assert own == outcomes[0.0][1][agent]["reward_own_mutual_information"]


def test_team_mutual_information_is_the_joint_states(monkeypatch):
    env = cooperative_localization_v0.parallel_env()
    _, infos = env.reset(seed=8)
    prior = env.vector.joint_state()[1][0]
    for step in ("predict", "gps_fixes"):  # P after the step: right after the updates
        monkeypatch.setattr(env.vector.env_scenario, step, lambda *args: None)
    _, _, _, _, infos = env.step(greedy_actions(env, infos))
    expected = mutual_information(prior, env.vector.joint_state()[1][0])
    assert expected > 0.1
    assert math.isclose(infos["robot_0"]["reward_team_mutual_information"], expected, rel_tol=1e-9)


def test_gps_drops_out_on_schedule_and_the_pose_uncertainty_then_grows():
    env = cooperative_localization_v0.parallel_env(scenario="convoy", n_robots=3, gps_outages=[(1, 5.0, 100.0)])
    _, infos = env.reset(seed=0)
    history = []
    while env.agents and infos["robot_1"]["time_s"] < 12.0:
        history.append((infos["robot_1"]["time_s"], infos["robot_1"]["gps_available"], infos["robot_1"]["pose_std"]))
        _, _, _, _, infos = env.step(dict.fromkeys(env.agents, 0))
    assert all(available == (time_s < 5.0) for time_s, available, _ in history)
    std_at_loss = next(std for time_s, _, std in history if time_s == 5.0)
    assert history[-1][2][0] > 1.5 * std_at_loss[0]


def test_gps_is_denied_under_canopy():
    env = cooperative_localization_v0.parallel_env(gps_outages=[], n_canopies=3)
    _, infos = env.reset(seed=2)
    denied_seen = 0
    while env.agents:
        for robot in (0, 1):
            agent = f"robot_{robot}"
            under = any(
                math.dist(infos[agent]["true_pose"][:2], zone.center) <= zone.radius
                for zone in env.vector.scenario(0).gps_denied_zones
            )
            assert infos[agent]["gps_available"] == (not under)
            denied_seen += under
        _, _, _, _, infos = env.step(dict.fromkeys(env.agents, 0))
    assert denied_seen > 0


@pytest.mark.parametrize("bad_action", [-1, 5, 2.5, "a", True, np.array([0, 1])])
def test_an_action_outside_the_space_raises_and_changes_nothing(bad_action):
    env = cooperative_localization_v0.parallel_env()
    _, infos = env.reset(seed=0)
    before = (*env.vector.joint_state(), env.vector.true_poses)
    actions = {**greedy_actions(env, infos), "robot_2": bad_action}
    with pytest.raises(ValueError, match="not in the action space"):
        env.step(actions)
    assert_identical(before, (*env.vector.joint_state(), env.vector.true_poses))


def test_masked_actions_are_noops_by_default_and_errors_on_request():
    env = cooperative_localization_v0.parallel_env()
    _, infos = env.reset(seed=0)
    own_index = {agent: 1 + robot for robot, agent in enumerate(env.agents)}  # observing oneself is always masked
    twin = pickle.loads(pickle.dumps(env))
    masked = env.step(own_index)
    noop = twin.step(dict.fromkeys(twin.agents, 0))
    for agent in env.possible_agents:
        assert masked[4][agent]["invalid_action"] and masked[4][agent]["chosen_action"] == 0
        assert masked[1][agent] == noop[1][agent] == 0.0
    np.testing.assert_array_equal(masked[0]["robot_0"], noop[0]["robot_0"])
    strict = cooperative_localization_v0.parallel_env(invalid_action="raise")
    strict.reset(seed=0)
    before = strict.vector.joint_state()
    with pytest.raises(ValueError, match="action 1 of robot_0 is not valid now"):
        strict.step({**dict.fromkeys(strict.agents, 0), "robot_0": 1})
    assert_identical(strict.vector.joint_state(), before)


def test_actions_must_name_every_live_agent():
    env = cooperative_localization_v0.parallel_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="one action per live agent"):
        env.step({"robot_0": 0})
    with pytest.raises(ValueError, match="one action per live agent"):
        env.step({**dict.fromkeys(env.agents, 0), "robot_9": 0})


def test_stepping_before_reset_or_after_the_end_raises():
    env = cooperative_localization_v0.parallel_env(max_cycles=2)
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})
    env.reset(seed=0)
    for _ in range(2):
        _, _, _, truncations, _ = env.step(dict.fromkeys(env.agents, 0))
    assert all(truncations.values()) and env.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})


@pytest.mark.parametrize(
    "config, message",
    [
        ({"n_robot": 3}, "unknown config key 'n_robot'.*Did you mean 'n_robots'"),
        ({"robot_sensors": ["gps", "sonar", "laser", "laser"]}, "unknown sensor 'sonar'.*" + ", ".join(KNOWN_SENSORS)),
        ({"estimator": "naive"}, "'estimator'.*must be one of"),
        ({"team_reward": 1.5}, "team_reward"),
        ({"n_robots": 1}, "n_robots"),
        ({"gps_outages": [(7, 0.0, 1.0)]}, "robots 0..3"),
    ],
)
def test_bad_config_raises_a_clear_error(config, message):
    with pytest.raises(ValueError, match=message):
        cooperative_localization_v0.parallel_env(**config)


@pytest.mark.render
def test_rgb_array_frames_show_the_team_and_relative_observations():
    env = cooperative_localization_v0.parallel_env(render_mode="rgb_array", render_size_px=300)
    _, infos = env.reset(seed=0)
    first = env.render()
    _, _, _, _, infos = env.step(greedy_actions(env, infos))
    second = env.render()
    assert first.dtype == np.uint8 and first.ndim == 3 and first.shape[2] == 3 and max(first.shape[:2]) == 300
    assert not np.array_equal(first, second)
    env.close()
    env.close()


@pytest.mark.parametrize(
    ("module", "config"),
    [(cooperative_localization_v0, {"team_reward": 1.0}), (cooperative_exploration_v0, {})],
    ids=["localization", "exploration"],
)
def test_observe_gains_appends_each_actions_expected_reward_to_the_observation(module, config):
    plain = module.parallel_env(**config)
    with_gains = module.parallel_env(**config, observe_gains=True)
    n_actions = plain.action_space("robot_0").n
    assert with_gains.observation_space("robot_0").shape == (plain.observation_space("robot_0").shape[0] + n_actions,)
    observations, infos = with_gains.reset(seed=3)
    plain_observations, _ = plain.reset(seed=3)
    for _ in range(30):
        for agent, observation in observations.items():
            gains = infos[agent]["action_information_gain"]
            np.testing.assert_array_equal(observation[:-n_actions], plain_observations[agent])
            np.testing.assert_allclose(observation[-n_actions:], gains, rtol=1e-6)
            assert with_gains.observation_space(agent).contains(observation)
        actions = {agent: int(np.argmax(infos[agent]["action_information_gain"])) for agent in observations}
        observations, _, _, _, infos = with_gains.step(actions)
        plain_observations, *_ = plain.step(actions)
        if not observations:
            break
    assert any(np.any(info["action_information_gain"] > 0) for info in infos.values())
