"""``action_masks()`` on every single-agent env, as sb3-contrib's ``MaskablePPO`` finds and uses it."""

import gymnasium as gym
import numpy as np
import pytest
import torch
from sb3_contrib import MaskablePPO
from sb3_contrib.common.maskable.utils import get_action_masks, is_masking_supported
from stable_baselines3.common.vec_env import DummyVecEnv

import infonav_gym  # noqa: F401  (registers the envs)

SINGLE_AGENT_IDS = sorted(
    env_id
    for env_id, spec in gym.registry.items()
    if isinstance(spec.entry_point, str) and spec.entry_point.startswith("infonav_gym.")
)
BLIND = {"sensor_max_range_m": 0.01}  # LandmarkSelection sees no landmark: no action is valid


class ActionRecorder(gym.Wrapper):
    """Records each step's action with the mask the env offered before it."""

    def __init__(self, env):
        super().__init__(env)
        self.steps = []

    def reset(self, **kwargs):
        observation, info = self.env.reset(**kwargs)
        self._mask = info["action_mask"]
        return observation, info

    def step(self, action):
        self.steps.append((int(action), self._mask))
        observation, reward, terminated, truncated, info = self.env.step(action)
        self._mask = info["action_mask"]
        return observation, reward, terminated, truncated, info


def test_every_gymnasium_env_of_the_package_is_covered():
    assert len(SINGLE_AGENT_IDS) >= 4 and "infonav/LandmarkSelection-v0" in SINGLE_AGENT_IDS


@pytest.mark.parametrize("env_id", SINGLE_AGENT_IDS)
def test_action_masks_is_the_info_mask_as_bool_through_wrappers_and_vec_envs(env_id):
    env = gym.make(env_id)  # wrapped: TimeLimit, OrderEnforcing, PassiveEnvChecker
    vec_env = DummyVecEnv([lambda: gym.make(env_id)])
    assert is_masking_supported(env) and is_masking_supported(vec_env)
    _, info = env.reset(seed=0)
    vec_env.seed(0)
    vec_env.reset()
    rng = np.random.default_rng(0)
    for _ in range(20):
        masks = get_action_masks(env)
        assert masks.dtype == bool and masks.shape == (env.action_space.n,)
        if info["action_mask"].any():
            np.testing.assert_array_equal(masks, info["action_mask"].astype(bool))
        np.testing.assert_array_equal(get_action_masks(vec_env), masks[None])
        action = int(rng.choice(np.flatnonzero(masks)))
        _, _, terminated, truncated, info = env.step(action)
        vec_env.step(np.array([action]))
        if terminated or truncated:
            break


def test_action_masks_returns_a_copy():
    env = gym.make("infonav/LandmarkSelection-v0")
    env.reset(seed=0)
    masks = env.get_wrapper_attr("action_masks")()
    masks[:] = ~masks
    np.testing.assert_array_equal(env.get_wrapper_attr("action_masks")(), ~masks)


def test_action_masks_before_reset_raises():
    with pytest.raises(RuntimeError, match="reset"):
        gym.make("infonav/LandmarkSelection-v0").get_wrapper_attr("action_masks")()


@pytest.mark.parametrize("mode", ["noop", "raise"])
def test_when_no_action_is_valid_every_action_is_allowed_and_is_the_same_no_op(mode):
    env = gym.make("infonav/LandmarkSelection-v0", invalid_action=mode, **BLIND)
    _, info = env.reset(seed=0)
    assert not info["action_mask"].any()
    np.testing.assert_array_equal(env.get_wrapper_attr("action_masks")(), np.ones(env.action_space.n, dtype=bool))
    twin = gym.make("infonav/LandmarkSelection-v0", invalid_action=mode, **BLIND)
    twin.reset(seed=0)
    observation, reward, _, _, info = env.step(3)  # accepted even in "raise" mode: nothing else could be chosen
    twin_observation, twin_reward, *_ = twin.step(0)
    assert reward == twin_reward == 0.0 and info["invalid_action"] and info["chosen_action"] == -1
    np.testing.assert_array_equal(observation, twin_observation)


@pytest.mark.parametrize("env_id", SINGLE_AGENT_IDS)
def test_maskable_ppo_learns_out_of_the_box_and_never_takes_a_masked_action(env_id):
    recorder = ActionRecorder(gym.make(env_id))
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # small MLPs; the second core is not worth it
    try:
        model = MaskablePPO("MlpPolicy", recorder, n_steps=128, batch_size=64, n_epochs=1, seed=0, device="cpu")
        model.learn(256)
    finally:
        torch.set_num_threads(threads)
    assert len(recorder.steps) >= 256
    taken_masked = [(action, mask.tolist()) for action, mask in recorder.steps if mask.any() and not mask[action]]
    assert taken_masked == []
    assert len({action for action, _ in recorder.steps}) > 1  # the policy samples, it is not stuck on one action
