"""``SensorSelectionVectorEnv``: the N = 1 env's numbers in each sub-env through autoresets, per-copy frames, infos.

The shared vector-env checks (API, seeding, Gymnasium's sync vectorization, bad input) run on it from
``test_vector_envs.py``; the single env's behaviour (entropy, gains, bandwidth) is in ``test_sensor_selection.py``.
"""

from __future__ import annotations

import numpy as np
import pytest
import vector_env_checks
from gymnasium.vector import AutoresetMode
from skimage.measure import shannon_entropy

import infonav_gym  # noqa: F401
from infonav_gym.envs.sensor_selection import IDLE_ACTION, SENSORS, SensorSelectionVectorEnv

ENV_ID = "infonav/SensorSelection-v0"
SMALL_FRAMES = {  # quick frames; the buffer holds 3 LADAR frames, and the credit still runs out
    "ladar_rows": 8,
    "ladar_columns": 45,
    "camera_rows": 30,
    "camera_columns": 40,
    "bandwidth_bytes_per_step": 500,
    "bandwidth_buffer_bytes": 2200,
}


def _greedy_or_any(rng: np.random.Generator, info: dict) -> np.ndarray:
    """Half the sub-envs take their largest estimate, the others any action (a masked one is a no-op)."""
    gains = info["action_information_gain"]
    best, blind = gains.argmax(axis=1), rng.integers(0, gains.shape[1], len(gains))
    return np.where(rng.random(len(gains)) < 0.5, best, blind)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("seed", [0, 9])
def test_sub_envs_equal_the_single_env_through_autoresets(mode, seed):
    ended = vector_env_checks.run_in_lockstep(ENV_ID, 3, seed, 16, _greedy_or_any, mode, horizon=6, **SMALL_FRAMES)
    assert ended == (0, 6)


def test_sub_envs_equal_the_single_env_with_default_frames_and_negentropy():
    config = {"horizon": 4, "image_information": "negentropy", "n_pan_sectors": 2}
    assert vector_env_checks.run_in_lockstep(ENV_ID, 2, 3, 5, _greedy_or_any, **config) == (0, 2)


def test_each_copy_pays_for_its_own_frames_and_reports_its_sensor():
    env = SensorSelectionVectorEnv(num_envs=4, horizon=20, **SMALL_FRAMES)
    _, info = env.reset(seed=5)
    sensors = env.sensors
    credit = np.full(4, 2200)
    for actions in ([1, 4, IDLE_ACTION, 6], [2, IDLE_ACTION, 3, 5], [3, 3, 3, 3]):
        actions = np.array(actions)
        valid = info["action_mask"][np.arange(4), actions].astype(bool)
        _, rewards, _, _, info = env.step(actions)
        indices, pans = sensors.options(np.where(valid, actions, -1))
        np.testing.assert_array_equal(info["sensor"], indices)
        np.testing.assert_array_equal(info["pan_rad"], pans)
        spent = np.array([sensors.frame_bytes[SENSORS[index]] if index >= 0 else 0 for index in indices])
        credit = np.minimum(credit - spent + 500, 2200)
        np.testing.assert_array_equal(info["bandwidth_credit_bytes"], credit)
        np.testing.assert_array_equal(rewards > 0, indices >= 0)  # a frame's entropy is > 0 (noise)
        np.testing.assert_array_equal(info["image_entropy"], rewards)
    assert not info["action_mask"][:, 1:].all(), "the credit never ran out"


def test_sub_env_0s_last_image_is_the_frame_it_was_rewarded_for():
    env = SensorSelectionVectorEnv(num_envs=2, **SMALL_FRAMES)
    env.reset(seed=1)
    _, rewards, _, _, info = env.step(np.array([4, 1]))
    image = env.last_image
    assert image.shape == (30, 40) and image.dtype == np.uint8
    assert rewards[0] == pytest.approx(shannon_entropy(image, base=np.e), abs=1e-12)
    env.step(np.array([IDLE_ACTION, 1]))
    assert env.last_image is None
