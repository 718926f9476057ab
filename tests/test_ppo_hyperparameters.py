"""PPO hyperparameters: shipped as package data, overridden by ``--hyperparams``, recorded in full; ``ppo:DIR``."""

import json
import shutil
import subprocess
import sys
import zipfile
from importlib import resources
from pathlib import Path

import pytest

pytest.importorskip("sb3_contrib")

from agents.ppo import load_hyperparameters, load_model  # noqa: E402
from infonav_gym.experiments.cli import main  # noqa: E402

# PPO training: slow; `pytest -m "not slow"` leaves it out while developing
pytestmark = pytest.mark.slow

LANDMARK_ID = "infonav/LandmarkSelection-v0"
ROOT = Path(__file__).resolve().parents[1]
SMALL = "default:\n  n_steps: 16\n  batch_size: 16\n  n_epochs: 1\n  gamma: 0.5\n"  # one 2 x 16-step rollout


def train_json(tmp_path, *extra, timesteps: int = 32) -> dict:
    """``infonav train`` for ``timesteps`` steps on 2 envs; its train.json."""
    output = tmp_path / "model"
    argv = ["train", "--env", LANDMARK_ID, "--timesteps", str(timesteps), "--n-envs", "2", "--output", str(output)]
    argv += extra
    assert main([*argv, "--json"]) == 0
    return json.loads((output / "train.json").read_text())


def one_line_error(capsys, argv) -> str:
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and err.count("\n") == 1 and "Traceback" not in err
    return err


def test_the_tuned_blocks_are_package_data_read_through_importlib_resources():
    shipped = resources.files("agents").joinpath("hyperparams/ppo.yml")
    assert shipped.is_file()
    assert load_hyperparameters(LANDMARK_ID)["gamma"] == 0.9
    assert load_hyperparameters("cooperative_localization_v0")["n_envs"] == 64
    assert load_hyperparameters("CartPole-v1") == load_hyperparameters("no block: the default one")


def test_the_built_wheel_contains_the_hyperparameters(tmp_path):
    pytest.importorskip("setuptools", reason="building without isolation needs setuptools in this environment")
    source = tmp_path / "source"  # a copy: building in the tree would leave build/ behind
    source.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, source / name)
    for package in ("infonav_gym", "agents"):
        shutil.copytree(ROOT / package, source / package, ignore=shutil.ignore_patterns("__pycache__"))
    command = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp_path)]
    subprocess.run([*command, str(source)], check=True, capture_output=True, timeout=120)
    (wheel,) = tmp_path.glob("infonav_gym-*.whl")
    assert "agents/hyperparams/ppo.yml" in zipfile.ZipFile(wheel).namelist()


def test_train_json_records_every_constructor_value_sb3_defaults_included(tmp_path):
    record = train_json(tmp_path, timesteps=128)  # one rollout of the tuned block: 64 steps x 2 envs
    assert record["hyperparameters"] == {**load_hyperparameters(LANDMARK_ID), "n_envs": 2}
    constructor = record["constructor"]
    assert constructor["gamma"] == 0.9 and constructor["n_steps"] == 64 and constructor["seed"] == 0
    assert constructor["vf_coef"] == 0.5 and constructor["max_grad_norm"] == 0.5, "SB3's defaults, not in the file"
    assert constructor["policy_kwargs"]["activation_fn"] == "torch.nn.modules.activation.Tanh"


def test_hyperparams_file_overrides_the_tuned_blocks(tmp_path):
    file = tmp_path / "small.yml"
    file.write_text(SMALL)
    record = train_json(tmp_path, "--hyperparams", str(file), timesteps=40)
    assert record["constructor"]["gamma"] == 0.5 and record["constructor"]["n_steps"] == 16
    assert record["constructor"]["ent_coef"] == 0.0 and record["rollout"] == 32
    assert record["timesteps_asked"] == 40 and record["timesteps"] == 64, "whole rollouts, said in train.json"


def test_lin_anneals_the_learning_rate_and_clip_range_to_zero_over_training(tmp_path, monkeypatch):
    import agents.ppo

    titles = []
    monkeypatch.setattr(agents.ppo, "drawn_curve", lambda output, title, references: titles.append(title))
    file = tmp_path / "annealed.yml"
    file.write_text(SMALL + "  learning_rate: lin_1e-3\n  clip_range: lin_0.2\n")
    train_json(tmp_path, "--hyperparams", str(file))
    assert titles[0].endswith(", gamma 0.5, learning rate lin_1e-3, clip range lin_0.2"), (
        "the title names each schedule"
    )
    model = load_model(tmp_path / "model")
    assert model.learning_rate(1.0) == 1e-3 and model.learning_rate(0.25) == pytest.approx(2.5e-4)
    assert model.clip_range(0.5) == pytest.approx(0.1) and model.clip_range(0.0) == 0.0
    # the saved optimizer holds the rate of the one update, after the 32 steps of 32: progress_remaining 0
    assert model.policy.optimizer.param_groups[0]["lr"] == 0.0


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "cannot read hyperparameter file {file}: No such file or directory"),
        ("default: [", "hyperparameter file {file} is not valid YAML"),
        ("- 1\n- 2\n", "hyperparameter file {file} must map env ids to blocks"),
        ("CartPole-v1: {}\n", "hyperparameter file {file} has no block for 'infonav/LandmarkSelection-v0'"),
        ("default: 3\n", "block 'default' of hyperparameter file {file} must be a mapping"),
        ("default: {gama: 0.9}\n", "unknown hyperparameter 'gama': the keys are n_envs, policy, n_timesteps"),
        ("default: {seed: 3}\n", "unknown hyperparameter 'seed': the keys are"),
        (
            "default: {learning_rate: lin_x}\n",
            "hyperparameter learning_rate must be a finite number > 0 or lin_<start>",
        ),
        ("default: {clip_range: exp_0.2}\n", "hyperparameter clip_range must be a number in (0, 1] or lin_<start>"),
        (
            "default: {learning_rate: lin_-1}\n",
            "with such a start, got 'lin_-1' (block 'default' of hyperparameter file",
        ),
    ],
)
def test_a_bad_hyperparams_file_is_one_line_exit_2(capsys, tmp_path, content, message):
    file = tmp_path / "ppo.yml"
    if content is not None:
        file.write_text(content)
    argv = ["train", "--env", LANDMARK_ID, "--timesteps", "8", "--output", str(tmp_path / "out")]
    assert message.format(file=file) in one_line_error(capsys, [*argv, "--hyperparams", str(file)])


def test_ppo_agent_accepts_the_directory_that_holds_model_zip(capsys, tmp_path):
    file = tmp_path / "small.yml"
    file.write_text(SMALL)
    train_json(tmp_path, "--hyperparams", str(file))
    capsys.readouterr()
    directory = tmp_path / "model"
    argv = ["evaluate", "--episodes", "1", "--config", "horizon=10", "--json", "--agents"]
    assert main([*argv, f"ppo:{directory}"]) == 0
    by_directory = json.loads(capsys.readouterr().out)["agents"][f"ppo:{directory}"]
    assert main([*argv, f"ppo:{directory / 'model.zip'}"]) == 0
    assert json.loads(capsys.readouterr().out)["agents"][f"ppo:{directory / 'model.zip'}"] == by_directory
    error = one_line_error(capsys, [*argv, f"ppo:{tmp_path}"])
    assert f"PPO model directory '{tmp_path}' holds no model.zip" in error


def test_version_prints_the_package_version(capsys):
    import infonav_gym

    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0 and capsys.readouterr().out == f"infonav {infonav_gym.__version__}\n"
