"""CooperativeLocalizationVectorEnv: copy i equals the parallel env seeded seed + i; autoreset, seeding, bad input."""

import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

import infonav_gym
from infonav_gym.multi import cooperative_localization_v0
from infonav_gym.multi.cooperative_localization_vector import CooperativeLocalizationVectorEnv
from infonav_gym.registry import PARALLEL, env_entry, make_vector_env, register, unregister
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.relative_pose import RELATIVE_POSE_SENSORS, noisy_relative_poses, relative_poses_with_noise

TOLERANCE = 1e-9
TEAM_ID = "cooperative_localization_v0"


def assert_copy_equals(observations, info, copy: int, reference: tuple, stepped: bool = True) -> None:
    """Copy ``copy`` of the vector env's observations and info equal the parallel env's ``(observations, infos)``."""
    reference_observations, reference_infos = reference
    for robot, agent in enumerate(reference_infos):
        np.testing.assert_allclose(observations[copy][robot], reference_observations[agent], rtol=0, atol=1e-6)
        for key, expected in reference_infos[agent].items():
            assert info[f"_{key}"][copy], key
            if key == "reward_terms":
                for term, value in expected.items():
                    assert info[key][f"_{term}"][copy] == stepped, term
                    assert info[key][term][copy, robot] == pytest.approx(value, abs=TOLERANCE), term
                continue
            got = info[key][copy] if key == "time_s" else info[key][copy, robot]
            np.testing.assert_allclose(got, expected, rtol=0, atol=TOLERANCE, err_msg=f"{key} of {agent}, copy {copy}")


def random_valid(masks: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return np.array([[rng.choice(np.flatnonzero(robot)) for robot in copy] for copy in masks])


def greedy(masks: np.ndarray, info: dict) -> np.ndarray:
    return np.argmax(np.where(masks, info["action_information_gain"], -1.0), axis=-1)


def run_against_parallel_envs(config: dict, n_copies: int, seed: int, policy: str, steps: int) -> int:
    """Step the vector env and one parallel env per copy alike (NEXT_STEP) for ``steps``; the episodes ended."""
    vector = CooperativeLocalizationVectorEnv(n_copies, **config)
    references = [cooperative_localization_v0.parallel_env(**config) for _ in range(n_copies)]
    observations, info = vector.reset(seed=seed)
    for copy, env in enumerate(references):
        assert_copy_equals(observations, info, copy, env.reset(seed=seed + copy), stepped=False)
    rng, ended = np.random.default_rng(seed), 0
    for _ in range(steps):
        masks = vector.action_masks()
        np.testing.assert_array_equal(masks, info["action_mask"].astype(bool))
        actions = random_valid(masks, rng) if policy == "random" else greedy(masks, info)
        observations, rewards, terminations, truncations, info = vector.step(actions)
        assert not terminations.any()
        for copy, env in enumerate(references):
            if not env.agents:  # the copy resets in this step (NEXT_STEP): its actions are ignored
                ended += 1
                assert_copy_equals(observations, info, copy, env.reset(), stepped=False)
                assert not rewards[copy].any() and not truncations[copy].any()
                continue
            step = env.step({agent: int(actions[copy, robot]) for robot, agent in enumerate(env.possible_agents)})
            reference_observations, reference_rewards, _, reference_truncations, reference_infos = step
            assert_copy_equals(observations, info, copy, (reference_observations, reference_infos))
            for robot, agent in enumerate(env.possible_agents):
                assert rewards[copy, robot] == pytest.approx(reference_rewards[agent], abs=TOLERANCE)
                assert truncations[copy, robot] == reference_truncations[agent]
    return ended


@pytest.mark.parametrize("estimator", ["joint", "independent"])
@pytest.mark.parametrize("seed, n_copies", [(0, 3), (11, 2)])
def test_copies_equal_the_parallel_env_seeded_seed_plus_i_through_autoresets(estimator, seed, n_copies):
    """max_cycles 50 reaches robot_1's DGPS outage at 21 s (step 42); 2 episodes and the resets between them."""
    config = {"max_cycles": 50, "estimator": estimator}
    assert run_against_parallel_envs(config, n_copies, seed, "random", 2 * 50 + 2) == 2 * n_copies


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
    assert run_against_parallel_envs(config, 2, 5, "greedy", 31) == 2


def test_a_team_without_relative_sensors_has_only_the_no_op():
    config = {"max_cycles": 5, "n_robots": 2, "robot_sensors": ["gps", "gps"]}
    assert run_against_parallel_envs(config, 2, 1, "random", 6) == 2
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


# ----------------------------------------------------------------------------- autoreset


def test_same_step_autoreset_returns_the_reset_and_the_final_observation_and_info():
    config, n_copies, seed = {"max_cycles": 4}, 2, 2
    next_step = CooperativeLocalizationVectorEnv(n_copies, **config)
    same_step = CooperativeLocalizationVectorEnv(n_copies, autoreset_mode="same_step", **config)
    assert next_step.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert same_step.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert CooperativeLocalizationVectorEnv.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP  # not mutated
    next_step.reset(seed=seed)
    same_step.reset(seed=seed)
    references = [cooperative_localization_v0.parallel_env(**config) for _ in range(n_copies)]
    for copy, env in enumerate(references):
        env.reset(seed=seed + copy)
    rng = np.random.default_rng(0)
    for step in range(2 * config["max_cycles"]):
        actions = random_valid(same_step.action_masks(), rng)
        observations, rewards, _, truncations, info = same_step.step(actions)
        np.testing.assert_array_equal(next_step.step(actions)[1], rewards)  # same rewards while no copy resets
        ended = (step + 1) % config["max_cycles"] == 0
        assert truncations.all() == ended and truncations.any() == ended
        for copy, env in enumerate(references):
            actions_of = {agent: int(actions[copy, robot]) for robot, agent in enumerate(env.possible_agents)}
            reference_observations, _, _, _, reference_infos = env.step(actions_of)
            if not ended:
                assert "final_obs" not in info
                assert_copy_equals(observations, info, copy, (reference_observations, reference_infos))
                continue
            assert info["_final_obs"][copy] and info["_final_info"][copy] and info["final_obs"].dtype == object
            assert_copy_equals(info["final_obs"], info["final_info"], copy, (reference_observations, reference_infos))
            assert_copy_equals(observations, info, copy, env.reset(), stepped=False)
        if ended:
            next_step.step(actions)  # NEXT_STEP spends a step on the reset


# ----------------------------------------------------------------------------- seeding


def test_a_seed_list_seeds_each_copy_and_no_seed_continues_each_copys_generator():
    vector = CooperativeLocalizationVectorEnv(3, max_cycles=5)
    references = [cooperative_localization_v0.parallel_env(max_cycles=5) for _ in range(3)]
    observations, info = vector.reset(seed=[4, None, 9])
    for copy, copy_seed in [(0, 4), (2, 9)]:
        assert_copy_equals(observations, info, copy, references[copy].reset(seed=copy_seed), stepped=False)
    assert [generator is not None for generator in vector.np_randoms] == [True] * 3
    observations, info = vector.reset()  # unseeded: each copy continues its generator, as the parallel env's reset()
    for copy in (0, 2):
        assert_copy_equals(observations, info, copy, references[copy].reset(), stepped=False)
    first, second = CooperativeLocalizationVectorEnv(3, max_cycles=5), CooperativeLocalizationVectorEnv(3, max_cycles=5)
    np.testing.assert_array_equal(first.reset(seed=7)[0], second.reset(seed=7)[0])


@pytest.mark.parametrize("seed", [-1, 1.5, True, "0", [0, 1], [0, 1, -2]])
def test_a_bad_seed_is_a_value_error_saying_what_a_seed_is(seed):
    with pytest.raises(ValueError, match=r"seed of CooperativeLocalizationVectorEnv.reset must be None, an int >= 0"):
        CooperativeLocalizationVectorEnv(3).reset(seed=seed)


# ----------------------------------------------------------------------------- bad input


@pytest.fixture
def vector() -> CooperativeLocalizationVectorEnv:
    env = CooperativeLocalizationVectorEnv(3, max_cycles=10, invalid_action="raise")
    env.reset(seed=0)
    return env


@pytest.mark.parametrize(
    "actions, message",
    [
        (np.zeros(3, dtype=int), r"integer array of shape \(3, 4\), one per copy and robot.*got int64 of shape \(3,\)"),
        (np.zeros((3, 4)), r"got float64 of shape \(3, 4\)"),
        (
            np.array([[0, 0, 0, 0], [0, 0, 5, 0], [0, 0, 0, 0]]),
            r"action 5 of robot_2 in sub-env 1 is not in the action",
        ),
        (np.array([[0, 0, 0, 0], [0, 0, 0, 0], [0, -1, 0, 0]]), r"action -1 of robot_1 in sub-env 2 .*in \[0, 4\]"),
    ],
    ids=["shape", "dtype", "too-big", "negative"],
)
def test_bad_actions_are_value_errors_naming_the_copy_and_robot(vector, actions, message):
    with pytest.raises(ValueError, match=message):
        vector.step(actions)


def test_a_masked_action_raises_naming_copy_and_robot_or_is_a_no_op_and_leaves_the_env_unchanged(vector):
    copy, robot, action = (int(index) for index in np.argwhere(~vector.action_masks())[0])
    masked = np.zeros((3, 4), dtype=int)
    masked[copy, robot] = action
    with pytest.raises(ValueError, match=rf"action {action} of robot_{robot} in sub-env {copy} is not valid now"):
        vector.step(masked)
    no_ops = np.zeros((3, 4), dtype=int)
    reference, noop = (
        CooperativeLocalizationVectorEnv(3, max_cycles=10, invalid_action=mode) for mode in ("raise", "noop")
    )
    reference.reset(seed=0)
    noop.reset(seed=0)
    expected_observations, expected_rewards, *_ = reference.step(no_ops)
    np.testing.assert_array_equal(vector.step(no_ops)[0], expected_observations)  # the refused step changed nothing
    observations, rewards, _, _, info = noop.step(masked)
    assert info["invalid_action"][copy, robot] and info["invalid_action"].sum() == 1
    assert info["chosen_action"][copy, robot] == 0
    np.testing.assert_array_equal(observations, expected_observations)
    np.testing.assert_array_equal(rewards, expected_rewards)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"num_envs": 0}, r"num_envs of CooperativeLocalizationVectorEnv must be an int >= 1, got 0"),
        ({"num_envs": 2.0}, r"must be an int >= 1, got 2.0"),
        ({"render_mode": "ascii"}, r"render_mode"),
        ({"autoreset_mode": "partial"}, r"autoreset_mode .* must be one of 'next_step', 'same_step' .*'partial'"),
        ({"n_robots": 9}, r"n_robots"),
        ({"estimator": "kalman"}, r"estimator"),
    ],
)
def test_a_bad_argument_is_a_value_error_naming_it(kwargs, message):
    with pytest.raises(ValueError, match=message):
        CooperativeLocalizationVectorEnv(**kwargs)


def test_step_before_reset_and_options_are_refused():
    env = CooperativeLocalizationVectorEnv(2)
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(np.zeros((2, 4), dtype=int))
    with pytest.raises(RuntimeError, match="call reset"):
        env.action_masks()
    with pytest.raises(ValueError, match=r"reset takes no options, got \['x'\]"):
        env.reset(options={"x": 1})


# ----------------------------------------------------------------------------- rendering


def test_render_draws_copy_0_as_its_parallel_env_through_an_autoreset():
    config = {"max_cycles": 3, "render_size_px": 96}
    vector = CooperativeLocalizationVectorEnv(2, render_mode="rgb_array", **config)
    team = cooperative_localization_v0.parallel_env(render_mode="rgb_array", **config)
    vector.reset(seed=4)
    team.reset(seed=4)
    rng = np.random.default_rng(0)
    for step in range(8):
        frame = vector.render()
        assert frame.shape[2] == 3 and max(frame.shape[:2]) == 96
        np.testing.assert_array_equal(frame, team.render(), err_msg=f"step {step}")
        actions = random_valid(vector.action_masks(), rng)
        vector.step(actions)
        if team.agents:
            team.step(dict(zip(team.possible_agents, actions[0].tolist())))
        else:  # the NEXT_STEP autoreset of copy 0
            team.reset()
    vector.close()


def test_render_without_a_render_mode_warns_and_returns_none():
    vector = CooperativeLocalizationVectorEnv(2)
    vector.reset(seed=0)
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert vector.render() is None


# ----------------------------------------------------------------------------- the vector API and the registry


def test_spaces_agents_and_registration():
    env = make_vector_env(TEAM_ID, num_envs=5, max_cycles=7)
    team = cooperative_localization_v0.parallel_env()
    assert type(env) is CooperativeLocalizationVectorEnv and env.num_envs == 5 and env.max_cycles == 7
    assert env.agents == team.possible_agents
    assert env.single_observation_space == team.observation_space("robot_0")
    assert env.single_action_space == team.action_space("robot_0") == spaces.Discrete(5)
    assert env.observation_space.shape == (5, 4, 30) and env.action_space == spaces.MultiDiscrete(np.full((5, 4), 5))
    observations, info = env.reset(seed=0)
    assert observations in env.observation_space and observations.dtype == np.float32
    assert env.action_masks().shape == (5, 4, 5) and env.action_masks().dtype == bool
    assert env.action_space.sample() in env.action_space
    env.close()
    assert env_entry(TEAM_ID).load_vector() is CooperativeLocalizationVectorEnv
    assert infonav_gym.make_vector_env is make_vector_env


def test_make_vector_env_makes_a_gymnasium_envs_native_vector_env_too():
    env = make_vector_env("infonav/LandmarkSelection-v0", 2, horizon=5)
    assert type(env).__name__ == "LandmarkSelectionVectorEnv" and env.num_envs == 2 and env.config["horizon"] == 5


def test_make_vector_env_refuses_an_env_without_a_native_vector_env():
    with pytest.raises(ValueError, match=r"env 'infonav/SensorSelection-v0' has no native vector env"):
        make_vector_env("infonav/SensorSelection-v0", 2)
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
