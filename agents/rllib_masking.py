"""Action masks for RLlib, carried in the observation as ``{"observation", "action_mask"}`` (RLlib's new API stack
reads nothing from ``info``); applied by ``agents.rllib_module``. Needs no Ray."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import VectorWrapper
from gymnasium.vector.utils import batch_space

from agents.base import usable_mask

OBSERVATION, ACTION_MASK = "observation", "action_mask"
NORMALIZE_OBSERVATIONS = "normalize_observations"  # the model_config key of agents.rllib_module's normalization


def masked_space(observation_space: spaces.Box, n_actions: int) -> spaces.Dict:
    """The observation space of a masked env: its own observation and an ``n_actions`` float32 mask."""
    mask_space = spaces.Box(0.0, 1.0, (n_actions,), dtype=np.float32)
    return spaces.Dict({OBSERVATION: observation_space, ACTION_MASK: mask_space})


def mask_observation(mask, n_actions: int) -> np.ndarray:
    """The ``"action_mask"`` part: ``mask`` as float32 0 / 1 (``usable_mask``: all ones when none is valid)."""
    return usable_mask(mask, n_actions).astype(np.float32)


def mask_rows(masks) -> np.ndarray:
    """``action_masks()`` of copies (..., n) as ``"action_mask"`` parts: float32 0 / 1, all ones where none is valid."""
    masks = np.array(masks, dtype=np.float32)
    masks[~masks.any(axis=-1)] = 1.0
    return masks


class MaskedObservations(gym.Wrapper):
    """A Gymnasium env with a Discrete action space whose observations carry its action mask (see the module)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        if not isinstance(env.action_space, spaces.Discrete):
            raise ValueError(f"MaskedObservations needs a Discrete action space, got {env.action_space}")
        self.n_actions = int(env.action_space.n)
        self.observation_space = masked_space(env.observation_space, self.n_actions)

    def reset(self, **kwargs):
        observation, info = self.env.reset(**kwargs)
        return self._masked(observation, info), info

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        return self._masked(observation, info), reward, terminated, truncated, info

    def _masked(self, observation, info: dict) -> dict:
        own = getattr(self.env.unwrapped, "action_masks", None)
        mask = own() if callable(own) else info.get(ACTION_MASK)
        return {OBSERVATION: observation, ACTION_MASK: mask_observation(mask, self.n_actions)}


class MaskedVectorObservations(VectorWrapper):
    """A native vector env whose observations carry its ``action_masks()`` (N, K), for RLlib's env runners."""

    def __init__(self, env):
        super().__init__(env)
        self.n_actions = int(env.single_action_space.n)
        self.single_observation_space = masked_space(env.single_observation_space, self.n_actions)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)

    def reset(self, **kwargs):
        observations, info = self.env.reset(**kwargs)
        return self._masked(observations), info

    def step(self, actions):
        observations, rewards, terminated, truncated, info = self.env.step(actions)
        return self._masked(observations), rewards, terminated, truncated, info

    def _masked(self, observations) -> dict:
        return {OBSERVATION: observations, ACTION_MASK: mask_rows(self.env.unwrapped.action_masks())}
