"""Sensor models: noise statistics against their stated covariances, coverage, availability, bad input."""

import math

import numpy as np
import pytest
from scipy import stats

from infonav_gym.config import ParameterError
from infonav_gym.estimation import relative_pose
from infonav_gym.multi.team import KNOWN_SENSORS, RobotSuite, parse_outages, parse_suites
from infonav_gym.sensors import (
    RELATIVE_POSE_SENSORS,
    Camera,
    GPSSensor,
    Ladar,
    OdometrySensor,
    RangeBearingSensor,
    RelativePoseSensor,
)

N_SAMPLES = 20000


def assert_noise_matches(errors: np.ndarray, covariance: np.ndarray) -> None:
    """Zero mean and the stated covariance: the NEES of the samples follows chi-square(dim)."""
    dim = covariance.shape[0]
    mean_nees = np.mean(np.einsum("ni,ij,nj->n", errors, np.linalg.inv(covariance), errors))
    low = stats.chi2.ppf(0.0005, dim * len(errors)) / len(errors)
    high = stats.chi2.ppf(0.9995, dim * len(errors)) / len(errors)
    assert low <= mean_nees <= high, f"mean NEES {mean_nees:.4f} outside [{low:.4f}, {high:.4f}]"
    standard_error = np.sqrt(np.diag(covariance) / len(errors))
    assert np.all(np.abs(errors.mean(axis=0)) < 4 * standard_error)


def test_gps_fix_noise_has_the_stated_covariance():
    gps, rng = GPSSensor(position_std_m=0.3), np.random.default_rng(0)
    errors = np.array([gps.measure([2.0, -1.0], rng) for _ in range(N_SAMPLES)]) - [2.0, -1.0]
    assert_noise_matches(errors, gps.noise_covariance())


def test_gps_drops_out_on_its_schedule_and_in_denied_zones():
    gps = GPSSensor(outages=((21.0, 30.0), (50.0, 1e9)))
    assert gps.available(20.99) and not gps.available(21.0) and not gps.available(29.9) and gps.available(30.0)
    assert not gps.available(60.0)
    assert not GPSSensor().available(0.0, in_denied_zone=True)


@pytest.mark.parametrize("bad", [{"position_std_m": 0.0}, {"outages": ((5.0, 5.0),)}, {"outages": ((1.0,),)}])
def test_gps_rejects_bad_parameters(bad):
    with pytest.raises(ValueError, match="GPS"):
        GPSSensor(**bad)


@pytest.mark.parametrize("name", sorted(RELATIVE_POSE_SENSORS))
def test_relative_pose_noise_has_the_stated_covariance(name):
    sensor, rng = RELATIVE_POSE_SENSORS[name], np.random.default_rng(1)
    observer, target = np.array([1.0, 2.0, 0.3]), np.array([6.0, 3.0, -2.0])
    truth = relative_pose(observer, target)[0]
    samples = np.array([sensor.measure(observer, target, rng) for _ in range(N_SAMPLES)])
    errors = samples - truth
    errors[:, 1:] = (errors[:, 1:] + np.pi) % (2 * np.pi) - np.pi
    assert_noise_matches(errors, sensor.noise_covariance(truth[0])[0])


def test_vision_is_narrow_and_noisier_with_distance_laser_sees_all_around():
    laser, vision = RELATIVE_POSE_SENSORS["laser"], RELATIVE_POSE_SENSORS["vision"]
    geometry = np.array([[5.0, 0.0, 0.0], [5.0, math.radians(40), 0.0], [5.0, math.pi - 0.1, 0.0], [20.0, 0.0, 0.0]])
    np.testing.assert_array_equal(vision.in_coverage(geometry), [True, False, False, False])
    np.testing.assert_array_equal(laser.in_coverage(geometry), [True, True, True, True])
    near, far = vision.noise_covariance([2.0, 10.0])
    assert np.all(np.diag(far) >= np.diag(near)) and far[0, 0] > near[0, 0] and far[2, 2] > near[2, 2]
    assert laser.max_range_m > vision.max_range_m


def test_relative_pose_sensor_rejects_bad_heading_noise():
    with pytest.raises(ValueError, match="heading_std_rad"):
        RelativePoseSensor(RangeBearingSensor(), heading_std_rad=0.0)


def test_team_suites_parse_names_strings_and_defaults():
    assert parse_suites(["gps+laser", ("vision",), "odometry"], 3, "team_field") == (
        RobotSuite(gps=True, relative_sensor="laser"),
        RobotSuite(gps=False, relative_sensor="vision"),
        RobotSuite(gps=False, relative_sensor=None),
    )
    default = parse_suites(None, 5, "team_field")
    assert default[0] == default[4] == RobotSuite(True, "laser") and default[3] == RobotSuite(False, "vision")


def test_team_suites_reject_unknown_sensors_listing_the_known_ones():
    with pytest.raises(ValueError, match="unknown sensor 'sonar' for robot_1") as error:
        parse_suites(["gps", "sonar"], 2, "team_field")
    assert all(name in str(error.value) for name in KNOWN_SENSORS)
    with pytest.raises(ValueError, match="one relative-pose sensor"):
        parse_suites(["laser+vision", "gps"], 2, "team_field")
    with pytest.raises(ValueError, match="one sensor suite per robot"):
        parse_suites(["gps"], 2, "team_field")


def test_gps_outages_parse_per_robot_and_reject_bad_triples():
    assert parse_outages([(1, 21, 30), [1, 40.0, 50.0]], 3) == ((), ((21.0, 30.0), (40.0, 50.0)), ())
    for bad, message in (([(3, 0, 1)],), "robots 0..2"), (([(0, 5, 1)],), "start_s < end_s"), (([(0, 5)],), "robot"):
        with pytest.raises(ValueError, match=message):
            parse_outages(bad[0], 3)


@pytest.mark.parametrize(
    ("sensor", "field", "value", "allowed"),
    [
        (RangeBearingSensor, "range_std_m", math.inf, "[0.0001, 100] m"),
        (RangeBearingSensor, "range_std_m", 1e-9, "[0.0001, 100] m"),
        (RangeBearingSensor, "range_std_per_m", math.nan, "[0, 1] m/m"),
        (RangeBearingSensor, "bearing_std_rad", 0.0, "[1e-05, 3.14159] rad"),
        (RangeBearingSensor, "max_range_m", 1e308, "(0, 1000] m"),
        (RangeBearingSensor, "fov_rad", 7.0, "(0, 6.28319] rad"),
        (OdometrySensor, "speed_std_mps", math.inf, "(0, 10] m/s"),
        (OdometrySensor, "turn_rate_std_rps", 0.0, "(0, 10] rad/s"),
        (GPSSensor, "position_std_m", 1e-12, "[0.001, 100] m"),
        (Ladar, "range_std_m", math.inf, "[0, 10] m"),
        (Ladar, "rows", 10**6, "an integer in [1, 1080]"),
        (Ladar, "columns", 2.0, "an integer in [1, 1920]"),
        (Ladar, "mount_height_m", 1e12, "(0, 100] m"),
        (Camera, "noise_std", math.inf, "[0, 1000] gray levels"),
        (Camera, "pan_rad", 1e12, "[-6.28319, 6.28319] rad"),
    ],
)
def test_each_sensor_checks_its_own_parameters_naming_the_field_and_its_range(sensor, field, value, allowed):
    with pytest.raises(ParameterError) as error:
        sensor(**{field: value})
    assert (error.value.parameter, error.value.value) == (field, value)
    assert f"{field} must be in {allowed}" in str(error.value) or f"{field} must be {allowed}" in str(error.value)


def test_relative_pose_sensor_checks_its_heading_noise_range():
    with pytest.raises(ParameterError, match=r"heading_std_per_m must be in \[0, 0.1\] rad/m, got inf"):
        RelativePoseSensor(RangeBearingSensor(), heading_std_rad=0.01, heading_std_per_m=math.inf)


@pytest.mark.parametrize("spec", [0, "gps", 1.5, None])
def test_gps_outages_must_be_a_sequence_of_triples(spec):
    with pytest.raises(ValueError, match="gps_outages must be a sequence of"):
        parse_outages(spec, 3)


def test_batched_measurements_given_the_noise_equal_the_single_draws():
    rng = np.random.default_rng(3)
    sensor, odometry = RangeBearingSensor(range_std_per_m=0.05), OdometrySensor()
    poses = np.column_stack([rng.uniform(-10, 10, (50, 2)), rng.uniform(-math.pi, math.pi, 50)])
    landmarks, controls = rng.uniform(-10, 10, (50, 2)), rng.uniform(-1, 1, (50, 2))
    noise = np.random.default_rng(9).standard_normal((50, 2))
    draws = np.random.default_rng(9)
    single = [sensor.measure(pose, landmark, draws) for pose, landmark in zip(poses, landmarks)]
    np.testing.assert_allclose(sensor.measure_with_noise(poses, landmarks, noise), single, rtol=0, atol=1e-12)
    draws = np.random.default_rng(9)
    single = [odometry.measure(control, draws) for control in controls]
    np.testing.assert_array_equal(odometry.measure_with_noise(controls, noise), single)
