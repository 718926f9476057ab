"""``LandmarkSelectionVectorEnv``: the single env's numbers in each sub-env, autoreset, seeding, API, bad input."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import infonav_gym
from infonav_gym.envs.landmark_selection_vector import LandmarkSelectionVectorEnv
from infonav_gym.world.scenarios import SCENARIOS, field

ENV_ID = "infonav/LandmarkSelection-v0"
TOLERANCE = 1e-9
SINGLE_INFO_KEYS = (
    "action_mask",
    "action_information_gain",
    "chosen_action",
    "invalid_action",
    "pose_entropy",
    "state_entropy",
    "position_error_m",
    "heading_error_rad",
    "true_pose",
    "estimated_pose",
    "time_s",
)


def _actions(rng: np.random.Generator, info: dict) -> np.ndarray:
    """Half the sub-envs pick their best landmark, the others any action (masked ones are no-ops)."""
    gains = info["action_information_gain"]
    best, blind = gains.argmax(axis=1), rng.integers(0, gains.shape[1], len(gains))
    return np.where(rng.random(len(gains)) < 0.5, best, blind)


def _assert_sub_env_matches(vector_info: dict, copy: int, single_info: dict, where: str) -> None:
    for key in SINGLE_INFO_KEYS:
        np.testing.assert_allclose(vector_info[key][copy], single_info[key], rtol=0, atol=TOLERANCE, err_msg=where)
        assert vector_info[f"_{key}"][copy], where
    single_terms = single_info["reward_terms"]
    assert vector_info["reward_terms"]["_mutual_information"][copy] == ("mutual_information" in single_terms), where
    if single_terms:
        reward = vector_info["reward_terms"]["mutual_information"][copy]
        assert abs(reward - single_terms["mutual_information"]) <= TOLERANCE, where


def _reset_as_step(env: gym.Env) -> tuple:
    """What a NEXT_STEP autoreset returns for a sub-env: the single env's ``reset()`` (no seed), reward 0."""
    observation, info = env.reset()
    return observation, 0.0, False, False, info


def _assert_outputs_match(vector_outputs: tuple, single_outputs: list, step: int) -> None:
    """Each sub-env's (observation, reward, terminated, truncated, info) equals its single env's."""
    observations, rewards, terminations, truncations, info = vector_outputs
    for copy, (observation, reward, terminated, truncated, single_info) in enumerate(single_outputs):
        where = f"sub-env {copy}, step {step}"
        np.testing.assert_allclose(observations[copy], observation, rtol=0, atol=TOLERANCE, err_msg=where)
        assert abs(rewards[copy] - reward) <= TOLERANCE, where
        assert (terminations[copy], truncations[copy]) == (terminated, truncated), where
        _assert_sub_env_matches(info, copy, single_info, where)


def _run_in_lockstep(n_envs: int, seed: int, n_steps: int, **config) -> int:
    """Step the vector env and N single envs (seeds ``seed + i``) together; every number must agree. Returns resets."""
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
    done, rng, resets = no_step, np.random.default_rng(seed), 0
    for step in range(1, n_steps + 1):
        actions = _actions(rng, info)
        outputs = vector.step(actions)
        single_outputs = [
            _reset_as_step(single) if done[copy] else single.step(actions[copy]) for copy, single in enumerate(singles)
        ]
        _assert_outputs_match(outputs, single_outputs, step)
        resets += int(done.sum())
        done, info = outputs[2] | outputs[3], outputs[4]
    vector.close()
    return resets


@pytest.mark.parametrize("n_envs", [1, 3, 8])
@pytest.mark.parametrize("seed", [0, 11])
def test_sub_envs_equal_the_single_env_through_autoresets(n_envs, seed):
    assert _run_in_lockstep(n_envs, seed, n_steps=50, horizon=20) == 2 * n_envs


@pytest.mark.parametrize(
    "config",
    [
        {"mapping": True},
        {"scenario": "corridor"},  # 4 landmarks for 8 candidates: padded rows
        {"scenario": "corridor", "mapping": True, "n_candidates": 6},
        {"n_candidates": 3, "sensor_fov_rad": 1.0, "invalid_action": "noop"},
    ],
    ids=["mapping", "corridor", "corridor-mapping", "narrow-fov"],
)
def test_sub_envs_equal_the_single_env_in_other_configs(config):
    assert _run_in_lockstep(3, 5, n_steps=35, horizon=15, **config) == 6


@pytest.mark.parametrize("config", [{}, {"mapping": True}], ids=["known-map", "mapping"])
def test_same_step_autoreset_gives_the_single_envs_last_and_reset_outputs(config):
    n_envs, seed = 3, 4
    vector = gym.make_vec(ENV_ID, num_envs=n_envs, autoreset_mode="same_step", horizon=7, **config)
    assert vector.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    singles = [gym.make(ENV_ID, horizon=7, **config) for _ in range(n_envs)]
    vector.reset(seed=seed)
    for copy, single in enumerate(singles):
        single.reset(seed=seed + copy)
    rng, endings = np.random.default_rng(0), 0
    for step in range(1, 20):
        actions = rng.integers(0, 8, n_envs)
        observations, rewards, terminations, truncations, info = vector.step(actions)
        for copy, single in enumerate(singles):
            where = f"sub-env {copy}, step {step}"
            single_observation, reward, terminated, truncated, single_info = single.step(actions[copy])
            assert abs(rewards[copy] - reward) <= TOLERANCE and truncations[copy] == truncated, where
            assert not terminations[copy] and ("_final_obs" in info) == truncations.any(), where  # as SyncVectorEnv
            if truncated:
                endings += 1
                np.testing.assert_allclose(info["final_obs"][copy], single_observation, atol=TOLERANCE, err_msg=where)
                _assert_sub_env_matches(info["final_info"], copy, single_info, where)
                single_observation, single_info = single.reset()
                single_info = {**single_info, "reward_terms": {}}
            elif truncations.any():
                assert info["final_obs"][copy] is None and not info["_final_info"][copy], where
            np.testing.assert_allclose(observations[copy], single_observation, rtol=0, atol=TOLERANCE, err_msg=where)
            _assert_sub_env_matches(info, copy, single_info, where)
    assert endings == 2 * n_envs


def test_an_unknown_autoreset_mode_is_a_clear_error():
    with pytest.raises(
        ValueError, match="autoreset_mode of LandmarkSelectionVectorEnv must be one of 'next_step', 'same_step'"
    ):
        LandmarkSelectionVectorEnv(num_envs=2, autoreset_mode="disabled")


def _trajectory(env: gym.vector.VectorEnv, seed, n_steps: int = 30) -> list:
    steps = [env.reset(seed=seed)]
    rng = np.random.default_rng(1)
    for _ in range(n_steps):
        steps.append(env.step(_actions(rng, steps[-1][-1])))
    return steps


def test_same_seed_same_trajectory_bit_for_bit():
    env = LandmarkSelectionVectorEnv(num_envs=4, horizon=12)
    first, second = _trajectory(env, 3), _trajectory(env, 3)
    assert data_equivalence(first, second, exact=True)
    assert data_equivalence(first, _trajectory(LandmarkSelectionVectorEnv(num_envs=4, horizon=12), [3, 4, 5, 6]))
    assert not data_equivalence(first[0][0], env.reset(seed=4)[0])


def test_seed_list_seeds_each_sub_env_and_none_keeps_its_generator():
    env = LandmarkSelectionVectorEnv(num_envs=3)
    observations, _ = env.reset(seed=[7, None, np.int64(2)])
    single = gym.make(ENV_ID)
    np.testing.assert_array_equal(observations[0], single.reset(seed=7)[0])
    np.testing.assert_array_equal(observations[2], single.reset(seed=2)[0])
    generator = env.np_randoms[1]
    env.reset(seed=[1, None, 1])
    assert env.np_randoms[1] is generator  # a None seed continues the sub-env's generator


def test_autoreset_is_next_step():
    env = gym.make_vec(ENV_ID, num_envs=2, horizon=3)
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    env.reset(seed=0)
    for step in range(1, 4):
        _, _, terminated, truncated, info = env.step(np.zeros(2, dtype=int))
        assert not terminated.any() and truncated.all() == (step == 3)
        np.testing.assert_allclose(info["time_s"], step * env.unwrapped.config["time_step_s"])
    observations, rewards, terminated, truncated, info = env.step(np.ones(2, dtype=int))  # actions ignored
    assert not (terminated.any() or truncated.any()) and not rewards.any()
    np.testing.assert_array_equal(observations[:, 9], 0.0)  # elapsed fraction of the new episode
    np.testing.assert_array_equal(info["chosen_action"], -1)
    assert not info["reward_terms"]["_mutual_information"].any()
    assert not env.step(np.zeros(2, dtype=int))[3].any()


def test_vector_api():
    env = gym.make_vec(ENV_ID, num_envs=5, n_candidates=6)
    assert isinstance(env, LandmarkSelectionVectorEnv)
    single = gym.make(ENV_ID, n_candidates=6)
    assert env.single_observation_space == single.observation_space
    assert env.single_action_space == single.action_space == gym.spaces.Discrete(6)
    assert env.action_space == gym.spaces.MultiDiscrete([6] * 5)
    observations, info = env.reset(seed=0)
    assert observations.dtype == np.float32 and observations in env.observation_space
    assert info["action_mask"].shape == (5, 6) and info["action_mask"].dtype == np.int8
    for _ in range(25):
        observations, rewards, terminated, truncated, info = env.step(env.action_space.sample())
        assert observations in env.observation_space
        assert rewards.shape == (5,) and rewards.dtype == np.float64
        assert terminated.dtype == truncated.dtype == bool and terminated.shape == truncated.shape == (5,)
        masked_keys = [key for key in info if not key.startswith("_")]
        assert all(info[f"_{key}"].shape == (5,) and info[f"_{key}"].all() for key in masked_keys)
    masks = env.action_masks()
    assert masks.dtype == bool and masks.shape == (5, 6) and masks.any(axis=1).all()
    some = info["action_mask"].any(axis=1)
    np.testing.assert_array_equal(masks[some], info["action_mask"][some].astype(bool))
    assert masks[~some].all()  # no landmark visible: every action is the no-op
    env.close()
    assert env.closed


def test_sync_and_async_vectorization_keep_working():
    native = gym.make_vec(ENV_ID, num_envs=2)
    for mode, kind in [("sync", SyncVectorEnv), ("async", gym.vector.AsyncVectorEnv)]:
        env = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode=mode)
        assert isinstance(env, kind)
        np.testing.assert_allclose(env.reset(seed=4)[0], native.reset(seed=4)[0], rtol=0, atol=TOLERANCE)
        env.close()


def test_step_before_reset_raises():
    with pytest.raises(RuntimeError, match="reset"):
        LandmarkSelectionVectorEnv(num_envs=2).step(np.zeros(2, dtype=int))
    with pytest.raises(RuntimeError, match="reset"):
        LandmarkSelectionVectorEnv(num_envs=2).action_masks()


@pytest.mark.parametrize(
    ("actions", "match"),
    [
        (np.zeros(4, dtype=int), r"shape \(3,\).*got int64 of shape \(4,\)"),
        (np.zeros((3, 1), dtype=int), r"shape \(3,\)"),
        (np.zeros(3), "integer array.*float64"),
        (np.zeros(3, dtype=bool), "integer array.*bool"),
        (np.array([0, 1, 8]), r"action 8 of sub-env 2 is not in the action space Discrete\(8\)"),
        ([0, -1, 0], "action -1 of sub-env 1"),
    ],
)
def test_bad_actions_raise_naming_the_sub_env(actions, match):
    env = LandmarkSelectionVectorEnv(num_envs=3)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(actions)


def _masked_actions(env: LandmarkSelectionVectorEnv, info: dict) -> tuple[np.ndarray, int]:
    """One masked action in a sub-env that has a valid one, valid actions elsewhere; and that sub-env."""
    mask = info["action_mask"]
    copy = int(np.flatnonzero(mask.any(axis=1) & ~mask.all(axis=1))[0])
    actions = mask.argmax(axis=1)
    actions[copy] = int(np.flatnonzero(mask[copy] == 0)[0])
    return actions, copy


def test_masked_action_follows_invalid_action_per_sub_env():
    env = LandmarkSelectionVectorEnv(num_envs=4, invalid_action="raise")
    _, info = env.reset(seed=1)
    actions, copy = _masked_actions(env, info)
    with pytest.raises(ValueError, match=f"action {actions[copy]} of sub-env {copy} is not valid now"):
        env.step(actions)
    noop = LandmarkSelectionVectorEnv(num_envs=4)
    _, info = noop.reset(seed=1)
    _, rewards, _, _, info = noop.step(actions)
    assert info["invalid_action"][copy] and rewards[copy] == 0.0 and info["chosen_action"][copy] == -1
    others = np.arange(4) != copy
    assert not info["invalid_action"][others].any() and (rewards[others] > 0).all()


@pytest.mark.parametrize(
    ("arguments", "match"),
    [
        ({"num_envs": 0}, "num_envs of LandmarkSelectionVectorEnv must be an int >= 1, got 0"),
        ({"num_envs": 2.0}, "num_envs"),
        ({"render_mode": "rgb"}, r"render_mode must be None or one of \['human', 'rgb_array'\], got 'rgb'"),
        ({"n_candidate": 3}, "n_candidate"),
        ({"n_candidates": 0}, "n_candidates"),
        ({"scenario": "maze"}, "scenario"),
    ],
)
def test_bad_arguments_raise(arguments, match):
    with pytest.raises(ValueError, match=match):
        LandmarkSelectionVectorEnv(**{"num_envs": 2, **arguments})


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
        LandmarkSelectionVectorEnv(num_envs=3).reset(**reset_arguments)


def test_vector_entry_point_needs_a_gymnasium_api():
    with pytest.raises(ValueError, match="vector_entry_point of env 'toy/Team-v0' needs api='gymnasium'"):
        infonav_gym.register("toy/Team-v0", "toy:Team", infonav_gym.PARALLEL, "toy:TeamVector")
    with pytest.raises(ValueError, match="'module:attribute'"):
        infonav_gym.register("toy/Beacon-v0", "toy:Beacon", vector_entry_point="toy.BeaconVector")


def _uneven(np_random, n_landmarks):
    """A field of 3 or 4 landmarks, by the copy's generator (``n_landmarks``, the candidates, is an upper bound)."""
    return field(np_random, n_landmarks=int(np_random.integers(3, min(n_landmarks, 4) + 1)))


@pytest.fixture
def uneven_scenario(monkeypatch):
    monkeypatch.setitem(SCENARIOS, "uneven", _uneven)


def test_sub_envs_with_different_landmark_counts_equal_the_single_env(uneven_scenario):
    assert _run_in_lockstep(6, 2, n_steps=30, horizon=12, scenario="uneven") == 12


def test_mapping_needs_the_same_landmark_count_in_every_sub_env(uneven_scenario):
    env = LandmarkSelectionVectorEnv(num_envs=8, scenario="uneven", mapping=True)
    with pytest.raises(ValueError, match=r"sub-env \d of LandmarkSelectionVectorEnv: with mapping=True every copy"):
        env.reset(seed=0)


def test_render_draws_sub_env_0_as_its_single_env_through_an_autoreset():
    vector = gym.make_vec(ENV_ID, num_envs=3, render_mode="rgb_array", horizon=4, render_size_px=96)
    single = gym.make(ENV_ID, render_mode="rgb_array", horizon=4, render_size_px=96)
    vector.reset(seed=21)
    single.reset(seed=21)
    rng = np.random.default_rng(0)
    for step in range(10):
        frame = vector.render()
        assert frame.shape == (96, 96, 3)
        np.testing.assert_array_equal(frame, single.render(), err_msg=f"step {step}")
        actions = rng.integers(0, 8, 3)
        truncated = vector.step(actions)[3]
        if step % 5 == 4:  # the NEXT_STEP autoreset of sub-env 0
            single.reset()
        else:
            single.step(actions[0])
        assert truncated[0] == (step % 5 == 3)
    vector.close()


def test_render_without_a_render_mode_warns_and_returns_none():
    env = LandmarkSelectionVectorEnv(num_envs=2)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert env.render() is None
