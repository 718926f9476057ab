"""MRCLAM loader and the ``infonav replay mrclam`` command: synthetic directories, and Dataset 6 when present."""

import json
import math
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from mrclam_exact import (  # tests/ is on sys.path (pytest rootdir-relative import)
    BARCODES,
    HEADER,
    LANDMARKS,
    UNKNOWN_BARCODE,
    true_pose,
    write_dataset,
    write_rows,
)

from infonav_gym.datasets import mrclam
from infonav_gym.experiments.cli import main
from infonav_gym.experiments.replay import ReplayConfig, replay, run_experiments

# whole MRCLAM replays: slow; `pytest -m "not slow"` leaves it out while developing
pytestmark = pytest.mark.slow

DEFAULT_DATASET6 = Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets" / "MRCLAM_Dataset6"
DATASET6 = Path(os.environ.get("INFONAV_MRCLAM_DATASET6", DEFAULT_DATASET6))  # e.g. in a git worktree
needs_dataset6 = pytest.mark.skipif(
    not DATASET6.is_dir(), reason=f"MRCLAM Dataset 6 is not at {DATASET6} (a fresh clone does not ship it)"
)


@pytest.fixture
def dataset_dir(tmp_path) -> Path:
    return write_dataset(tmp_path / "synthetic")


def test_load_round_trips_the_files_maps_barcodes_and_counts_unknown_ones(dataset_dir):
    with pytest.warns(UserWarning, match=r"skipped 2 measurements .*\[99\]"):
        dataset = mrclam.load(dataset_dir)
    assert dataset.robots == (1, 2) and dataset.barcodes == {barcode: s for s, barcode in BARCODES.items()}
    assert dataset.unknown_barcodes == 2 and dataset.unknown_barcode_values == (UNKNOWN_BARCODE,)
    np.testing.assert_array_equal(dataset.landmark_ids, [3, 4, 5])
    np.testing.assert_allclose(dataset.landmarks, list(LANDMARKS.values()))
    odometry = np.loadtxt(dataset_dir / "Robot1_Odometry.dat")
    np.testing.assert_array_equal(dataset.odometry[1], odometry)
    assert dataset.start_time == odometry[0, 0]
    landmark_rows, robot_rows = dataset.landmark_measurements[1], dataset.robot_measurements[1]
    assert len(landmark_rows) == 3 * len(robot_rows) and set(landmark_rows[:, 1]) == {3, 4, 5}
    assert set(robot_rows[:, 1]) == {2}, "robot 1 sees robot 2, named by subject, not barcode"
    t = robot_rows[0, 0] - dataset.start_time
    expected_range = np.hypot(*(true_pose(2, t)[:2] - true_pose(1, t)[:2]))
    assert robot_rows[0, 2] == pytest.approx(expected_range, abs=1e-6)
    assert dataset.groundtruth[2].shape[1] == 4 and dataset.has_groundtruth


@pytest.mark.parametrize(
    ("line", "problem"), [("1000000000.5 0.2", "expected 3 numbers, found 2"), ("1000000000.5 0.2 abc", "not all")]
)
def test_a_malformed_line_raises_naming_the_file_and_the_line(dataset_dir, line, problem):
    path = dataset_dir / "Robot2_Odometry.dat"
    lines = path.read_text().splitlines()
    lines.insert(6, line)  # becomes line 7 (two header lines, then data)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=rf"Robot2_Odometry\.dat, line 7: malformed line \({problem}"):
        mrclam.load(dataset_dir)


def test_missing_files_are_reported_not_fatal(dataset_dir):
    (dataset_dir / "Robot2_Groundtruth.dat").unlink()
    (dataset_dir / "Robot1_Measurement.dat").unlink()
    with pytest.warns(UserWarning) as caught:
        dataset = mrclam.load(dataset_dir)
    messages = " ".join(str(w.message) for w in caught)
    assert "Robot2_Groundtruth.dat is missing" in messages and "Robot1_Measurement.dat is missing" in messages
    assert not dataset.has_groundtruth and len(dataset.landmark_measurements[1]) == 0
    (dataset_dir / "Robot2_Odometry.dat").unlink()
    with pytest.warns(UserWarning) as caught:
        assert mrclam.load(dataset_dir).robots == (1,)
    assert any("Robot2_Odometry.dat is missing, robot left out" in str(w.message) for w in caught)
    with pytest.raises(FileNotFoundError, match="Barcodes.dat is missing"):
        (dataset_dir / "Barcodes.dat").unlink()
        mrclam.load(dataset_dir)


def test_replay_of_exact_synthetic_logs_fuses_every_reading_or_one_a_step(dataset_dir):
    full = replay(dataset_dir, ReplayConfig(noise="picked"))
    for metrics in full["robots"].values():
        assert metrics["position_rmse_m"] < 0.05 and metrics["updates_gated"] == 0
        assert metrics["updates_used"] == 3 * metrics["steps"]  # the three landmarks at every measurement time
    greedy = replay(dataset_dir, ReplayConfig(policy="greedy", noise="picked"))
    assert greedy["robots"]["1"]["updates_used"] == greedy["robots"]["1"]["steps"] == full["robots"]["1"]["steps"]
    cooperative = replay(dataset_dir, ReplayConfig(cooperative=True, noise="picked"))
    # each 0.5 s step but the first (scans from 0.5 s on) holds a scan of the three landmarks and the teammate
    assert cooperative["robots"]["1"]["updates_used"] == 4 * (cooperative["robots"]["1"]["steps"] - 1)


def test_cli_replays_a_directory_and_prints_json(dataset_dir, capsys):
    argv = ["replay", "mrclam", str(dataset_dir), "--policy", "all,greedy,random,nearest", "--seeds", "2", "--json"]
    assert main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    assert [row["policy"] for row in result["rows"]] == ["all", "greedy", "random", "nearest"]
    assert result["rows"][2]["n_runs"] == 2
    assert result["dead_reckoning"]["position_rmse_m"] >= 0


def test_cli_without_groundtruth_says_so_and_replays_nothing(dataset_dir, capsys):
    for robot in (1, 2):
        (dataset_dir / f"Robot{robot}_Groundtruth.dat").unlink()
    assert main(["replay", "mrclam", str(dataset_dir)]) == 0
    captured = capsys.readouterr()
    assert "no ground truth for robot(s) [1, 2]: they are not replayed" in captured.err
    assert "| all | 1 | n/a |" in captured.out


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--policy", "oracle"], "unknown policy ['oracle']"),
        (["--outage-robot", "7"], "outage robot 7 is not one of the robots [1, 2]"),
    ],
)
def test_cli_errors_are_one_line(dataset_dir, capsys, extra, message):
    with pytest.raises(SystemExit) as error:
        main(["replay", "mrclam", str(dataset_dir), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert error.value.code == 2 and err[-1].startswith("infonav replay: error:") and message in err[-1]


def test_cli_errors_on_a_missing_or_malformed_directory(tmp_path, capsys):
    with pytest.raises(SystemExit) as error:
        main(["replay", "mrclam", str(tmp_path / "nowhere")])
    assert error.value.code == 2 and "does not exist" in capsys.readouterr().err
    directory = write_dataset(tmp_path / "bad")
    with open(directory / "Robot1_Measurement.dat", "a") as file:
        file.write("1000000030.0 33 1.0\n")
    with pytest.raises(SystemExit):
        main(["replay", "mrclam", str(directory)])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "Robot1_Measurement.dat, line" in err and "expected 4 numbers, found 3" in err


def _replay_error(capsys, directory: Path) -> str:
    """``infonav replay mrclam DIRECTORY``'s one-line error (exit 2, no traceback)."""
    with pytest.raises(SystemExit) as exit_info:
        main(["replay", "mrclam", str(directory)])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and "Traceback" not in err
    lines = err.strip().splitlines()
    assert lines[-1].startswith("infonav replay: error:") and not any("error" in line for line in lines[:-1])
    return lines[-1]


@pytest.mark.parametrize("name", ["Barcodes.dat", "Landmark_Groundtruth.dat"])
@pytest.mark.parametrize("content", ["", HEADER])
def test_an_empty_or_header_only_map_file_is_an_error_naming_it(dataset_dir, capsys, name, content):
    (dataset_dir / name).write_text(content)
    with pytest.raises(ValueError, match=rf"{name} holds no rows \(empty or only '#' comments\)"):
        mrclam.load(dataset_dir)
    assert f"{dataset_dir / name} holds no rows" in _replay_error(capsys, dataset_dir)


def test_a_file_given_for_the_dataset_directory_says_so(dataset_dir, capsys):
    file = dataset_dir / "Barcodes.dat"
    with pytest.raises(NotADirectoryError, match="is a file: give the MRCLAM dataset directory"):
        mrclam.load(file)
    assert f"{file} is a file: give the MRCLAM dataset directory" in _replay_error(capsys, file)


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("Robot2_Odometry.dat", "time [s], forward velocity [m/s], angular velocity [rad/s]"),
        ("Robot2_Measurement.dat", "time [s], barcode #, range [m], bearing [rad]"),
        ("Robot2_Groundtruth.dat", "time [s], x [m], y [m], orientation [rad]"),
    ],
)
@pytest.mark.parametrize("content", ["", HEADER])
def test_an_empty_or_header_only_robot_file_is_an_error_naming_it(dataset_dir, capsys, name, expected, content):
    path = dataset_dir / name
    path.write_text(content)
    message = f"{path} holds no rows (empty or only '#' comments): expected lines of {expected}"
    with pytest.raises(ValueError) as error:
        mrclam.load(dataset_dir)
    assert str(error.value) == message
    assert _replay_error(capsys, dataset_dir).endswith(message)


def test_negative_or_repeated_timestamps_warn_naming_the_file_and_the_count(dataset_dir, capsys):
    odometry = dataset_dir / "Robot1_Odometry.dat"
    rows = np.loadtxt(odometry)
    rows[10, 0] = rows[9, 0]
    rows[20, 0] = rows[19, 0]
    write_rows(odometry, np.vstack([[-1.0, 0.0, 0.0], rows]))
    measurements = dataset_dir / "Robot2_Measurement.dat"  # several barcodes per time are normal there
    with pytest.warns(UserWarning) as caught:
        mrclam.load(dataset_dir)
    messages = [str(warning.message) for warning in caught]
    assert f"{odometry}: 1 row(s) with a negative timestamp, left out" in messages
    assert f"{odometry}: 2 row(s) repeat the timestamp of the row before" in messages
    assert not any(str(measurements) in message for message in messages)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        main(["replay", "mrclam", str(dataset_dir), "--duration-s", "2", "--json"])
    captured = capsys.readouterr()
    assert f"infonav replay: warning: {odometry}: 2 row(s) repeat the timestamp" in captured.err
    assert json.loads(captured.out)["rows"], "a warning does not stop the replay"


@pytest.fixture(scope="module")
def dataset6():
    with pytest.warns(UserWarning) as caught:
        dataset = mrclam.load(DATASET6)
    assert any("skipped" in str(warning.message) for warning in caught)
    return dataset


@needs_dataset6
def test_dataset6_loads_and_counts_its_unknown_barcodes():
    with pytest.warns(UserWarning) as caught:
        dataset = mrclam.load(DATASET6)
    messages = [str(warning.message) for warning in caught]
    assert any("skipped" in message for message in messages)
    assert f"{DATASET6 / 'Robot4_Odometry.dat'}: 10 row(s) repeat the timestamp of the row before" in messages
    assert dataset.robots == (1, 2, 3, 4, 5) and len(dataset.landmarks) == 15 and dataset.unknown_barcodes > 0


@needs_dataset6
def test_dataset6_all_landmarks_localize_within_20_cm():
    result = replay(DATASET6)
    assert result["mean"]["position_rmse_m"] <= 0.20
    assert result["mean"]["dead_reckoning_position_rmse_m"] > 2.0, "dead reckoning drifts metres"


@needs_dataset6
def test_dataset6_greedy_has_the_lowest_posterior_entropy_of_the_one_reading_policies():
    summary = run_experiments(
        DATASET6, ("greedy", "random", "nearest"), n_seeds=3, config=ReplayConfig(duration_s=240.0)
    )
    entropy = {row["policy"]: row["mean_entropy_nats"]["mean"] for row in summary["rows"]}
    assert entropy["greedy"] < min(entropy["random"], entropy["nearest"])


@needs_dataset6
def test_dataset6_outage_teammates_halve_the_dead_reckoning_error():
    summary = run_experiments(DATASET6, (), outage=(2, 60.0, math.inf), config=ReplayConfig(duration_s=240.0))
    outage = summary["outage"]
    assert outage["position_rmse_m"] <= 0.5 * outage["dead_reckoning_from_start_position_rmse_m"]
    assert outage["cooperative_run"]["robots"]["2"]["updates_used"] > 0
