"""``LandmarkSelectionVectorEnv``: the single env's numbers in each sub-env, autoreset, seeding, API, bad input."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import vector_env_checks
from gymnasium.vector import AutoresetMode

import infonav_gym
from infonav_gym.envs.landmark_selection import LandmarkSelectionVectorEnv
from infonav_gym.envs.vector_infos import reward_terms_of
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
    assert vector_info["_reward_mutual_information"][copy], where
    reward = vector_info["reward_mutual_information"][copy]
    assert abs(reward - reward_terms_of(single_info)["mutual_information"]) <= TOLERANCE, where


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
    """Step the vector env (NEXT_STEP) and N single envs (seeds ``seed + i``) together; every number must agree.
    Returns resets."""
    vector = gym.make_vec(ENV_ID, num_envs=n_envs, autoreset_mode="next_step", **config)
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
            elif truncations.any():
                assert info["final_obs"][copy] is None and not info["_final_info"][copy], where
            np.testing.assert_allclose(observations[copy], single_observation, rtol=0, atol=TOLERANCE, err_msg=where)
            _assert_sub_env_matches(info, copy, single_info, where)
    assert endings == 2 * n_envs


def test_an_unknown_autoreset_mode_is_a_clear_error():
    with pytest.raises(
        ValueError,
        match="autoreset_mode of LandmarkSelectionVectorEnv must be one of 'next_step', 'same_step', 'disabled'",
    ):
        LandmarkSelectionVectorEnv(num_envs=2, autoreset_mode="sometimes")


def test_with_autoreset_disabled_sub_envs_step_on_past_their_end_until_reset():
    vector_env_checks.check_autoreset_disabled(ENV_ID)


def test_autoreset_is_next_step_on_request():
    env = gym.make_vec(ENV_ID, num_envs=2, horizon=3, autoreset_mode="next_step")
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
    assert info["_reward_mutual_information"].all() and not info["reward_mutual_information"].any()
    assert not env.step(np.zeros(2, dtype=int))[3].any()


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


def test_a_malformed_vector_entry_point_is_refused():  # any api may have one: see test_cooperative_localization_vector
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


def test_render_without_a_render_mode_warns_and_returns_none():
    env = LandmarkSelectionVectorEnv(num_envs=2)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert env.render() is None


@pytest.mark.parametrize("mapping", [False, True])
def test_the_filter_equals_filterpys_ekf_update_for_update(mapping, monkeypatch):
    """Along a whole episode the env's EKF equals raw filterpy fed the same readings (x 1e-12, P 1e-10)."""
    n_observed = vector_env_checks.check_filter_equals_filterpy(
        ENV_ID, lambda chosen: chosen, monkeypatch, seed=5, n_steps=120, mapping=mapping
    )
    assert n_observed > 60
