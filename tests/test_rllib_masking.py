"""The masked observations RLlib trains on carry each env's own action mask (no Ray needed)."""

import gymnasium as gym
import numpy as np
import pytest

from agents.rllib_masking import (
    ACTION_MASK,
    OBSERVATION,
    MaskedObservations,
    MaskedVectorObservations,
    mask_observation,
)

# RLlib: slow; `pytest -m "not slow"` leaves it out while developing
pytestmark = pytest.mark.slow

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


def test_no_valid_action_or_no_mask_means_every_action_as_maskable_ppo_takes_it():
    np.testing.assert_array_equal(mask_observation(np.zeros(4, dtype=np.int8), 4), np.ones(4))
    np.testing.assert_array_equal(mask_observation(None, 3), np.ones(3))
    np.testing.assert_array_equal(mask_observation([0, 1, 1], 3), [0.0, 1.0, 1.0])


def test_a_continuous_action_space_is_refused():
    with pytest.raises(ValueError, match="MaskedObservations needs a Discrete action space"):
        MaskedObservations(gym.make("Pendulum-v1"))


def test_a_masked_native_vector_env_equals_its_masked_single_envs_copy_for_copy():
    vector = MaskedVectorObservations(gym.make_vec(LANDMARK_ID, 3, horizon=20))
    singles = [MaskedObservations(gym.make(LANDMARK_ID, horizon=20)) for _ in range(3)]
    observations, _ = vector.reset(seed=7)
    single_observations = [env.reset(seed=7 + i)[0] for i, env in enumerate(singles)]
    assert vector.single_observation_space == singles[0].observation_space
    for _ in range(20):
        assert vector.observation_space.contains(observations)
        for i, single in enumerate(single_observations):
            for key in (OBSERVATION, ACTION_MASK):
                np.testing.assert_allclose(observations[key][i], single[key], rtol=0, atol=1e-9)
        actions = np.array([int(np.flatnonzero(mask)[0]) for mask in observations[ACTION_MASK]])
        observations, *_ = vector.step(actions)
        single_observations = [env.step(int(action))[0] for env, action in zip(singles, actions)]
