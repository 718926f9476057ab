"""``ActiveLocalizationVectorEnv``: the single env's numbers in each sub-env, autoreset, seeding, API, bad input."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from gymnasium.wrappers.vector import DictInfoToList, RecordEpisodeStatistics

from agents import GreedyEntropyAgent
from infonav_gym.envs.active_localization import N_PRIMITIVES, REWARD_TERMS
from infonav_gym.envs.active_localization_vector import ActiveLocalizationVectorEnv

ENV_ID = "infonav/ActiveLocalization-v0"
TOLERANCE = 1e-9
GREEDY = GreedyEntropyAgent()


def _greedy_or_blind(rng: np.random.Generator, info: dict) -> np.ndarray:
    """Per sub-env: the greedy agent's action, a random valid one, or any action (masked ones are no-ops)."""
    mask = info["action_mask"]
    keys = ("action_mask", "action_information_gain")
    greedy = np.array([GREEDY.act(None, {key: info[key][copy] for key in keys}) for copy in range(len(mask))])
    valid = np.array([rng.choice(np.flatnonzero(row)) for row in mask])
    blind = rng.integers(0, mask.shape[1], len(mask))
    return np.select([rng.random(len(mask)) < 0.4, rng.random(len(mask)) < 0.7], [greedy, valid], blind)


def _assert_info_matches(vector_info: dict, copy: int, single_info: dict, where: str) -> None:
    """Every key of the single env's info equals the sub-env's entry, which its ``_key`` mask marks as present."""
    assert set(vector_info) == set(single_info) | {f"_{key}" for key in single_info}, where
    for key, value in single_info.items():
        assert vector_info[f"_{key}"][copy], f"{where}: _{key}"
        if key != "reward_terms":
            np.testing.assert_allclose(vector_info[key][copy], value, rtol=0, atol=TOLERANCE, err_msg=f"{where}: {key}")
    terms = vector_info["reward_terms"]
    for term in REWARD_TERMS:
        assert terms[f"_{term}"][copy] == (term in single_info["reward_terms"]), f"{where}: _{term}"
        expected = single_info["reward_terms"].get(term, 0.0)
        assert abs(terms[term][copy] - expected) <= TOLERANCE, f"{where}: {term}"


def _assert_outputs_match(vector_outputs: tuple, single_outputs: list, step: int) -> None:
    """Each sub-env's (observation, reward, terminated, truncated, info) equals its single env's."""
    observations, rewards, terminations, truncations, info = vector_outputs
    for copy, (observation, reward, terminated, truncated, single_info) in enumerate(single_outputs):
        where = f"sub-env {copy}, step {step}"
        np.testing.assert_allclose(observations[copy], observation, rtol=0, atol=TOLERANCE, err_msg=where)
        assert abs(rewards[copy] - reward) <= TOLERANCE, where
        assert (terminations[copy], truncations[copy]) == (terminated, truncated), where
        _assert_info_matches(info, copy, single_info, where)


def _run_in_lockstep(n_envs: int, seed: int, n_steps: int, **config) -> tuple[int, int]:
    """Step the vector env and N single envs (seeds ``seed + i``) together; every number must agree.

    Returns:
        How many episodes ended terminated, and how many truncated.
    """
    vector = gym.make_vec(ENV_ID, num_envs=n_envs, **config)
    singles = [gym.make(ENV_ID, **config) for _ in range(n_envs)]
    observations, info = vector.reset(seed=seed)
    reset_outputs = [single.reset(seed=seed + copy) for copy, single in enumerate(singles)]
    no_step = np.zeros(n_envs, dtype=bool)
    _assert_outputs_match(
        (observations, np.zeros(n_envs), no_step, no_step, info),
        [(observation, 0.0, False, False, single_info) for observation, single_info in reset_outputs],
        step=0,
    )
    done, rng, ended = no_step, np.random.default_rng(seed), np.zeros(2, dtype=int)
    for step in range(1, n_steps + 1):
        actions = _greedy_or_blind(rng, info)
        outputs = vector.step(actions)
        single_outputs = [
            _reset_as_step(single) if done[copy] else single.step(actions[copy]) for copy, single in enumerate(singles)
        ]
        _assert_outputs_match(outputs, single_outputs, step)
        ended += [outputs[2].sum(), outputs[3].sum()]
        done, info = outputs[2] | outputs[3], outputs[4]
    vector.close()
    return int(ended[0]), int(ended[1])


def _reset_as_step(env: gym.Env) -> tuple:
    """What a NEXT_STEP autoreset returns for a sub-env: the single env's ``reset()`` (no seed), reward 0."""
    observation, info = env.reset()
    return observation, 0.0, False, False, info


@pytest.mark.parametrize("n_envs", [1, 4])
@pytest.mark.parametrize("seed", [0, 21])
def test_sub_envs_equal_the_single_env_through_autoresets(n_envs, seed):
    terminated, truncated = _run_in_lockstep(n_envs, seed, n_steps=60, horizon=25)
    assert truncated >= n_envs  # every sub-env ended at least once, and was reset


@pytest.mark.parametrize(
    ("config", "ends"),
    [
        ({"goal_radius_m": 30.0}, "terminated"),  # the goal is reached within a few steps
        ({"max_position_std_m": 0.25}, "terminated"),  # the uncertainty bound is crossed
        ({"max_observations": 0, "n_obstacles": 0, "horizon": 20}, "truncated"),  # no budget: observe nothing
        ({"n_candidates": 5, "sensor_fov_rad": 1.0, "horizon": 12}, "truncated"),
    ],
    ids=["goal", "failure", "no-budget", "narrow-fov"],
)
def test_sub_envs_equal_the_single_env_in_other_configs(config, ends):
    terminated, truncated = _run_in_lockstep(3, 5, n_steps=45, **config)
    assert {"terminated": terminated, "truncated": truncated}[ends] >= 3


def test_whole_greedy_episodes_equal_the_single_env():
    """Greedy to the end of the default 100-step episodes, through a reset of every sub-env."""
    vector = ActiveLocalizationVectorEnv(num_envs=3)
    _, info = vector.reset(seed=40)
    singles = [gym.make(ENV_ID) for _ in range(3)]
    single_infos = [single.reset(seed=40 + copy)[1] for copy, single in enumerate(singles)]
    done, endings = np.zeros(3, dtype=bool), 0
    while endings < 4:
        actions = np.array([GREEDY.act(None, single_info) for single_info in single_infos])
        outputs = vector.step(actions)
        single_outputs = [
            _reset_as_step(single) if done[copy] else single.step(actions[copy]) for copy, single in enumerate(singles)
        ]
        _assert_outputs_match(outputs, single_outputs, step=-1)
        single_infos = [single_output[4] for single_output in single_outputs]
        done = outputs[2] | outputs[3]
        endings += int(done.sum())


def _assert_infos_match(native: dict, sync: dict, where: str) -> None:
    """The native info holds every entry of Gymnasium's ``SyncVectorEnv`` info; its other entries are masked out."""
    for key, value in sync.items():
        if isinstance(value, dict):
            _assert_infos_match(native[key], value, f"{where}: {key}")
        elif key == "final_obs":
            assert [row is None for row in native[key]] == [row is None for row in value], where
            for native_row, sync_row in zip(native[key], value):
                if sync_row is not None:
                    np.testing.assert_allclose(native_row, sync_row, rtol=0, atol=TOLERANCE, err_msg=where)
        else:
            np.testing.assert_allclose(native[key], value, rtol=0, atol=TOLERANCE, err_msg=f"{where}: {key}")
    for key in set(native) - set(sync):  # reward terms of sub-envs that did not step (a reset info has none)
        assert not native[f"_{key.lstrip('_')}"].any(), f"{where}: {key}"


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_the_native_env_equals_gymnasiums_sync_vectorization(mode):
    native = gym.make_vec(ENV_ID, num_envs=3, horizon=15, autoreset_mode=mode)
    sync = gym.make_vec(
        ENV_ID, num_envs=3, horizon=15, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}
    )
    assert native.metadata["autoreset_mode"] == sync.metadata["autoreset_mode"] == mode
    native_outputs, sync_outputs = native.reset(seed=8), sync.reset(seed=8)
    rng, endings = np.random.default_rng(8), 0
    for step in range(45):
        for native_item, sync_item in zip(native_outputs[:-1], sync_outputs[:-1]):
            np.testing.assert_allclose(native_item, sync_item, rtol=0, atol=TOLERANCE, err_msg=f"step {step}")
        _assert_infos_match(native_outputs[-1], sync_outputs[-1], f"step {step}")
        actions = _greedy_or_blind(rng, native_outputs[-1])
        native_outputs, sync_outputs = native.step(actions), sync.step(actions)
        endings += int(np.sum(native_outputs[2] | native_outputs[3]))
    assert endings >= 6


def test_same_step_autoreset_gives_the_single_envs_last_and_reset_outputs():
    n_envs, seed, config = 3, 6, {"horizon": 9, "goal_radius_m": 29.0}  # episodes end both ways
    vector = gym.make_vec(ENV_ID, num_envs=n_envs, autoreset_mode="same_step", **config)
    singles = [gym.make(ENV_ID, **config) for _ in range(n_envs)]
    _, info = vector.reset(seed=seed)
    for copy, single in enumerate(singles):
        single.reset(seed=seed + copy)
    rng, ended = np.random.default_rng(0), np.zeros(2, dtype=int)
    for step in range(1, 30):
        actions = _greedy_or_blind(rng, info)
        observations, rewards, terminations, truncations, info = vector.step(actions)
        assert ("_final_obs" in info) == (terminations | truncations).any()  # as SyncVectorEnv
        for copy, single in enumerate(singles):
            where = f"sub-env {copy}, step {step}"
            single_observation, reward, terminated, truncated, single_info = single.step(actions[copy])
            assert abs(rewards[copy] - reward) <= TOLERANCE, where
            assert (terminations[copy], truncations[copy]) == (terminated, truncated), where
            if terminated or truncated:
                ended += [terminated, truncated]
                np.testing.assert_allclose(info["final_obs"][copy], single_observation, atol=TOLERANCE, err_msg=where)
                _assert_info_matches(info["final_info"], copy, single_info, where)
                single_observation, single_info = single.reset()
            elif "_final_obs" in info:
                assert info["final_obs"][copy] is None and not info["_final_info"][copy], where
            np.testing.assert_allclose(observations[copy], single_observation, rtol=0, atol=TOLERANCE, err_msg=where)
            _assert_info_matches(_without_final(info), copy, single_info, where)
    assert ended.min() >= 1 and ended.sum() >= 2 * n_envs


def _without_final(info: dict) -> dict:
    return {key: value for key, value in info.items() if not key.lstrip("_").startswith("final_")}


def test_an_unknown_autoreset_mode_is_a_clear_error():
    with pytest.raises(
        ValueError, match="autoreset_mode of ActiveLocalizationVectorEnv must be one of 'next_step', 'same_step'"
    ):
        ActiveLocalizationVectorEnv(num_envs=2, autoreset_mode="disabled")


def _trajectory(env: gym.vector.VectorEnv, seed, n_steps: int = 30) -> list:
    steps = [env.reset(seed=seed)]
    rng = np.random.default_rng(1)
    for _ in range(n_steps):
        steps.append(env.step(_greedy_or_blind(rng, steps[-1][-1])))
    return steps


def test_same_seed_same_trajectory_bit_for_bit():
    env = ActiveLocalizationVectorEnv(num_envs=4, horizon=12)
    first, second = _trajectory(env, 3), _trajectory(env, 3)
    assert data_equivalence(first, second, exact=True)
    assert data_equivalence(first, _trajectory(ActiveLocalizationVectorEnv(num_envs=4, horizon=12), [3, 4, 5, 6]))
    assert not data_equivalence(first[0][0], env.reset(seed=4)[0])


def test_seed_list_seeds_each_sub_env_and_none_keeps_its_generator():
    env = ActiveLocalizationVectorEnv(num_envs=3)
    observations, _ = env.reset(seed=[7, None, np.int64(2)])
    single = gym.make(ENV_ID)
    np.testing.assert_array_equal(observations[0], single.reset(seed=7)[0])
    np.testing.assert_array_equal(observations[2], single.reset(seed=2)[0])
    generator = env.np_randoms[1]
    env.reset(seed=[1, None, 1])
    assert env.np_randoms[1] is generator  # a None seed continues the sub-env's generator


def test_autoreset_is_next_step_after_termination_and_truncation():
    env = gym.make_vec(ENV_ID, num_envs=2, horizon=3, goal_radius_m=33.0, failure_penalty=4.0)
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    _, info = env.reset(seed=0)
    distance = info["distance_to_goal_m"]
    assert distance[0] > 33.0 and distance[1] > 33.0  # neither reached yet
    ended = np.zeros(2, dtype=bool)
    for step in range(1, 4):
        _, rewards, terminated, truncated, info = env.step(np.zeros(2, dtype=int))  # to the goal, observing nothing
        assert not (terminated & truncated).any()
        np.testing.assert_array_equal(terminated, info["goal_reached"] & ~ended)
        np.testing.assert_array_equal(info["reward_terms"]["goal_bonus"], np.where(terminated, 10.0, 0.0))
        assert (truncated == (~ended & ~terminated & (step == 3))).all()
        ended |= terminated | truncated
        if ended.all():
            break
    assert ended.all()
    observations, rewards, terminated, truncated, info = env.step(np.full(2, 7))  # actions ignored
    assert not (terminated.any() or truncated.any()) and not rewards.any()
    np.testing.assert_array_equal(observations[:, 9], 0.0)  # elapsed fraction of the new episode
    np.testing.assert_array_equal(info["chosen_action"], -1)
    np.testing.assert_array_equal(info["observations_left"], env.unwrapped.config["max_observations"])
    assert not any(info["reward_terms"][f"_{term}"].any() for term in REWARD_TERMS)
    assert not env.step(np.zeros(2, dtype=int))[3].any()


def test_vector_api():
    env = gym.make_vec(ENV_ID, num_envs=5, n_candidates=6, n_obstacles=2)
    assert isinstance(env, ActiveLocalizationVectorEnv)
    single = gym.make(ENV_ID, n_candidates=6, n_obstacles=2)
    assert env.single_observation_space == single.observation_space
    assert env.single_action_space == single.action_space == gym.spaces.Discrete(N_PRIMITIVES * 7)
    assert env.action_space == gym.spaces.MultiDiscrete([N_PRIMITIVES * 7] * 5)
    observations, info = env.reset(seed=0)
    assert observations.dtype == np.float32 and observations in env.observation_space
    assert info["action_mask"].shape == (5, 35) and info["action_mask"].dtype == np.int8
    for _ in range(40):
        observations, rewards, terminated, truncated, info = env.step(env.action_space.sample())
        assert observations in env.observation_space
        assert rewards.shape == (5,) and rewards.dtype == np.float64
        assert terminated.dtype == truncated.dtype == bool and terminated.shape == truncated.shape == (5,)
        masked_keys = [key for key in info if not key.startswith("_")]
        assert all(info[f"_{key}"].shape == (5,) and info[f"_{key}"].all() for key in masked_keys)
        masks = env.action_masks()
        np.testing.assert_array_equal(masks, info["action_mask"].astype(bool))  # observing nothing is always valid
        assert masks[:, :N_PRIMITIVES].all()
    with pytest.raises(NotImplementedError, match="render"):
        env.render()
    env.close()
    assert env.closed


def test_gymnasium_vector_wrappers_read_its_infos():
    env = DictInfoToList(RecordEpisodeStatistics(gym.make_vec(ENV_ID, num_envs=3, horizon=10)))
    _, infos = env.reset(seed=2)
    assert len(infos) == 3 and infos[1]["goal"].shape == (2,) and infos[1]["reward_terms"] == {}
    returns, episodes = np.zeros(3), []
    for _ in range(11):  # one episode of 10 steps, then the reset step (reward 0)
        _, rewards, terminated, truncated, infos = env.step(np.zeros(3, dtype=int))
        returns += rewards
        episodes += [info["episode"] for info in infos if "episode" in info]
    assert len(episodes) == 3
    np.testing.assert_allclose(sorted(episode["r"] for episode in episodes), sorted(returns), rtol=1e-6)
    assert all(episode["l"] == 10 for episode in episodes)


def test_sync_and_async_vectorization_keep_working():
    native = gym.make_vec(ENV_ID, num_envs=2)
    for mode, kind in [("sync", SyncVectorEnv), ("async", gym.vector.AsyncVectorEnv)]:
        env = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode=mode)
        assert isinstance(env, kind)
        np.testing.assert_allclose(env.reset(seed=4)[0], native.reset(seed=4)[0], rtol=0, atol=TOLERANCE)
        env.close()


def test_step_before_reset_raises():
    with pytest.raises(RuntimeError, match="reset"):
        ActiveLocalizationVectorEnv(num_envs=2).step(np.zeros(2, dtype=int))
    with pytest.raises(RuntimeError, match="reset"):
        ActiveLocalizationVectorEnv(num_envs=2).action_masks()


@pytest.mark.parametrize(
    ("actions", "match"),
    [
        (np.zeros(4, dtype=int), r"shape \(3,\).*got int64 of shape \(4,\)"),
        (np.zeros((3, 1), dtype=int), r"shape \(3,\)"),
        (np.zeros(3), "integer array.*float64"),
        (np.zeros(3, dtype=bool), "integer array.*bool"),
        (np.array([0, 1, 45]), r"action 45 of sub-env 2 is not in the action space Discrete\(45\)"),
        ([0, -1, 0], r"action -1 of sub-env 1 .*in \[0, 44\]"),
    ],
)
def test_bad_actions_raise_naming_the_sub_env(actions, match):
    env = ActiveLocalizationVectorEnv(num_envs=3)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(actions)


def _masked_actions(info: dict) -> tuple[np.ndarray, int]:
    """Observing a hidden landmark in one sub-env (driving to the goal), valid observations elsewhere."""
    mask = info["action_mask"]
    observable = mask[:, N_PRIMITIVES:].any(axis=1)
    copy = int(np.flatnonzero(observable)[0])
    actions = mask[:, N_PRIMITIVES:].argmax(axis=1) + N_PRIMITIVES  # the first observable (or masked) landmark
    actions[copy] = int(np.flatnonzero(mask[copy] == 0)[0])
    return actions, copy


def test_masked_action_follows_invalid_action_per_sub_env():
    env = ActiveLocalizationVectorEnv(num_envs=4, invalid_action="raise")
    _, info = env.reset(seed=1)
    actions, copy = _masked_actions(info)
    with pytest.raises(ValueError, match=f"action {actions[copy]} of sub-env {copy} is not valid now"):
        env.step(actions)
    noop = ActiveLocalizationVectorEnv(num_envs=4)
    _, info = noop.reset(seed=1)
    _, rewards, _, _, info = noop.step(actions)
    assert info["invalid_action"][copy] and rewards[copy] == 0.0 and info["chosen_action"][copy] == -1
    np.testing.assert_array_equal(info["observations_left"][copy], 12)  # a no-op observes nothing
    valid = np.arange(4) != copy
    observed = info["observations_left"][valid] == 11
    assert not info["invalid_action"][valid].any() and (info["reward_terms"]["mutual_information"][valid] > 0).all()
    assert observed.all()


@pytest.mark.parametrize(
    ("arguments", "match"),
    [
        ({"num_envs": 0}, "num_envs of ActiveLocalizationVectorEnv must be an int >= 1, got 0"),
        ({"num_envs": 2.0}, "num_envs"),
        ({"render_mode": "rgb_array"}, "render_mode must be None"),
        ({"n_candidate": 8}, "n_candidate"),
        ({"n_candidates": 2}, "n_candidates"),
        ({"max_position_std_m": 0.05}, "must exceed initial_position_std_m"),
    ],
)
def test_bad_arguments_raise(arguments, match):
    with pytest.raises(ValueError, match=match):
        ActiveLocalizationVectorEnv(**{"num_envs": 2, **arguments})


@pytest.mark.parametrize(
    ("reset_arguments", "match"),
    [
        ({"seed": [1, 2]}, r"None, an int >= 0 or a list of 3 such seeds \(one per sub-env\), got \[1, 2\]"),
        ({"seed": -1}, "int >= 0"),
        ({"seed": [0, np.int64(3), -2]}, "int >= 0"),
        ({"seed": 1.5}, "seed"),
        ({"seed": [1, True, 2]}, "seed"),
        ({"options": {"reset_mask": [True] * 3}}, "takes no options"),
    ],
)
def test_bad_reset_arguments_raise(reset_arguments, match):
    with pytest.raises(ValueError, match=match):
        ActiveLocalizationVectorEnv(num_envs=3).reset(**reset_arguments)
