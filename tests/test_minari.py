"""Minari's ``DataCollector`` records every single-agent env as it comes, infos included, and the dataset it writes
loads and recreates the env (issue 45: the ecosystem's offline-RL tools accept the envs)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import infonav_gym  # noqa: F401  (registers the envs)
from infonav_gym.envs.vector_infos import reward_terms_of
from infonav_gym.registry import GYMNASIUM, registered_envs

minari = pytest.importorskip("minari", reason="minari is not installed (the data extra)")
pytest.importorskip("jax", reason="Minari's DataCollector needs jax (the data extra)")

ENV_IDS = [entry.id for entry in registered_envs(GYMNASIUM)]
HORIZON = 6  # short episodes: a recording crosses a reset


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_data_collector_records_every_info_and_the_dataset_recreates_the_env(env_id, tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    collector = minari.DataCollector(gym.make(env_id, horizon=HORIZON), record_infos=True)
    _, info = collector.reset(seed=0)
    first_keys = set(info)
    rng = np.random.default_rng(0)
    steps = 2 * HORIZON + 2
    for _ in range(steps):
        valid = np.flatnonzero(info["action_mask"])
        _, _, terminated, truncated, info = collector.step(int(rng.choice(valid)) if valid.size else 0)
        assert set(info) == first_keys, "a step's info has other keys than the reset's"
        if terminated or truncated:
            _, info = collector.reset()
    dataset_id = f"infonav/{env_id.split('/')[-1].lower()}/random-v0"
    collector.create_dataset(dataset_id=dataset_id, algorithm_name="random")
    dataset = minari.load_dataset(dataset_id)
    assert dataset.total_steps == steps
    episode = next(dataset.iterate_episodes())
    assert set(episode.infos) == first_keys and len(reward_terms_of(episode.infos)) > 0
    assert type(dataset.recover_environment().unwrapped) is type(collector.unwrapped)
