"""A new user's runs of ``infonav``: bad input is one line on stderr (exit 2) before anything slow starts, an
interruption (exit 130) keeps the work finished so far."""

import contextlib
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from conftest import unused_address

from infonav_gym.experiments.cli import main

REPOSITORY = Path(__file__).resolve().parents[1]
LANDMARK_ID = "infonav/LandmarkSelection-v0"


def _infonav(*argv: str, **popen) -> subprocess.Popen:
    """``infonav ARGV`` in a fresh interpreter of this checkout, stdout and stderr piped."""
    env = {**os.environ, "PYTHONPATH": str(REPOSITORY)}
    command = [sys.executable, "-m", "infonav_gym.experiments.cli", *argv]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, **popen)


def _one_line_error(stderr: str, command: str, message: str) -> None:
    lines = stderr.strip().splitlines()
    assert "Traceback" not in stderr and len(lines) == 1, stderr
    assert lines[0].startswith(f"infonav {command}: error: ") and message in lines[0], stderr


@contextlib.contextmanager
def silent_address():
    """``127.0.0.1:PORT`` of a port that accepts connections and never answers (not a Ray cluster)."""
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        yield f"127.0.0.1:{listener.getsockname()[1]}"


@pytest.mark.parametrize("command", [["evaluate", "--agents", "random", "--ray"], ["train", "--backend", "rllib"]])
@pytest.mark.parametrize("address", [unused_address, silent_address], ids=["refused", "silent"])
def test_an_address_without_a_ray_cluster_is_one_line_within_10_s(command, address):
    pytest.importorskip("ray")
    with address() as where:
        start = time.perf_counter()
        length = "--timesteps" if "train" in command else "--episodes"
        run = _infonav(*command, "--env", LANDMARK_ID, length, "10", "--address", where)
        _, stderr = run.communicate(timeout=30)
        elapsed = time.perf_counter() - start
    assert run.returncode == 2 and elapsed < 10, (elapsed, stderr)
    _one_line_error(stderr, command[0], f"cannot reach a Ray cluster at '{where}'")


def _hyperparameters(tmp_path, block: dict) -> list[str]:
    path = tmp_path / "ppo.yml"
    path.write_text(yaml.safe_dump({"default": block}))
    return ["--hyperparams", str(path)]


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--env", "infonav/Nope-v0"], "unknown env id 'infonav/Nope-v0'"),
        (["--config", "nope=1"], "unknown config key 'nope'"),
        (["--policies", "per_robot"], "policies 'per_robot' is for a team env"),
        ({"n_stepz": 3}, "hyperparameter(s) ['n_stepz'] have no RLlib translation"),
        ({"n_steps": 0}, "hyperparameter n_steps must be an integer >= 1, got 0"),
        ({"learning_rate": "fast"}, "hyperparameter learning_rate must be a finite number >= 0, got 'fast'"),
        ({"normalize": "yes"}, "normalize must be true, false or a dict"),
        ({"policy_kwargs": {"activation_fn": "gelu"}}, "activation_fn must be one of tanh, relu, got 'gelu'"),
    ],
)
def test_rllib_training_checks_its_arguments_before_ray_starts(extra, message, tmp_path, capsys, monkeypatch):
    ray = pytest.importorskip("ray")

    def start(*args, **kwargs):
        raise AssertionError("Ray started")

    monkeypatch.setattr(ray, "init", start)
    extra = _hyperparameters(tmp_path, extra) if isinstance(extra, dict) else extra
    argv = ["train", "--backend", "rllib", "--env", LANDMARK_ID, "--timesteps", "10", *extra]
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--output", str(tmp_path / "model")])
    assert exit_info.value.code == 2
    _one_line_error(capsys.readouterr().err, "train", message)
