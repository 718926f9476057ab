"""Bad input to ``infonav``: one line on stderr, exit 2, before any work; output stems kept whole."""

import importlib.util
import json

import numpy as np
import pytest

import infonav_gym.experiments.evaluation as evaluation
from infonav_gym.experiments.arguments import SEED_LIMIT, seed
from infonav_gym.experiments.cli import build_parser, main

LANDMARK_ID = "infonav/LandmarkSelection-v0"
TINY_EVALUATE = ["evaluate", "--episodes", "1", "--agents", "random", "--config", "horizon=5"]
REPLAY = ["replay", "mrclam", "{missing}"]  # a missing directory: the argument's error must come before loading
SEED_ERROR = f"argument --seed: must be an integer from 0 to {SEED_LIMIT - 1} (2**32 - 1), got '{{}}'"


def refused(capsys, tmp_path, argv) -> str:
    """Run ``infonav ARGV`` ({tmp} and {missing} filled in); assert exit 2 with exactly one line on stderr,
    ``infonav COMMAND: error: ...``, nothing on stdout, no traceback; return the line."""
    argv = [part.format(tmp=tmp_path, missing=tmp_path / "missing") for part in argv]
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    out, err = capsys.readouterr()
    assert exit_info.value.code == 2 and out == "" and "Traceback" not in err
    assert len(err.splitlines()) == 1 and err.startswith(f"infonav {argv[0]}: error: ")
    return err.strip()


@pytest.fixture
def no_work(monkeypatch):
    """Evaluation and calibration fail the test if they start."""

    def fail(*args, **kwargs):
        raise AssertionError("the work started before the input was checked")

    monkeypatch.setattr(evaluation, "evaluate", fail)
    monkeypatch.setattr("infonav_gym.experiments.replay.calibration.calibrate", fail)


@pytest.mark.parametrize(
    ("argv", "value"),
    [
        (["demo", "--seed", "-1"], "-1"),
        (["evaluate", "--seed", "-1"], "-1"),
        (["evaluate", "--seed", str(SEED_LIMIT)], str(SEED_LIMIT)),
        (["render", "--output", "{tmp}/episode", "--seed", "-3"], "-3"),
        (["train", "--env", LANDMARK_ID, "--timesteps", "8", "--seed", "-1"], "-1"),
        (["benchmark", "--seed", "1.5"], "1.5"),
        (["reproduce", "fig3", "--seed", "-1"], "-1"),
        ([*REPLAY, "--seed", "-1"], "-1"),
    ],
)
def test_every_command_refuses_a_bad_seed_in_one_line(capsys, tmp_path, no_work, argv, value):
    assert refused(capsys, tmp_path, argv).endswith(SEED_ERROR.format(value))


def test_the_seed_limit_is_numpys_legacy_one_that_stable_baselines_seeds_with():
    assert seed(str(SEED_LIMIT - 1)) == SEED_LIMIT - 1
    np.random.RandomState(SEED_LIMIT - 1)
    with pytest.raises(ValueError):
        np.random.RandomState(SEED_LIMIT)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["demo", "--steps", "-1"], "argument --steps: must be an integer from 1 to 200, got '-1'"),
        (["evaluate", "--episodes", "0"], "argument --episodes: must be an integer from 1 to 1000000, got '0'"),
        (["evaluate", "--episodes", "-2"], "argument --episodes: must be an integer from 1 to 1000000, got '-2'"),
        (["evaluate", "--workers", "0"], "argument --workers: must be an integer from 1 to 1024, got '0'"),
        (["evaluate", "--agents", "greedy,,random"], "argument --agents: an empty name in 'greedy,,random'"),
        (
            ["render", "--output", "{tmp}/e", "--every", "0"],
            "argument --every: must be an integer from 1 to 1000000, got '0'",
        ),
        (
            ["render", "--output", "{tmp}/e", "--max-steps", "-1"],
            "argument --max-steps: must be an integer from 1 to 1000000",
        ),
        (
            ["train", "--env", LANDMARK_ID, "--timesteps", "-1"],
            "argument --timesteps: must be an integer from 0 to 10000000000",
        ),
        (["train", "--env", LANDMARK_ID, "--timesteps", "8", "--n-envs", "0"], "argument --n-envs: must be"),
        (
            ["train", "--env", LANDMARK_ID, "--timesteps", "8", "--num-env-runners", "-1"],
            "must be an integer from 0 to 1024",
        ),
        (["train", "--env", LANDMARK_ID, "--timesteps", "8", "--envs-per-runner", "0"], "--envs-per-runner: must"),
        (["benchmark", "--seconds", "-1"], "argument --seconds: must be a number in (0, 600], got '-1'"),
        (["benchmark", "--seconds", "inf"], "argument --seconds: must be a number in (0, 600], got 'inf'"),
        (["benchmark", "--rounds", "0"], "argument --rounds: must be an integer from 1 to 100, got '0'"),
        (["reproduce", "fig3", "--seeds", "0"], "argument --seeds: must be an integer from 1 to 10000, got '0'"),
        ([*REPLAY, "--seeds", "0"], "argument --seeds: must be an integer from 1 to 10000, got '0'"),
        ([*REPLAY, "--policy", "all,"], "argument --policy: an empty name in 'all,'"),
        ([*REPLAY, "--duration-s", "0"], "argument --duration-s: must be a number in (0, 1e+07], got '0'"),
        ([*REPLAY, "--outage-robot", "0"], "argument --outage-robot: must be an integer from 1 to 99, got '0'"),
        ([*REPLAY, "--outage-start-s", "-1"], "argument --outage-start-s: must be a number in [0, 1e+07]"),
        ([*REPLAY, "--outage-end-s", "nan"], "argument --outage-end-s: must be a number > 0 (inf: the end)"),
        (["evaluate", "--episodes", "1000000000"], "argument --episodes: must be an integer from 1 to 1000000"),
        (["evaluate", "--episodes", "100000000000000000000"], "--episodes: must be an integer from 1 to 1000000"),
        (["leaderboard", "--episodes", "1000001"], "argument --episodes: must be an integer from 1 to 1000000"),
        (["demo", "--steps", "100000000000"], "argument --steps: must be an integer from 1 to 200"),
        (["evaluate", "--workers", "100000"], "argument --workers: must be an integer from 1 to 1024"),
        (["train", "--env", LANDMARK_ID, "--timesteps", "1e30"], "--timesteps: must be an integer from 0 to"),
        (["train", "--env", LANDMARK_ID, "--timesteps", "8", "--n-envs", "10000000"], "--n-envs: must be an integer"),
        (["benchmark", "--rounds", "1000000"], "argument --rounds: must be an integer from 1 to 100"),
        (["benchmark", "--vector-sizes", "1,10000000"], "each number of sub-envs must be an integer from 1 to 65536"),
        ([*REPLAY, "--outage-start-s", "5", "--outage-end-s", "2"], "outage must end after it starts, got 5.0..2.0"),
        ([*REPLAY, "--outage-start-s", "5"], "--outage-start-s set the outage of --outage-robot ROBOT: add it"),
    ],
)
def test_a_nonsense_number_or_list_is_refused_in_one_line(capsys, tmp_path, no_work, argv, message):
    assert message in refused(capsys, tmp_path, argv)


def test_zero_env_runners_is_rllibs_sampling_in_the_driver_and_accepted():
    argv = ["train", "--backend", "rllib", "--env", LANDMARK_ID, "--timesteps", "8", "--num-env-runners", "0"]
    assert build_parser().parse_args(argv).num_env_runners == 0


@pytest.mark.parametrize(
    ("extra", "ignored"),
    [
        (
            ["--policy", "greedy", "--seeds", "2", "--noise", "picked"],
            "--policy, --seeds, --noise would be ignored; drop them",
        ),
        (["--output", "{tmp}/replay", "--seed", "3"], "--output, --seed would be ignored; drop them"),
    ],
)
def test_calibrate_refuses_the_replay_options_it_would_ignore(capsys, tmp_path, no_work, extra, ignored):
    error = refused(capsys, tmp_path, [*REPLAY, "--calibrate", "{tmp}/noise.json", *extra])
    assert error == f"infonav replay: error: --calibrate only fits the noise model: {ignored.format(tmp=tmp_path)}"


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("time_step_s=nan", "must be in (0, 60] s, got nan"),
        ("time_step_s=NaN", "must be in (0, 60] s, got nan"),
        ("time_step_s=-inf", "must be in (0, 60] s, got -inf"),
        ("horizon=inf", "must be a finite integer (like the default 200), got inf"),
        ("horizon=1.5", "must be a finite integer (like the default 200), got 1.5"),
        ("time_step_s=fast", "must be a number (like the default 0.5), got 'fast'"),
    ],
)
def test_a_non_finite_config_value_is_refused_in_one_line(capsys, tmp_path, setting, message):
    error = refused(capsys, tmp_path, [*TINY_EVALUATE, "--config", setting])
    assert f"config key '{setting.partition('=')[0]}' of LandmarkSelectionEnv {message}" in error


@pytest.mark.parametrize(
    ("output", "stem"),
    [("sweep_lr0.01", "sweep_lr0.01"), ("sweep_lr0.001", "sweep_lr0.001"), ("eval.v2.md", "eval.v2")],
)
def test_evaluate_output_keeps_the_whole_stem_but_for_its_own_suffix(capsys, tmp_path, output, stem):
    assert main([*TINY_EVALUATE, "--output", str(tmp_path / output), "--json"]) == 0
    suffixes = [".md", ".csv", ".json"] + [".png"] * (importlib.util.find_spec("matplotlib") is not None)
    assert sorted(path.name for path in tmp_path.iterdir()) == sorted(stem + suffix for suffix in suffixes)
    assert json.loads(capsys.readouterr().out)["files"] == [str(tmp_path / (stem + suffix)) for suffix in suffixes]


def test_render_output_keeps_the_whole_stem(capsys, tmp_path):
    pytest.importorskip("PIL")
    pytest.importorskip("matplotlib")
    pytest.importorskip("pygame")
    argv = ["render", "--max-steps", "1", "--config", "render_size_px=64", "--output", str(tmp_path / "episode.v2")]
    assert main([*argv, "--json"]) == 0
    assert sorted(path.name for path in tmp_path.iterdir()) == ["episode.v2.gif", "episode.v2.png"]


def test_replay_help_says_when_the_nees_plot_is_written(capsys):
    with pytest.raises(SystemExit):
        main(["replay", "mrclam", "--help"])
    assert "OUTPUT.md, OUTPUT.json and, when --policy includes all, OUTPUT_nees.png" in " ".join(
        capsys.readouterr().out.split()
    )
