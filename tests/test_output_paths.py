"""Output paths of ``infonav``: checked before the work starts; a write that fails afterwards keeps the table."""

import json
from pathlib import Path

import pytest
from mrclam_exact import write_dataset  # tests/ is on sys.path (pytest rootdir-relative import)

import infonav_gym.experiments.evaluation as evaluation
import infonav_gym.experiments.evaluation_files as evaluation_files
import infonav_gym.experiments.replay as replay_package
from infonav_gym.experiments.cli import main
from infonav_gym.experiments.paths import check_output_dir, check_output_stem, output_file
from infonav_gym.experiments.reproduce import fig6

EVALUATE = ["evaluate", "--episodes", "1", "--agents", "greedy"]


def one_line_error(capsys, argv) -> tuple[str, str]:
    """Run ``infonav ARGV``; assert exit 2 with one error line (after any progress bar) and no traceback;
    return (stdout, the line)."""
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    captured = capsys.readouterr()
    assert exit_info.value.code == 2 and "Traceback" not in captured.err
    error_lines = [line for line in captured.err.splitlines() if "error" in line]
    assert len(error_lines) == 1 and error_lines[0].startswith(f"infonav {argv[0]}: error: ")
    assert captured.err.endswith(error_lines[0] + "\n")
    return captured.out, error_lines[0]


@pytest.fixture
def a_file(tmp_path):
    path = tmp_path / "a_file"
    path.write_text("not a directory\n")
    return path


@pytest.fixture
def no_work(monkeypatch):
    """Evaluation, training and reproduction fail the test if they start."""

    def fail(*args, **kwargs):
        raise AssertionError("the work started before the output path was checked")

    monkeypatch.setattr(evaluation, "evaluate", fail)
    monkeypatch.setattr(fig6, "terrain_frame_pair", fail)
    monkeypatch.setattr("agents.ppo.train", fail)
    monkeypatch.setattr("infonav_gym.experiments.replay.calibration.calibrate", fail)
    monkeypatch.setattr("infonav_gym.experiments.demo.run_demo", fail)


def test_check_output_dir_accepts_a_directory_to_be_created_and_creates_nothing(tmp_path, a_file):
    assert check_output_dir(tmp_path / "new" / "deeper", "--output-dir") == tmp_path / "new" / "deeper"
    assert not (tmp_path / "new").exists()
    assert check_output_stem(tmp_path / "eval.v2", (".md", ".json"), "--output") == tmp_path / "eval.v2"
    assert check_output_stem(tmp_path / "eval.v2.md", (".md", ".json"), "--output") == tmp_path / "eval.v2"
    assert output_file(tmp_path / "eval.v2", ".md") == tmp_path / "eval.v2.md"
    with pytest.raises(ValueError, match=f"--output-dir {a_file}/sub: {a_file} is a file, not a directory"):
        check_output_dir(a_file / "sub", "--output-dir")
    (tmp_path / "stem.md").mkdir()
    with pytest.raises(ValueError, match=r"--output .*/stem: .*/stem\.md is a directory, not a file"):
        check_output_stem(tmp_path / "stem", (".md", ".json"), "--output")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (EVALUATE + ["--output", "{file}/results"], "--output {file}/results: {file} is a file, not a directory"),
        (EVALUATE + ["--output", "{tmp}"], "--output {tmp} is a directory: give a file stem"),
        (["reproduce", "fig6", "--seeds", "1", "--output-dir", "{file}"], "{file}: {file} is a file, not a directory"),
        (["reproduce", "fig6", "--seeds", "1", "--output-dir", "{file}/figures"], "{file} is a file, not a directory"),
        (["train", "--env", "infonav/LandmarkSelection-v0", "--timesteps", "8", "--output", "{file}"], "is a file"),
        (["replay", "mrclam", "{dataset}", "--output", "{file}/replay"], "--output {file}/replay: {file} is a file"),
    ],
)
def test_a_bad_output_path_is_one_line_exit_2_before_the_work(capsys, tmp_path, a_file, no_work, argv, message):
    names = {"file": a_file, "tmp": tmp_path, "dataset": write_dataset(tmp_path / "dataset")}
    argv = [part.format(**names) for part in argv]
    _, error = one_line_error(capsys, argv)
    assert message.format(**names) in error


@pytest.mark.parametrize("locked", [Path("/sys"), Path("/proc")])  # os.access passes for root; a write fails
def test_an_unwritable_directory_is_refused_before_the_work(capsys, tmp_path, no_work, locked):
    _, error = one_line_error(capsys, EVALUATE + ["--output", str(locked / "eval")])
    assert f"--output {locked / 'eval'}: cannot write to {locked} (" in error
    _, error = one_line_error(capsys, ["reproduce", "fig6", "--output-dir", str(locked / "figures" / "fig6")])
    assert f"cannot create {locked / 'figures' / 'fig6'} in {locked} (" in error
    _, error = one_line_error(capsys, ["demo", "--plot", str(locked / "demo")])
    assert f"--plot {locked / 'demo'}: cannot write to {locked} (" in error
    dataset = write_dataset(tmp_path / "dataset")
    _, error = one_line_error(capsys, ["replay", "mrclam", str(dataset), "--calibrate", str(locked / "noise.json")])
    assert f"--calibrate {locked / 'noise'}: cannot write to {locked} (" in error


def _fail_to_write(*args, **kwargs):
    raise PermissionError(13, "Permission denied", "results/eval.md")


@pytest.mark.parametrize("as_json", [False, True])
def test_evaluate_prints_its_table_when_writing_fails(capsys, tmp_path, monkeypatch, as_json):
    monkeypatch.setattr(evaluation_files, "write_results", _fail_to_write)
    out, error = one_line_error(capsys, EVALUATE + ["--output", str(tmp_path / "eval")] + ["--json"] * as_json)
    assert error.endswith("could not write --output " + str(tmp_path / "eval") + ": results/eval.md Permission denied")
    if as_json:
        assert json.loads(out)["agents"]["greedy"]["episodes"], "the computed episodes are printed"
    else:
        assert "| greedy |" in out


def test_replay_prints_its_table_when_writing_fails(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(replay_package, "write_results", _fail_to_write)
    dataset = write_dataset(tmp_path / "dataset")
    out, error = one_line_error(capsys, ["replay", "mrclam", str(dataset), "--output", str(tmp_path / "replay")])
    assert "could not write --output" in error and "| all |" in out


def test_reproduce_prints_its_table_when_the_figure_cannot_be_written(capsys, tmp_path, monkeypatch):
    def unwritable_plot(pair, icp_motion, registration, path):
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(fig6, "plot_fig6", unwritable_plot)
    out, error = one_line_error(capsys, ["reproduce", "fig6", "--seeds", "1", "--output-dir", str(tmp_path)])
    assert error.endswith(f"could not write fig6's files: {tmp_path / 'fig6.png'} Permission denied")
    assert "Fig. 6, seed 0: registration error" in out and out.strip().endswith("wrote no files")
    assert not (tmp_path / "fig6.json").exists()


def test_reproduce_help_says_where_it_writes_by_default(capsys):
    with pytest.raises(SystemExit):
        main(["reproduce", "--help"])
    assert "default: ./results" in " ".join(capsys.readouterr().out.split())


def test_any_other_failed_write_is_one_line_exit_2(capsys, a_file):
    _, error = one_line_error(capsys, ["demo", "--steps", "2", "--plot", str(a_file / "fig2.png")])
    assert str(a_file) in error
