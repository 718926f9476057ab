"""``VectorEnvAdapter``: a Gymnasium vector env in SAME_STEP autoreset as an SB3 ``VecEnv``.

Transitions equal SB3's ``DummyVecEnv`` over the single envs for the same seeds; masks reach MaskablePPO
in one call; sub-env access and bad input are errors for people.
"""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.envs.classic_control.cartpole import CartPoleVectorEnv
from gymnasium.vector import AutoresetMode

pytest.importorskip("sb3_contrib")

from sb3_contrib import MaskablePPO  # noqa: E402
from sb3_contrib.common.maskable.utils import get_action_masks, is_masking_supported  # noqa: E402
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402
from stable_baselines3.common.vec_env import VecEnv, VecMonitor, VecNormalize  # noqa: E402

import infonav_gym  # noqa: E402, F401  (registers the envs)
from agents.vector_adapter import VectorEnvAdapter  # noqa: E402
from infonav_gym.experiments.ppo_timing import SameStepCartPoleVectorEnv  # noqa: E402

LANDMARK_ID = "infonav/LandmarkSelection-v0"
SAME_STEP = {"autoreset_mode": AutoresetMode.SAME_STEP}
DISABLED = {"autoreset_mode": AutoresetMode.DISABLED}
NEXT_STEP = {"autoreset_mode": AutoresetMode.NEXT_STEP}
CASES = [  # (env id, config, vectorization mode of gym.make_vec)
    ("CartPole-v1", {}, "sync"),
    (LANDMARK_ID, {"horizon": 15}, "sync"),
    (LANDMARK_ID, {"horizon": 12, "mapping": True}, "sync"),
    (LANDMARK_ID, {"horizon": 15}, "vector_entry_point"),
    (LANDMARK_ID, {"horizon": 12, "mapping": True}, "vector_entry_point"),
]
CASE_IDS = ["cartpole", "landmarks", "landmarks-mapping", "native-landmarks", "native-landmarks-mapping"]


def make_adapter(env_id: str, n_envs: int, config: dict, mode: str = "sync", **adapter_kwargs) -> VectorEnvAdapter:
    """An adapter over ``gym.make_vec`` in SAME_STEP autoreset, through Gymnasium's sync env or the native one."""
    if mode == "sync":
        vector_env = gym.make_vec(env_id, n_envs, vectorization_mode=mode, vector_kwargs=SAME_STEP, **config)
    else:
        vector_env = gym.make_vec(env_id, n_envs, vectorization_mode=mode, **SAME_STEP, **config)
    return VectorEnvAdapter(vector_env, **adapter_kwargs)


def valid_actions(masks: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One uniformly drawn valid action per row of ``masks``."""
    return np.array([rng.choice(np.flatnonzero(row)) for row in masks])


# ---------------------------------------------------------------- the same transitions as DummyVecEnv


@pytest.mark.parametrize("env_id, config, mode", CASES, ids=CASE_IDS)
@pytest.mark.parametrize("seed", [0, 7])
def test_transitions_and_masks_equal_dummy_vec_env_over_the_single_envs(env_id, config, mode, seed):
    """Bit for bit through Gymnasium's sync env; to float32 rounding through the native one (batched math)."""
    n_envs, close = 3, {"rtol": 1e-6, "atol": 1e-9}
    adapter = make_adapter(env_id, n_envs, config, mode, info_keywords=("position_error_m",) if config else ())
    reference = make_vec_env(env_id, n_envs=n_envs, seed=seed, env_kwargs=config)
    assert adapter.seed(seed) == [seed, seed + 1, seed + 2]
    np.testing.assert_allclose(adapter.reset(), reference.reset(), **close)
    rng, ends, truncations = np.random.default_rng(seed), 0, 0
    for step in range(100):
        masks = adapter.action_masks()
        np.testing.assert_array_equal(masks, get_action_masks(reference) if config else np.ones((n_envs, 2), bool))
        actions = valid_actions(masks, rng)
        observations, rewards, dones, infos = adapter.step(actions)
        expected_observations, expected_rewards, expected_dones, expected_infos = reference.step(actions)
        if mode == "sync":
            np.testing.assert_array_equal(observations, expected_observations, err_msg=f"step {step}")
            np.testing.assert_array_equal(rewards, expected_rewards)
        np.testing.assert_allclose(observations, expected_observations, **close, err_msg=f"step {step}")
        np.testing.assert_allclose(rewards, expected_rewards, **close)
        assert rewards.dtype == np.float32 and dones.dtype == bool and len(infos) == n_envs
        np.testing.assert_array_equal(dones, expected_dones)
        for index in range(n_envs):
            if not dones[index]:
                assert infos[index] == {}
                continue
            ends += 1
            truncations += infos[index]["TimeLimit.truncated"]
            expected = expected_infos[index]
            np.testing.assert_allclose(infos[index]["terminal_observation"], expected["terminal_observation"], **close)
            assert infos[index]["TimeLimit.truncated"] == expected["TimeLimit.truncated"]
            if config:
                assert infos[index]["position_error_m"] == pytest.approx(expected["position_error_m"], abs=1e-9)
    assert ends >= n_envs
    assert truncations == (ends if config else 0)  # LandmarkSelection only truncates, CartPole falls first
    adapter.close()


def test_seed_is_used_once_and_a_reset_without_it_continues_each_generator_as_dummy_vec_env():
    adapter = make_adapter("CartPole-v1", 2, {})
    reference = make_vec_env("CartPole-v1", n_envs=2, seed=None)
    for vec_env in (adapter, reference):
        vec_env.seed(5)
    first, again = adapter.reset(), adapter.reset()
    np.testing.assert_array_equal(first, reference.reset())
    np.testing.assert_array_equal(again, reference.reset())
    assert not np.array_equal(first, again)
    adapter.seed(5)
    np.testing.assert_array_equal(adapter.reset(), first)


def test_options_reach_every_sub_env_once_and_different_options_are_refused():
    adapter = VectorEnvAdapter(SameStepCartPoleVectorEnv(num_envs=4))
    adapter.set_options({"low": 0.3, "high": 0.31})
    assert np.all(adapter.reset() >= 0.3)
    assert np.all(np.abs(adapter.reset()) <= 0.05), "the options were used once"
    adapter.set_options([{"low": 0.3, "high": 0.31}] + [{}] * 3)
    with pytest.raises(ValueError, match="one options dict for all sub-envs, but set_options gave them different"):
        adapter.reset()


# ---------------------------------------------------------------- the SB3 VecEnv contract


def test_the_vec_env_contract_spaces_shapes_dtypes_and_determinism():
    adapter = VecMonitor(make_adapter(LANDMARK_ID, 4, {"horizon": 10}))
    assert isinstance(adapter, VecEnv) and adapter.num_envs == 4
    assert adapter.observation_space == gym.make(LANDMARK_ID).observation_space
    assert adapter.action_space == gym.make(LANDMARK_ID).action_space
    runs = []
    for _ in range(2):
        adapter.seed(11)
        observations, trajectory = adapter.reset(), []
        for _ in range(25):
            assert observations.shape == (4, *adapter.observation_space.shape)
            assert all(adapter.observation_space.contains(row) for row in observations)
            observations, rewards, dones, infos = adapter.step(np.zeros(4, dtype=np.int64))
            trajectory.append((observations, rewards, dones))
        runs.append(trajectory)
        assert adapter.episode_count == 8 * len(runs)  # 2 x 4 episodes of 10 steps each run, VecMonitor counted
    for (first, *_), (second, *_) in zip(*runs):
        np.testing.assert_array_equal(first, second)


def test_same_step_cartpole_resets_in_the_step_gymnasium_resets_at_the_next():
    ours, gymnasiums = SameStepCartPoleVectorEnv(num_envs=8), CartPoleVectorEnv(num_envs=8)
    assert ours.reset(seed=3)[0].tolist() == gymnasiums.reset(seed=3)[0].tolist()
    rng = np.random.default_rng(0)
    while True:
        actions = rng.integers(0, 2, 8)
        observations, rewards, terminated, truncated, info = ours.step(actions)
        expected, expected_rewards, expected_terminated, _, _ = gymnasiums.step(actions)
        np.testing.assert_array_equal(rewards, expected_rewards)
        np.testing.assert_array_equal(terminated, expected_terminated)
        ended = terminated | truncated
        if ended.any():
            break
        np.testing.assert_array_equal(observations, expected)
        assert info == {}
    np.testing.assert_array_equal(info["_final_obs"], ended)
    for index in np.flatnonzero(ended):
        np.testing.assert_array_equal(info["final_obs"][index], expected[index])
    after_reset = gymnasiums.step(actions)[0]  # Gymnasium draws the same reset states one step later
    np.testing.assert_array_equal(observations[ended], after_reset[ended])
    np.testing.assert_array_equal(observations[~ended], expected[~ended])


# ---------------------------------------------------------------- action masks for MaskablePPO


class MaskedCartPole(SameStepCartPoleVectorEnv):
    """A native vector env with its own ``action_masks()``: sub-env ``i`` may only push ``i % 2``."""

    def action_masks(self) -> np.ndarray:
        masks = np.zeros((self.num_envs, 2), dtype=bool)
        masks[np.arange(self.num_envs), np.arange(self.num_envs) % 2] = True
        return masks


def test_masks_come_from_the_vector_envs_own_action_masks_in_one_call():
    adapter = VecNormalize(VectorEnvAdapter(MaskedCartPole(num_envs=3)))
    adapter.reset()
    assert is_masking_supported(adapter)
    np.testing.assert_array_equal(get_action_masks(adapter), [[True, False], [False, True], [True, False]])
    np.testing.assert_array_equal(adapter.env_method("action_masks", indices=[1, 2]), [[False, True], [True, False]])


class InfoMaskedCartPole(SameStepCartPoleVectorEnv):
    """Masks in the reset info only: sub-env 0 has no valid action, 1 only action 1, 2 reports none."""

    def reset(self, **kwargs):
        observations, _ = super().reset(**kwargs)
        masks = np.array([[0, 0], [0, 1], [0, 0]], dtype=np.int8)
        return observations, {"action_mask": masks, "_action_mask": np.array([True, True, False])}


def test_info_masks_with_nothing_valid_or_absent_allow_every_action():
    adapter = VectorEnvAdapter(InfoMaskedCartPole(num_envs=3))
    adapter.reset()
    np.testing.assert_array_equal(adapter.action_masks(), [[True, True], [False, True], [True, True]])


@pytest.mark.parametrize("mode", ["sync", "vector_entry_point"])
def test_maskable_ppo_learns_on_it_never_choosing_a_masked_action_with_vec_normalize_on_top(mode):
    config = {"horizon": 20, "invalid_action": "raise"}  # a masked action would raise in its sub-env
    vec_env = VecNormalize(VecMonitor(make_adapter(LANDMARK_ID, 4, config, mode)), norm_reward=False)
    vec_env.seed(0)
    model = MaskablePPO("MlpPolicy", vec_env, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(256)
    assert model.num_timesteps == 256 and len(model.ep_info_buffer) == 4 * 256 // (4 * 20)
    assert vec_env.obs_rms.count > 256
    vec_env.close()


# ---------------------------------------------------------------- sub-env access


def test_sync_sub_envs_are_reached_through_gymnasiums_get_attr_set_attr_and_call():
    adapter = make_adapter("CartPole-v1", 3, {}, info_keywords=())
    assert adapter.get_attr("render_mode") == [None] * 3
    assert adapter.get_attr("spec", indices=[2])[0].id == "CartPole-v1"
    adapter.set_attr("marker", 4.5)
    assert adapter.get_attr("marker") == [4.5] * 3 and adapter.has_attr("marker") and not adapter.has_attr("nothing")
    assert [space.n for space in adapter.env_method("get_wrapper_attr", "action_space")] == [2, 2, 2]
    assert adapter.env_is_wrapped(gym.wrappers.TimeLimit) == [True] * 3
    with pytest.raises(ValueError, match=r"set_attr\('marker'\) of a Gymnasium vector env acts on every sub-env"):
        adapter.set_attr("marker", 1.0, indices=[0])
    with pytest.raises(ValueError, match=r"env_method\('close'\) of a Gymnasium vector env acts on every sub-env"):
        adapter.env_method("close", indices=1)
    with pytest.raises(ValueError, match=r"sub-env indices \[3\] are outside 0..2"):
        adapter.get_attr("spec", indices=[0, 3])


def test_a_native_vector_env_has_no_sub_env_objects_to_reach():
    adapter = VectorEnvAdapter(SameStepCartPoleVectorEnv(num_envs=2))
    assert adapter.env_is_wrapped(gym.wrappers.TimeLimit) == [False, False]
    message = "SameStepCartPoleVectorEnv is a native vector env without sub-env objects"
    with pytest.raises(AttributeError, match=f"{message}: it has no per-sub-env attribute 'gravity'"):
        adapter.get_attr("gravity")
    assert not adapter.has_attr("gravity")
    with pytest.raises(ValueError, match=f"{message}: it has no per-sub-env attribute 'gravity'"):
        adapter.set_attr("gravity", 1.0)
    with pytest.raises(ValueError, match=f"{message}: it has no per-sub-env method 'render'.*vector_env.render"):
        adapter.env_method("render")


def test_images_of_every_sub_env_are_tiled_by_sb3():
    adapter = VectorEnvAdapter(
        gym.make_vec("CartPole-v1", 2, vectorization_mode="sync", vector_kwargs=SAME_STEP, render_mode="rgb_array")
    )
    adapter.reset()
    frames = adapter.get_images()
    assert len(frames) == 2 and frames[0].shape == (400, 600, 3)
    assert adapter.render(mode="rgb_array").shape == (800, 600, 3)
    adapter.close()


def test_async_sub_envs_in_worker_processes_have_unknown_wrappers():
    vector_env = gym.make_vec("CartPole-v1", 2, vectorization_mode="async", vector_kwargs=SAME_STEP)
    adapter = VectorEnvAdapter(vector_env)
    try:
        assert adapter.get_attr("spec")[1].id == "CartPole-v1"
        with pytest.raises(ValueError, match="AsyncVectorEnv keeps its sub-envs in worker processes"):
            adapter.env_is_wrapped(gym.wrappers.TimeLimit)
    finally:
        adapter.close()


# ---------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "make, mode",
    [
        (lambda: gym.make_vec("CartPole-v1", 2, vectorization_mode="sync"), "NextStep"),
        (lambda: CartPoleVectorEnv(num_envs=2), "NextStep"),
        (
            lambda: gym.make_vec(LANDMARK_ID, 2, vectorization_mode="vector_entry_point", **NEXT_STEP),
            "NextStep",
        ),
        (lambda: gym.make_vec(LANDMARK_ID, 2, vectorization_mode="sync", vector_kwargs=DISABLED), "Disabled"),
    ],
    ids=["sync", "cartpole-vector", "native-landmarks", "disabled"],
)
def test_another_autoreset_mode_is_refused_saying_how_to_ask_for_same_step(make, mode):
    vector_env = make()
    with pytest.raises(ValueError, match=f"metadata\\['autoreset_mode'\\] = <AutoresetMode.* '{mode}'>") as error:
        VectorEnvAdapter(vector_env)
    assert "vector_kwargs={'autoreset_mode': AutoresetMode.SAME_STEP}" in str(error.value)
    assert "gym.make_vec(env_id, num_envs=N, autoreset_mode=AutoresetMode.SAME_STEP)" in str(error.value)
    vector_env.close()


def test_a_single_env_is_not_a_vector_env():
    with pytest.raises(ValueError, match="VectorEnvAdapter wraps a gymnasium.vector.VectorEnv, got TimeLimit"):
        VectorEnvAdapter(gym.make("CartPole-v1"))


class SameStepInName(CartPoleVectorEnv):
    """Declares SAME_STEP but resets at the next step, without ``final_obs``."""

    metadata = {**CartPoleVectorEnv.metadata, "autoreset_mode": AutoresetMode.SAME_STEP}


class WrongMasks(SameStepCartPoleVectorEnv):
    def action_masks(self) -> np.ndarray:
        return np.ones((self.num_envs, 3), dtype=bool)


def test_a_vector_env_breaking_same_step_or_the_mask_shape_is_named():
    adapter = VectorEnvAdapter(SameStepInName(num_envs=2))
    adapter.reset()
    with pytest.raises(ValueError, match=r"sub-env \d of SameStepInName ended its episode but the step's info has no"):
        for _ in range(200):
            adapter.step(np.ones(2, dtype=np.int64))
    adapter = VectorEnvAdapter(WrongMasks(num_envs=2))
    with pytest.raises(ValueError, match=r"action_masks\(\) of WrongMasks has shape \(2, 3\), expected \(2, 2\)"):
        adapter.action_masks()


def test_an_info_keyword_missing_from_the_final_info_is_named():
    adapter = make_adapter(LANDMARK_ID, 2, {"horizon": 3}, info_keywords=("success",))
    adapter.reset()
    adapter.step(np.zeros(2, dtype=np.int64))
    adapter.step(np.zeros(2, dtype=np.int64))
    with pytest.raises(ValueError, match=r"info keyword 'success' is not in the final info of sub-env 0 .*'true_pose'"):
        adapter.step(np.zeros(2, dtype=np.int64))
