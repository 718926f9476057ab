"""The config check helpers: intervals with finiteness, integer checks, and errors that name the config key."""

import math
import re

import numpy as np
import pytest

from infonav_gym.config import (
    Interval,
    ParameterError,
    check_arguments,
    check_integer,
    check_number,
    config_keys,
    from_config,
    stated_requirements,
)
from infonav_gym.sensors import RangeBearingSensor


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 1e308, True, "1.0", None, -0.5])
def test_check_number_refuses_non_finite_out_of_range_and_non_numbers(value):
    with pytest.raises(ParameterError) as error:
        check_number("Sensor", "gain", value, 0.0, 10.0, unit="m")
    assert str(error.value) == f"Sensor gain must be in [0, 10] m, got {value!r}"
    assert (error.value.owner, error.value.parameter, error.value.value) == ("Sensor", "gain", value)


def test_check_number_open_and_closed_bounds():
    check_number("Sensor", "gain", 0.0, 0.0, 1.0)
    check_number("Sensor", "gain", np.float32(1.0), 0.0, 1.0)
    with pytest.raises(ParameterError, match=r"in \(0, 1\), got 0.0"):
        check_number("Sensor", "gain", 0.0, 0.0, 1.0, open_low=True, open_high=True)
    with pytest.raises(ParameterError, match=r"in \(0, 1\), got 1.0"):
        check_number("Sensor", "gain", 1.0, 0.0, 1.0, open_low=True, open_high=True)


@pytest.mark.parametrize("value", [3.0, True, np.bool_(True), 10**12, -1, "3"])
def test_check_integer_refuses_floats_bools_and_out_of_range(value):
    with pytest.raises(ParameterError, match=r"count must be an integer in \[0, 100\]"):
        check_integer("builder", "count", value, 0, 100)


def test_check_integer_accepts_numpy_integers():
    check_integer("builder", "count", np.int64(7), 0, 100)


def test_interval_tables_check_each_argument_by_its_own_interval():
    intervals = {"count": Interval(1, 5, integer=True), "size_m": Interval(0.0, 9.0, open_low=True, unit="m")}
    check_arguments("builder", intervals, count=5, size_m=9.0)
    with pytest.raises(ParameterError, match=r"builder size_m must be in \(0, 9\] m, got 0.0"):
        check_arguments("builder", intervals, count=5, size_m=0.0)
    with pytest.raises(ParameterError, match=r"builder count must be an integer in \[1, 5\], got 2.5"):
        check_arguments("builder", intervals, count=2.5)


def test_config_keys_names_the_config_key_and_lets_other_errors_through():
    with pytest.raises(ValueError) as error:
        with config_keys("MyEnv", {"gain": "sensor_gain"}):
            check_number("Sensor", "gain", math.inf, 0.0, 10.0)
    assert type(error.value) is ValueError
    assert str(error.value) == "config key 'sensor_gain' of MyEnv must be in [0, 10], got inf (the Sensor's gain)"
    with pytest.raises(ParameterError, match="Sensor offset"):
        with config_keys("MyEnv", {"gain": "sensor_gain"}):
            check_number("Sensor", "offset", math.inf, 0.0, 10.0)


def test_from_config_builds_from_the_keys_and_names_the_bad_one():
    keys = {"range_std_m": "noise", "max_range_m": "reach"}
    sensor = from_config(RangeBearingSensor, {"noise": 0.2, "reach": 5.0, "other": 1}, keys, "MyEnv")
    assert (sensor.range_std_m, sensor.max_range_m) == (0.2, 5.0)
    with pytest.raises(ValueError, match=r"config key 'reach' of MyEnv must be in \(0, 1000\] m, got -5.0"):
        from_config(RangeBearingSensor, {"noise": 0.2, "reach": -5.0}, keys, "MyEnv")


def test_stated_requirements_log_each_key_as_its_error_states_it():
    config = {"sensor_max_range_m": 15.0, "range_std_m": 0.1, "unused": 1.0}
    keys = {"max_range_m": "sensor_max_range_m", "range_std_m": "range_std_m"}
    with stated_requirements() as requirements:
        from_config(RangeBearingSensor, config, keys, "Env")
        check_number("Sensor", "gain", 1.0, 0.0, 10.0)  # no config key sets it: not logged
    assert requirements["sensor_max_range_m"] == ["in (0, 1000] m"]
    assert "gain" not in requirements and "unused" not in requirements
    with pytest.raises(ValueError) as error:
        from_config(RangeBearingSensor, {**config, "sensor_max_range_m": -1.0}, keys, "Env")
    assert f"must be {requirements['sensor_max_range_m'][0]}, got -1.0" in str(error.value)
    from_config(RangeBearingSensor, config, keys, "Env")  # outside the context: nothing more logged
    assert requirements["sensor_max_range_m"] == ["in (0, 1000] m"]


def test_stated_requirements_of_a_made_env_match_its_errors():
    import gymnasium as gym

    import infonav_gym  # noqa: F401  (registers the envs)

    with stated_requirements() as requirements:
        gym.make("infonav/LandmarkSelection-v0").close()
    assert requirements["scenario"] == ["one of ['corridor', 'field']"]
    assert requirements["n_obstacles"] == ["an integer in [0, 100]"]
    for key, value in (("scenario", "nowhere"), ("n_obstacles", 101)):
        with pytest.raises(ValueError, match=re.escape(f"must be {requirements[key][0]}, got {value!r}")):
            gym.make("infonav/LandmarkSelection-v0", **{key: value})
