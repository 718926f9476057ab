"""``NoiseStreams`` hands each copy the numbers its generator gives one call at a time."""

import numpy as np
import pytest

from infonav_gym.envs.noise_streams import NoiseStreams


def streams_and_references(n_copies: int, width: int, block_draws: int, steps: int, share: float):
    """Streams whose copy ``k`` draws from ``default_rng(k)``, a reference generator of each, and ``steps`` random
    draws of the copies that take (each in with probability ``share``)."""
    streams = NoiseStreams(n_copies, width, block_draws=block_draws)
    for copy in range(n_copies):
        streams.restart(copy, np.random.default_rng(copy))
    pattern = np.random.default_rng(99)
    takers = [np.flatnonzero(pattern.random(n_copies) < share) for _ in range(steps)]
    return streams, [np.random.default_rng(seed) for seed in range(n_copies)], takers


def test_each_copy_gets_its_generators_draws_in_order_through_block_refills_and_restarts():
    n_copies, width = 5, 3
    streams, references, takers = streams_and_references(n_copies, width, 4, steps=40, share=0.6)
    for step, copies in enumerate(takers):
        if step == 20:  # copy 2 starts a new episode with a new generator
            streams.restart(2, np.random.default_rng(1000))
            references[2] = np.random.default_rng(1000)
        expected = np.array([references[copy].standard_normal(width) for copy in copies.tolist()]).reshape(-1, width)
        np.testing.assert_array_equal(streams.take(copies), expected)


def test_take_many_gives_each_used_slot_its_copys_next_draw_in_slot_order_across_block_boundaries():
    n_copies, width, n_slots = 4, 2, 3
    streams, references, takers = streams_and_references(n_copies, width, 3, steps=30, share=0.7)
    for step, copies in enumerate(takers):
        used = (np.arange(len(copies) * n_slots).reshape(-1, n_slots) * (step + 1)) % 3 != 1  # 0 to 3 slots each
        expected = np.zeros((len(copies), n_slots, width))
        for row, copy in enumerate(copies.tolist()):
            expected[row, used[row]] = references[copy].standard_normal((used[row].sum(), width))
        np.testing.assert_array_equal(streams.take_many(copies, used), expected)
        if len(copies):  # one draw each, through take, continues the same streams
            expected = np.array([references[c].standard_normal(width) for c in copies.tolist()])
            np.testing.assert_array_equal(streams.take(copies), expected)


def test_a_copy_without_a_generator_is_a_clear_error():
    streams = NoiseStreams(2, 2)
    streams.restart(0, np.random.default_rng(0))
    with pytest.raises(RuntimeError, match="copy 1 has no generator yet"):
        streams.take(np.arange(2))
