"""``NoiseStreams`` hands each copy the numbers its generator gives one call at a time."""

import numpy as np
import pytest

from infonav_gym.envs.noise_streams import NoiseStreams


def test_each_copy_gets_its_generators_draws_in_order_through_block_refills_and_restarts():
    n_copies, width = 5, 3
    streams = NoiseStreams(n_copies, width, block_draws=4)
    references = [np.random.default_rng(seed) for seed in range(n_copies)]
    for copy in range(n_copies):
        streams.restart(copy, np.random.default_rng(copy))
    pattern = np.random.default_rng(99)
    for step in range(40):
        copies = np.flatnonzero(pattern.random(n_copies) < 0.6)
        if step == 20:  # copy 2 starts a new episode with a new generator
            streams.restart(2, np.random.default_rng(1000))
            references[2] = np.random.default_rng(1000)
        expected = np.array([references[copy].standard_normal(width) for copy in copies.tolist()]).reshape(-1, width)
        np.testing.assert_array_equal(streams.take(copies), expected)


def test_a_copy_without_a_generator_is_a_clear_error():
    streams = NoiseStreams(2, 2)
    streams.restart(0, np.random.default_rng(0))
    with pytest.raises(RuntimeError, match="copy 1 has no generator yet"):
        streams.take(np.arange(2))
