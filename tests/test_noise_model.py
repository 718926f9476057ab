"""The noise model's JSON schema: round trip, the shipped model, and errors that name the file and key."""

import dataclasses
import json
import math
import re

import numpy as np
import pytest
from mrclam_synthetic import MODEL
from scipy import integrate

from infonav_gym.datasets.noise_model import (
    NoiseModel,
    corrected_logs,
    integrated_variance,
    load_noise_model,
    parse_noise_model,
    shipped_noise_model,
)


def _document():
    return NoiseModel(robots={1: MODEL}, pooled=MODEL, source="test").to_json()


def test_save_and_load_round_trip(tmp_path):
    model = NoiseModel(robots={1: MODEL, 3: dataclasses.replace(MODEL, speed_std=0.5)}, pooled=MODEL, source="x")
    loaded = load_noise_model(model.save(tmp_path / "noise.json"))
    assert loaded.robots == model.robots and loaded.pooled == model.pooled
    assert loaded.for_robot(3).speed_std == 0.5 and loaded.for_robot(9) == MODEL  # unknown robot: pooled


def test_the_shipped_model_is_package_data_fitted_on_dataset6():
    model = shipped_noise_model()
    assert sorted(model.robots) == [1, 2, 3, 4, 5]
    assert "MRCLAM_Dataset6" in model.command and "--calibrate" in model.command
    assert all(noise.range_bias_std_m > 0 and noise.speed_std > 0 for noise in model.robots.values())


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.pop("pooled"), "test: missing key 'pooled'"),
        (lambda d: d["robots"]["1"].pop("turn_rate_std"), "test: robots.1: missing key 'turn_rate_std'"),
        (lambda d: d["robots"]["1"].update(range_std=0.1), "test: robots.1: unknown key 'range_std'"),
        (lambda d: d.update(extra=1), "test: unknown key 'extra'"),
        (lambda d: d["pooled"].update(bearing_white_std_rad=-0.01), "pooled.bearing_white_std_rad: a std"),
        (lambda d: d["pooled"].update(speed_scale=0.0), "pooled.speed_scale: a std, scale or time must be positive"),
        (
            lambda d: d["pooled"].update(range_outlier_fraction=1.5),
            "pooled.range_outlier_fraction: expected a fraction",
        ),
        (lambda d: d["pooled"].update(speed_std="fast"), "pooled.speed_std: expected a finite number"),
        (lambda d: d.update(schema_version=0), "schema_version 0 is not supported (expected 2)"),
        (lambda d: d["robots"].update(robotA=d["pooled"]), "robots: key 'robotA' is not a robot subject number"),
    ],
)
def test_bad_documents_raise_naming_the_key(edit, message):
    document = _document()
    edit(document)
    with pytest.raises(ValueError, match=re.escape(message)):
        parse_noise_model(document, "test")


def test_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.json does not exist"):
        load_noise_model(tmp_path / "missing.json")
    (tmp_path / "broken.json").write_text("{not json")
    with pytest.raises(ValueError, match="broken.json: not valid JSON"):
        load_noise_model(tmp_path / "broken.json")
    (tmp_path / "list.json").write_text(json.dumps([1, 2]))
    with pytest.raises(ValueError, match="list.json: expected a JSON object"):
        load_noise_model(tmp_path / "list.json")


def test_corrections_shift_clocks_and_remove_the_systematic_errors():
    odometry = np.array([[10.0, 0.104, 0.0309]])
    np.testing.assert_allclose(MODEL.correct_odometry(odometry), [[10.2, 0.1, 0.03]])
    measurement = np.array([[10.0, 7.0, 3.0, 0.2]])
    expected_range = 3.0 - (0.15 - 1.5 * 0.04 + 3.0 * (-0.01 - 0.3 * 0.04))
    expected_bearing = 0.2 - (0.005 - 0.05 * 0.04)
    np.testing.assert_allclose(MODEL.correct_measurements(measurement), [[9.9, 7.0, expected_range, expected_bearing]])
    total = MODEL.total_noise(2.0)
    np.testing.assert_allclose(
        np.diag(total), [(0.005 + 0.0033 * 4.0) ** 2 + 0.04**2 + 0.01**2, 0.005**2 + 0.004**2 + 0.003**2]
    )


def test_integrated_variance_is_the_double_integral_of_the_noise_autocovariance():
    q, sigma, tau = 0.02, 0.01, 7.0
    for window in (0.5, 5.0, 60.0):
        numeric, _ = integrate.dblquad(
            lambda t, s: sigma**2 * math.exp(-abs(t - s) / tau), 0, window, 0, window, epsabs=1e-14, epsrel=1e-10
        )
        assert integrated_variance(window, q, sigma, tau) == pytest.approx(q**2 * window + numeric, rel=1e-6)


def test_the_odometry_density_matches_the_fitted_variance_over_the_horizon():
    white = dataclasses.replace(MODEL, speed_bias_std=0.0, turn_rate_bias_std=0.0)
    np.testing.assert_allclose(white.odometry_density(), [MODEL.speed_std, MODEL.turn_rate_std])
    slow = dataclasses.replace(MODEL, turn_rate_bias_std=0.01, turn_rate_correlation_time_s=20.0)
    density = slow.odometry_density(64.0)[1]
    assert density**2 * 64.0 == pytest.approx(integrated_variance(64.0, MODEL.turn_rate_std, 0.01, 20.0))
    assert density > MODEL.turn_rate_std


def test_corrected_logs_leave_ground_truth_and_map_alone(tmp_path):
    from mrclam_synthetic import write_synthetic_dataset

    from infonav_gym.datasets import mrclam

    dataset = mrclam.load(write_synthetic_dataset(tmp_path / "d", np.random.default_rng(0), duration_s=20.0))
    corrected = corrected_logs(dataset, NoiseModel(robots={}, pooled=MODEL, source="test"))
    assert corrected.groundtruth is dataset.groundtruth and corrected.landmarks is dataset.landmarks
    np.testing.assert_allclose(corrected.odometry[1][:, 0], dataset.odometry[1][:, 0] + 0.2)
