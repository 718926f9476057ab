"""``infonav/SensorSelection-v0``: image information, the greedy estimate, the bandwidth budget, config errors.

The env contract (checkers, determinism, pickle, subprocess) is in ``test_envs.py``.
"""

import math

import gymnasium as gym
import numpy as np
import pytest
from skimage.measure import shannon_entropy

import infonav_gym  # noqa: F401
from agents import GreedyEntropyAgent, RandomAgent
from infonav_gym.envs.sensor_selection import IDLE_ACTION, MAX_IMAGE_ENTROPY, SENSORS
from infonav_gym.envs.vector_infos import reward_terms_of

SENSOR_ID = "infonav/SensorSelection-v0"


def make(**config):
    return gym.make(SENSOR_ID, **config).unwrapped


def episode_return(env, agent, seed: int) -> float:
    observation, info = env.reset(seed=seed)
    agent.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        observation, reward, terminated, truncated, info = env.step(agent.act(observation, info))
        total += reward
        done = terminated or truncated
    return total


def test_greedy_beats_random_in_cumulative_information_on_every_one_of_20_seeds():
    env = make()
    greedy = [episode_return(env, GreedyEntropyAgent(), seed) for seed in range(20)]
    random = [episode_return(env, RandomAgent(env.action_space.n), seed) for seed in range(20)]
    margins = np.subtract(greedy, random)
    assert np.all(margins > 0), f"greedy lost on seeds {np.flatnonzero(margins <= 0).tolist()}: {margins}"


@pytest.mark.parametrize("convention", ["entropy", "negentropy"])
def test_reward_is_the_histogram_entropy_of_the_acquired_image_as_scikit_image_computes_it(convention):
    env = make(image_information=convention, bandwidth_bytes_per_step=10**6, bandwidth_buffer_bytes=10**6)
    env.reset(seed=3)
    for action in range(1, env.action_space.n):
        _, reward, _, _, info = env.step(action)
        image = env.last_image
        expected_shape = (
            (env.vector.sensors.ladar.rows, env.vector.sensors.ladar.columns)
            if SENSORS[info["sensor"]] == "ladar"
            else (120, 160)
        )
        assert image.dtype == np.uint8 and image.shape == expected_shape
        entropy = shannon_entropy(image, base=np.e)
        assert info["image_entropy"] == pytest.approx(entropy, abs=1e-12)
        expected = entropy if convention == "entropy" else math.log(256) - entropy
        assert reward == pytest.approx(expected, abs=1e-12)
        assert reward_terms_of(info) == {"image_information": reward}
    env.step(IDLE_ACTION)
    assert env.last_image is None


def test_the_gain_is_the_last_value_measured_and_ln_256_for_options_never_acquired():
    env = make(bandwidth_bytes_per_step=10**6, bandwidth_buffer_bytes=10**6)
    _, info = env.reset(seed=4)
    assert info["action_information_gain"][IDLE_ACTION] == 0.0
    assert np.all(info["action_information_gain"][1:] == MAX_IMAGE_ENTROPY)
    measured = {}
    for step, action in enumerate([2, 5, 2, 6]):
        observation, reward, _, _, info = env.step(action)
        measured[action] = (reward, step)  # acquired during step ``step``: one step old after it
        for option, (value, acquired_step) in measured.items():
            assert info["action_information_gain"][option] == value
            row = observation[3 * (option - 1) : 3 * option]
            age = (step + 1 - acquired_step) / env.config["horizon"]
            assert row.tolist() == pytest.approx([1.0, value, age], abs=1e-6)
        never = [a for a in range(1, env.action_space.n) if a not in measured]
        assert np.all(info["action_information_gain"][never] == MAX_IMAGE_ENTROPY)
        assert np.all(observation[[3 * (a - 1) for a in never]] == 0.0)  # never acquired


def test_bandwidth_credit_pays_for_frames_by_size_and_masks_what_it_cannot_cover():
    env = make(bandwidth_bytes_per_step=5000, bandwidth_buffer_bytes=40000, n_pan_sectors=2)
    assert env.vector.sensors.frame_bytes == {"ladar": 2 * 32 * 180, "camera": 120 * 160}
    ladar_actions, camera_actions = [1, 2], [3, 4]
    _, info = env.reset(seed=0)
    credit, affordable_sets = 40000, set()
    for _ in range(12):
        assert info["bandwidth_credit_bytes"] == credit
        mask = info["action_mask"]
        assert mask[IDLE_ACTION] == 1
        assert np.all(mask[ladar_actions] == (credit >= 11520)) and np.all(mask[camera_actions] == (credit >= 19200))
        affordable_sets.add((bool(mask[1]), bool(mask[3])))
        action = camera_actions[0] if mask[camera_actions[0]] else ladar_actions[1] if mask[1] else IDLE_ACTION
        cost = {1: 11520, 2: 11520, 3: 19200, 4: 19200}.get(action, 0)
        observation, _, _, _, info = env.step(action)
        credit = min(credit - cost + 5000, 40000)
        assert observation[-4] == pytest.approx(credit / 40000)
        assert observation[-3:-1].tolist() == [credit >= 11520, credit >= 19200]
    assert affordable_sets == {(True, True), (True, False), (False, False)}, "the credit never ran down"


def test_frame_sizes_follow_the_image_config():
    env = make(ladar_rows=16, ladar_columns=90, camera_rows=60, camera_columns=80)
    assert env.vector.sensors.frame_bytes == {"ladar": 2 * 16 * 90, "camera": 60 * 80}
    env.reset(seed=1)
    env.step(1)
    assert env.last_image.shape == (16, 90)
    env.step(4)
    assert env.last_image.shape == (60, 80)


@pytest.mark.parametrize("n_pan_sectors, span_deg", [(1, 160.0), (3, 160.0), (5, 120.0)])
def test_pan_sectors_spread_evenly_from_left_to_right(n_pan_sectors, span_deg):
    env = make(n_pan_sectors=n_pan_sectors, pan_span_rad=math.radians(span_deg))
    assert env.action_space.n == 1 + 2 * n_pan_sectors
    sensors = env.vector.sensors
    pans = [sensors.option(a)[1] for a in range(1, 1 + n_pan_sectors)]
    assert [sensors.option(a)[0] for a in range(1, env.action_space.n)] == ["ladar"] * n_pan_sectors + [
        "camera"
    ] * n_pan_sectors
    expected = [0.0] if n_pan_sectors == 1 else np.linspace(span_deg / 2, -span_deg / 2, n_pan_sectors)
    assert np.degrees(pans) == pytest.approx(expected)


def test_pan_turns_the_view_the_left_image_is_the_image_seen_from_a_heading_turned_left():
    env = make()
    env.reset(seed=2)
    vector, sensors = env.vector, env.vector.sensors
    pan, pose, terrain = sensors.pan_angles_rad[0], vector.true_poses[0], vector.terrain(0)
    panned = sensors.acquire(terrain, pose, np.random.default_rng(7), "camera", pan)
    turned = sensors.camera.capture(terrain, pose + [0.0, 0.0, pan], np.random.default_rng(7))
    assert np.array_equal(panned, turned)


@pytest.mark.parametrize(
    "key, value",
    [
        ("ladar_rows", 0),
        ("ladar_columns", 0),
        ("camera_rows", 0),
        ("camera_columns", -4),
        ("ladar_horizontal_fov_rad", 0.0),
        ("ladar_vertical_fov_rad", math.pi),
        ("camera_horizontal_fov_rad", -0.1),
        ("camera_horizontal_fov_rad", math.radians(180.0)),
        ("ladar_range_std_m", -0.01),
        ("camera_noise_std", -1.0),
        ("ladar_max_range_m", 0.0),
        ("n_pan_sectors", 0),
        ("bandwidth_bytes_per_step", 0),
        ("bandwidth_buffer_bytes", 1000),
        ("pan_span_rad", -1.0),
    ],
)
def test_bad_config_raises_value_error_naming_the_key(key, value):
    with pytest.raises(ValueError, match=f"'{key}'"):
        gym.make(SENSOR_ID, **{key: value})
