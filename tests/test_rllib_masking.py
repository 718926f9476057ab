"""The masked observations RLlib trains on carry each env's own action mask (no Ray needed)."""

import gymnasium as gym
import numpy as np
import pytest

from agents.rllib_masking import ACTION_MASK, OBSERVATION, MaskedObservations, MaskedParallelEnv, valid_actions
from infonav_gym.multi import cooperative_localization_v0

LANDMARK_ID = "infonav/LandmarkSelection-v0"


def test_a_masked_single_env_observes_its_action_masks_and_stays_in_its_space():
    plain, masked = gym.make(LANDMARK_ID), MaskedObservations(gym.make(LANDMARK_ID))
    observation, info = masked.reset(seed=4)
    plain_observation, _ = plain.reset(seed=4)
    partial = 0
    for _ in range(60):
        assert masked.observation_space.contains(observation)
        np.testing.assert_array_equal(observation[OBSERVATION], plain_observation)
        np.testing.assert_array_equal(observation[ACTION_MASK], masked.unwrapped.action_masks().astype(np.float32))
        partial += 0 < observation[ACTION_MASK].sum() < observation[ACTION_MASK].size
        action = int(np.flatnonzero(observation[ACTION_MASK])[-1])
        observation, *_ = masked.step(action)
        plain_observation, *_ = plain.step(action)
    assert partial > 0


def test_a_masked_team_env_observes_each_robots_info_mask():
    env = MaskedParallelEnv(cooperative_localization_v0.parallel_env(max_cycles=30))
    observations, infos = env.reset(seed=2)
    while env.agents:
        for agent, observation in observations.items():
            assert env.observation_space(agent).contains(observation)
            np.testing.assert_array_equal(observation[ACTION_MASK], infos[agent]["action_mask"].astype(np.float32))
        actions = {agent: int(np.flatnonzero(o[ACTION_MASK])[-1]) for agent, o in observations.items()}
        observations, _, _, _, infos = env.step(actions)


def test_no_valid_action_or_no_mask_means_every_action_as_maskable_ppo_takes_it():
    np.testing.assert_array_equal(valid_actions(np.zeros(4, dtype=np.int8), 4), np.ones(4))
    np.testing.assert_array_equal(valid_actions(None, 3), np.ones(3))
    np.testing.assert_array_equal(valid_actions([0, 1, 1], 3), [0.0, 1.0, 1.0])


def test_a_continuous_action_space_is_refused():
    with pytest.raises(ValueError, match="MaskedObservations needs a Discrete action space"):
        MaskedObservations(gym.make("Pendulum-v1"))
