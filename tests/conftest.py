"""Shared test setup.

- pygame must never open a real window in tests: select SDL's dummy video driver
  before anything imports pygame.
- ``spawned_reset_observation`` runs in a *spawned* child process. It lives here,
  not in ``test_envs.py``, because unpickling it in the child imports its module:
  this module deliberately does not import ``infonav_gym``, so the child proves that
  ``gym.make("infonav_gym:...")`` imports and registers the package by itself.
"""

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import sys  # noqa: E402

import pytest  # noqa: E402


def pytest_configure(config):
    config.addinivalue_line("markers", "render: needs infonav_gym.rendering (pygame)")


def spawned_reset_observation(seed: int = 3) -> tuple[bool, list[float]]:
    """In a fresh interpreter: make the env through the ``module:`` prefix, reset, return the observation.

    Also returns whether ``infonav_gym`` had already been imported before ``gym.make``.
    """
    imported_before = "infonav_gym" in sys.modules
    import gymnasium as gym

    env = gym.make("infonav_gym:infonav/LandmarkSelection-v0")
    observation, _ = env.reset(seed=seed)
    env.close()
    return imported_before, observation.tolist()


@pytest.fixture
def spawned_reset():
    return spawned_reset_observation
