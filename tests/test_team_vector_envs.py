"""Every team env's native vector env: autoreset, seeding, bad input, rendering and its spaces (from the registry).

Each test runs on every registered PettingZoo team env with a vector entry point; what it expects comes from the
vector env and its parallel env, never from the id. That copy i equals the parallel env seeded seed + i along
whole episodes is each env's own test file (``test_cooperative_*_vector.py``).
"""

import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from team_vector_checks import assert_copy_equals, random_valid, team_envs

from infonav_gym.experiments.vector_timing import vector_env_ids
from infonav_gym.registry import PARALLEL, api_of, make_vector_env

TEAM_VECTOR_IDS = [env_id for env_id in vector_env_ids() if api_of(env_id) == PARALLEL]


def test_every_team_env_with_a_vector_env_is_checked():
    assert {"cooperative_localization_v0", "cooperative_exploration_v0"} <= set(TEAM_VECTOR_IDS)


# ----------------------------------------------------------------------------- autoreset


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
def test_same_step_autoreset_returns_the_reset_and_the_final_observation_and_info(env_id):
    parallel_class, vector_class = team_envs(env_id)
    config, n_copies, seed = {"max_cycles": 4}, 2, 2
    next_step = vector_class(n_copies, autoreset_mode="next_step", **config)
    same_step = vector_class(n_copies, **config)  # the default: SB3's and TorchRL's convention
    assert next_step.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert same_step.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert vector_class.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP  # not mutated
    next_step.reset(seed=seed)
    same_step.reset(seed=seed)
    references = [parallel_class(**config) for _ in range(n_copies)]
    for copy, env in enumerate(references):
        env.reset(seed=seed + copy)
    rng, team_keys = np.random.default_rng(0), same_step.team_info_keys
    for step in range(2 * config["max_cycles"]):
        actions = random_valid(same_step.action_masks(), rng)
        observations, rewards, _, truncations, info = same_step.step(actions)
        np.testing.assert_array_equal(next_step.step(actions)[1], rewards)  # same rewards while no copy resets
        ended = (step + 1) % config["max_cycles"] == 0
        assert truncations.all() == ended and truncations.any() == ended
        for copy, env in enumerate(references):
            actions_of = {agent: int(actions[copy, robot]) for robot, agent in enumerate(env.possible_agents)}
            reference_observations, _, _, _, reference_infos = env.step(actions_of)
            reference = (reference_observations, reference_infos)
            if not ended:
                assert "final_obs" not in info
                assert_copy_equals(observations, info, copy, reference, team_keys)
                continue
            assert info["_final_obs"][copy] and info["_final_info"][copy] and info["final_obs"].dtype == object
            assert_copy_equals(info["final_obs"], info["final_info"], copy, reference, team_keys)
            assert_copy_equals(observations, info, copy, env.reset(), team_keys)
        if ended:
            next_step.step(actions)  # NEXT_STEP spends a step on the reset


# ----------------------------------------------------------------------------- seeding


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
def test_without_autoreset_a_copy_goes_on_from_its_last_state_until_reset(env_id):
    """``DISABLED``: what the PettingZoo view steps; no copy starts again by itself."""
    _, vector_class = team_envs(env_id)
    vector = vector_class(2, max_cycles=3, autoreset_mode="disabled")
    assert vector.metadata["autoreset_mode"] == AutoresetMode.DISABLED
    _, info = vector.reset(seed=1)
    noops = np.full((2, len(vector.agents)), vector.traits.noop_action)
    for step in range(1, 6):
        _, _, terminated, truncated, info = vector.step(noops)
        assert not terminated.any() and truncated.all() == (step >= 3) and "final_obs" not in info
        np.testing.assert_allclose(info["time_s"], step * vector.config["time_step_s"])
    _, info = vector.reset(seed=1)
    assert not info["time_s"].any()


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
def test_a_seed_list_seeds_each_copy_and_no_seed_continues_each_copys_generator(env_id):
    parallel_class, vector_class = team_envs(env_id)
    vector = vector_class(3, max_cycles=5)
    references = [parallel_class(max_cycles=5) for _ in range(3)]
    observations, info = vector.reset(seed=[4, None, 9])
    for copy, copy_seed in [(0, 4), (2, 9)]:
        reference = references[copy].reset(seed=copy_seed)
        assert_copy_equals(observations, info, copy, reference, vector.team_info_keys)
    assert [generator is not None for generator in vector.np_randoms] == [True] * 3
    observations, info = vector.reset()  # unseeded: each copy continues its generator, as the parallel env's reset()
    for copy in (0, 2):
        assert_copy_equals(observations, info, copy, references[copy].reset(), vector.team_info_keys)


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
def test_the_same_seed_gives_the_same_numbers_bit_for_bit(env_id):
    _, vector_class = team_envs(env_id)
    first, second = (vector_class(3, max_cycles=6, autoreset_mode="next_step") for _ in range(2))
    outputs = first.reset(seed=7), second.reset(seed=7)
    rng = np.random.default_rng(1)
    for _ in range(8):
        np.testing.assert_array_equal(outputs[0][0], outputs[1][0])
        for key, value in outputs[0][-1].items():
            np.testing.assert_array_equal(value, outputs[1][-1][key], err_msg=key)
        actions = random_valid(first.action_masks(), rng)
        outputs = first.step(actions), second.step(actions)
        for got, expected in zip(outputs[0][1:4], outputs[1][1:4]):
            np.testing.assert_array_equal(got, expected)
    assert not np.array_equal(vector_class(3, max_cycles=6).reset(seed=8)[0], first.reset(seed=7)[0])


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
@pytest.mark.parametrize("seed", [-1, 1.5, True, "0", [0, 1], [0, 1, -2]])
def test_a_bad_seed_is_a_value_error_saying_what_a_seed_is(env_id, seed):
    _, vector_class = team_envs(env_id)
    with pytest.raises(ValueError, match=rf"seed of {vector_class.__name__}.reset must be None, an int >= 0"):
        vector_class(3).reset(seed=seed)


# ----------------------------------------------------------------------------- bad input


def bad_actions(vector) -> list[tuple[np.ndarray, str]]:
    """(actions, message) pairs of a vector env of 3 copies: wrong shape, dtype, too big, negative."""
    n_robots, top = len(vector.agents), vector.single_action_space.n - 1
    too_big, negative = np.zeros((3, n_robots), dtype=int), np.zeros((3, n_robots), dtype=int)
    too_big[1, n_robots - 1], negative[2, 1] = top + 1, -1
    last = vector.agents[-1]
    return [
        (np.zeros(3, dtype=int), rf"integer array of shape \(3, {n_robots}\), one per copy and robot.*shape \(3,\)"),
        (np.zeros((3, n_robots)), rf"got float64 of shape \(3, {n_robots}\)"),
        (too_big, rf"action {top + 1} of {last} in sub-env 1 is not in the action"),
        (negative, rf"action -1 of robot_1 in sub-env 2 .*in \[0, {top}\]"),
    ]


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
@pytest.mark.parametrize("case", range(4), ids=["shape", "dtype", "too-big", "negative"])
def test_bad_actions_are_value_errors_naming_the_copy_and_robot(env_id, case):
    _, vector_class = team_envs(env_id)
    vector = vector_class(3, max_cycles=10)
    vector.reset(seed=0)
    actions, message = bad_actions(vector)[case]
    with pytest.raises(ValueError, match=message):
        vector.step(actions)


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
def test_a_masked_action_raises_naming_copy_and_robot_or_is_a_no_op_and_leaves_the_env_unchanged(env_id):
    _, vector_class = team_envs(env_id)
    raising, reference, noop = (
        vector_class(3, max_cycles=10, invalid_action=mode) for mode in ("raise",) * 2 + ("noop",)
    )
    for env in (raising, reference, noop):
        env.reset(seed=0)
    copy, robot, action = (int(index) for index in np.argwhere(~raising.action_masks())[0])
    no_ops = np.full((3, len(raising.agents)), raising.traits.noop_action)
    masked = no_ops.copy()
    masked[copy, robot] = action
    with pytest.raises(ValueError, match=rf"action {action} of robot_{robot} in sub-env {copy} is not valid now"):
        raising.step(masked)
    expected_observations, expected_rewards, *_ = reference.step(no_ops)
    np.testing.assert_array_equal(raising.step(no_ops)[0], expected_observations)  # the refused step changed nothing
    observations, rewards, _, _, info = noop.step(masked)
    assert info["invalid_action"][copy, robot] and info["invalid_action"].sum() == 1
    assert info["chosen_action"][copy, robot] == no_ops[copy, robot]
    np.testing.assert_array_equal(observations, expected_observations)
    np.testing.assert_array_equal(rewards, expected_rewards)


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"num_envs": 0}, r"num_envs of {name} must be an int >= 1, got 0"),
        ({"num_envs": 2.0}, r"must be an int >= 1, got 2.0"),
        ({"render_mode": "ascii"}, r"render_mode"),
        (
            {"autoreset_mode": "partial"},
            r"autoreset_mode .* must be one of 'next_step', 'same_step', 'disabled' .*'partial'",
        ),
        ({"max_cyclez": 9}, r"max_cyclez"),
    ],
)
def test_a_bad_argument_is_a_value_error_naming_it(env_id, kwargs, message):
    _, vector_class = team_envs(env_id)
    with pytest.raises(ValueError, match=message.format(name=vector_class.__name__)):
        vector_class(**kwargs)


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
def test_step_before_reset_and_options_are_refused(env_id):
    _, vector_class = team_envs(env_id)
    env = vector_class(2)
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(np.zeros((2, len(env.agents)), dtype=int))
    with pytest.raises(RuntimeError, match="call reset"):
        env.action_masks()
    with pytest.raises(ValueError, match=r"reset takes no options, got \['x'\]"):
        env.reset(options={"x": 1})


# ----------------------------------------------------------------------------- rendering


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
def test_render_draws_copy_0_as_its_parallel_env_through_an_autoreset(env_id):
    parallel_class, vector_class = team_envs(env_id)
    config = {"max_cycles": 3, "render_size_px": 96}
    vector = vector_class(2, render_mode="rgb_array", autoreset_mode="next_step", **config)
    team = parallel_class(render_mode="rgb_array", **config)
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


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
def test_render_without_a_render_mode_warns_and_returns_none(env_id):
    _, vector_class = team_envs(env_id)
    vector = vector_class(2)
    vector.reset(seed=0)
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert vector.render() is None


# ----------------------------------------------------------------------------- the vector API


@pytest.mark.parametrize("env_id", TEAM_VECTOR_IDS)
def test_spaces_agents_masks_and_registration(env_id):
    parallel_class, vector_class = team_envs(env_id)
    env = make_vector_env(env_id, num_envs=5, max_cycles=7)
    team = parallel_class()
    assert type(env) is vector_class and env.num_envs == 5 and env.max_cycles == 7
    assert env.agents == team.possible_agents
    n_robots, n_actions = len(env.agents), team.action_space("robot_0").n
    assert env.single_observation_space == team.observation_space("robot_0")
    assert env.single_action_space == team.action_space("robot_0") == spaces.Discrete(n_actions)
    assert env.observation_space.shape == (5, n_robots, *env.single_observation_space.shape)
    assert env.action_space == spaces.MultiDiscrete(np.full((5, n_robots), n_actions))
    observations, info = env.reset(seed=0)
    assert observations in env.observation_space and observations.dtype == np.float32
    masks = env.action_masks()
    assert masks.shape == (5, n_robots, n_actions) and masks.dtype == bool
    assert masks[..., team.traits.noop_action].all()
    assert env.action_space.sample() in env.action_space
    assert env.team_info_keys <= set(info) and all(info[key].shape == (5,) for key in env.team_info_keys)
    env.close()
