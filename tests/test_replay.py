"""Replay building blocks: the replay clock and dead reckoning; the longest stretch a replay plays."""

import numpy as np
import pytest

from infonav_gym.datasets.timeline import Timeline, _tick_means, dead_reckoning
from infonav_gym.estimation.ekf import PoseEKF
from infonav_gym.experiments.replay import ReplayConfig
from infonav_gym.experiments.replay.run import longest_run


def test_tick_means_integrate_held_odometry_exactly():
    odometry = np.array([[10.0, 1.0, 0.5], [10.03, 2.0, -0.5], [10.05, 0.0, 0.0]])
    means = _tick_means(odometry, np.array([9.98, 10.0, 10.02, 10.04, 10.06]))
    np.testing.assert_allclose(means[:, 0], [0.0, 1.0, 1.5, 1.0], atol=1e-12)  # 0 before the first reading
    np.testing.assert_allclose(means[:, 1], [0.0, 0.5, 0.0, -0.25], atol=1e-12)


def test_dead_reckoning_matches_the_filter_prediction():
    rng = np.random.default_rng(0)
    controls = rng.uniform([0.0, -0.5], [0.3, 0.5], size=(50, 1, 2))
    timeline = Timeline(start_time=0.0, dt=0.02, controls=controls, events=[np.zeros((0, 6))])
    ekf = PoseEKF([1.0, 2.0, 3.0], np.eye(3) * 0.01)
    for control in controls[:, 0]:
        ekf.predict(control, 0.02, np.eye(2) * 1e-4)
    np.testing.assert_allclose(dead_reckoning(np.array([[1.0, 2.0, 3.0]]), timeline)[-1, 0], ekf.x, atol=1e-12)


@pytest.mark.parametrize(
    ("usable", "expected"),
    [([1, 1, 0, 1, 1, 1, 0], (3, 3)), ([0, 0], (0, 0)), ([1, 1, 0, 1, 1], (0, 2)), ([1], (0, 1))],
)
def test_longest_run_is_the_first_longest_stretch(usable, expected):
    assert longest_run(np.array(usable, dtype=bool)) == expected


def test_config_rejects_unknown_policy_an_empty_outage_and_an_outage_without_teammates():
    with pytest.raises(ValueError, match="unknown policy 'oracle'"):
        ReplayConfig(policy="oracle")
    with pytest.raises(ValueError, match="outage must end after it starts"):
        ReplayConfig(cooperative=True, outage_robot=1, outage_start_s=5.0, outage_end_s=5.0)
    with pytest.raises(ValueError, match="an outage needs the cooperative replay"):
        ReplayConfig(outage_robot=1)
