"""A new user's runs of ``infonav``: bad input is one line on stderr (exit 2) before anything slow starts, an
interruption (exit 130) keeps the work finished so far."""

import contextlib
import csv
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest
import yaml
from conftest import unused_address

from infonav_gym.experiments.cli import main
from infonav_gym.experiments.episode_pool import EpisodeRunner
from infonav_gym.experiments.evaluation import evaluate

REPOSITORY = Path(__file__).resolve().parents[1]
LANDMARK_ID = "infonav/LandmarkSelection-v0"


def _own_process_group_taking_ctrl_c() -> None:
    """In the child before exec: a process group of its own (as a terminal's foreground job) and Ctrl-C's default
    handling, which a parent started in the background has set to ignored."""
    os.setsid()
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _infonav(*argv: str, stderr=subprocess.PIPE) -> subprocess.Popen:
    """``infonav ARGV`` in a fresh interpreter of this checkout (a process group of its own), stdout piped."""
    env = {**os.environ, "PYTHONPATH": str(REPOSITORY)}
    command = [sys.executable, "-m", "infonav_gym.experiments.cli", *argv]
    return subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=stderr,
        text=True,
        env=env,
        preexec_fn=_own_process_group_taking_ctrl_c,
    )


def _ctrl_c_once_progressing(
    argv: list[str], tmp_path, counted: int = 1, within_s: float | None = None
) -> tuple[int, str, str]:
    """Run ``infonav ARGV``, press Ctrl-C (SIGINT to its process group) once its progress bar has counted ``counted``
    (episodes, steps); its exit code, stdout and the lines of stderr that are not the bar's. ``within_s``: the
    seconds it may take from Ctrl-C to its exit."""
    log = tmp_path / "stderr.txt"
    with log.open("w") as stderr:
        run = _infonav(*argv, stderr=stderr)
        deadline = time.monotonic() + 30
        while run.poll() is None and time.monotonic() < deadline:
            if max(map(int, re.findall(r"\| *(\d+)/", log.read_text())), default=0) >= counted:
                break
            time.sleep(0.05)
        os.killpg(run.pid, signal.SIGINT)
        pressed = time.monotonic()
        stdout, _ = run.communicate(timeout=30)
    assert within_s is None or time.monotonic() - pressed < within_s
    text = log.read_text()
    assert "Traceback" not in text, text
    bar = re.compile(r"^(evaluating on|training PPO)")
    return run.returncode, stdout, "\n".join(line for line in text.splitlines() if line and not bar.match(line))


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
        ({"n_stepz": 3}, "unknown hyperparameter 'n_stepz': the keys are"),
        ({"vf_coef": 0.5}, "hyperparameter(s) ['vf_coef'] have no RLlib translation"),
        ({"n_steps": 0}, "hyperparameter n_steps must be an integer from 1 to 65536, got 0"),
        ({"learning_rate": "fast"}, "hyperparameter learning_rate must be a finite number > 0 or lin_<start>"),
        ({"normalize": "yes"}, "normalize must be true or false, or a mapping"),
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


def test_an_interrupted_evaluation_writes_the_seeds_every_agent_finished(tmp_path, capsys, monkeypatch):
    play, played = EpisodeRunner.play, []

    def ctrl_c_after_3(runner, task):
        if len(played) == 3:
            raise KeyboardInterrupt
        played.append(task)
        return play(runner, task)

    monkeypatch.setattr(EpisodeRunner, "play", ctrl_c_after_3)
    stem = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--agents", "random,greedy", "--episodes", "5", "--output", str(stem), "--json"])
    captured = capsys.readouterr()
    assert exit_info.value.code == 130 and played == [("random", 0), ("greedy", 0), ("random", 1)]
    files = ", ".join(f"{stem}{suffix}" for suffix in (".md", ".csv", ".json", ".png"))
    assert captured.err == f"infonav evaluate: interrupted after 1 of 5 seeds; wrote {files}\n"
    result = json.loads(captured.out)
    assert json.loads(stem.with_suffix(".json").read_text())["interrupted"] is result["interrupted"] is True
    monkeypatch.setattr(EpisodeRunner, "play", play)
    whole = evaluate(LANDMARK_ID, ["random", "greedy"], 1, progress=False)  # the same episodes, uninterrupted
    assert result["seeds"] == [0] and all(
        result["agents"][name]["episodes"] == agent["episodes"] for name, agent in whole["agents"].items()
    )
    rows = list(csv.DictReader(stem.with_suffix(".csv").open()))
    assert [(row["agent"], row["seed"]) for row in rows] == [("random", "0"), ("greedy", "0")]
    assert "interrupted after 1 of 5 episodes per agent, seeds 0..0" in stem.with_suffix(".md").read_text()


def test_an_interrupted_evaluation_without_output_says_where_its_seeds_are(capsys, monkeypatch):
    def ctrl_c(runner, task):
        if task[1] == 1:
            raise KeyboardInterrupt
        return play(runner, task)

    play = EpisodeRunner.play
    monkeypatch.setattr(EpisodeRunner, "play", ctrl_c)
    for flags, where in (([], "the tables above hold them"), (["--json"], "the JSON on stdout holds them")):
        with pytest.raises(SystemExit):
            main(["evaluate", "--agents", "random", "--episodes", "3", *flags])
        last_line = capsys.readouterr().err.splitlines()[-1]
        assert last_line == f"infonav evaluate: interrupted after 1 of 3 seeds; {where}"


def test_ctrl_c_stops_an_evaluation_on_two_workers_within_2_s_keeping_whole_seeds(tmp_path):
    argv = ["evaluate", "--agents", "random,greedy", "--episodes", "1000000", "--workers", "2"]
    code, stdout, message = _ctrl_c_once_progressing(argv, tmp_path, counted=4, within_s=2.0)
    kept = re.fullmatch(
        r"infonav evaluate: interrupted after (\d+) of 1000000 seeds; the tables above hold them", message
    )
    assert code == 130 and kept, message
    seeds = int(kept[1])
    assert f"interrupted after {seeds} of 1000000 episodes per agent, seeds 0..{seeds - 1}" in stdout and seeds >= 1


def test_ctrl_c_in_training_saves_the_model_trained_so_far(tmp_path):
    blocks = _hyperparameters(tmp_path, {"n_envs": 2, "n_steps": 16, "batch_size": 32, "n_epochs": 1})
    output = tmp_path / "model"
    argv = ["train", "--env", LANDMARK_ID, "--timesteps", "1000000", *blocks, "--output", str(output)]
    code, _, message = _ctrl_c_once_progressing(argv, tmp_path)
    record = json.loads((output / "train.json").read_text())
    assert code == 130 and record["interrupted"] and 0 < record["timesteps"] < 1_000_000
    assert message == (
        f"infonav train: interrupted after {record['timesteps']} of 1000000 env steps; saved {output}/model.zip "
        "and train.json"
    )
    with zipfile.ZipFile(output / "model.zip") as model:  # SB3's format: the policy's weights and the run's data
        data = json.loads(model.read("data"))
    assert "policy.pth" in model.namelist() and data["num_timesteps"] == record["timesteps"]


@pytest.mark.parametrize(
    "trained_on, policies, module, evaluated_on, message",
    [
        (
            "cooperative_localization_v0",
            "shared",
            "shared_policy",
            LANDMARK_ID,
            "was trained for env 'cooperative_localization_v0' (policies: shared_policy), but the env has id "
            f"'{LANDMARK_ID}' (policy 'default_policy')",
        ),
        (
            LANDMARK_ID,
            "single",
            "default_policy",
            "cooperative_localization_v0",
            f"was trained for env '{LANDMARK_ID}' (policies: default_policy), but the env (robot_0) has id "
            "'cooperative_localization_v0' (policy 'robot_0')",
        ),
    ],
)
def test_an_rllib_policy_of_another_env_names_the_env_it_was_trained_for(
    trained_on, policies, module, evaluated_on, message, tmp_path, capsys
):
    pytest.importorskip("ray")
    from agents.rllib_agent import MODULES_PATH
    from agents.rllib_train import CHECKPOINT_DIR

    tmp_path.joinpath(CHECKPOINT_DIR, *MODULES_PATH, module).mkdir(parents=True)  # what Ray would load: not reached
    tmp_path.joinpath("train.json").write_text(json.dumps({"env_id": trained_on, "policies": policies}))
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--env", evaluated_on, "--agents", f"random,rllib:{tmp_path}", "--episodes", "1"])
    assert exit_info.value.code == 2
    _one_line_error(capsys.readouterr().err, "evaluate", f"RLlib training directory '{tmp_path}' {message}")


def test_the_infonav_command_imports_an_env_module_from_the_working_directory(tmp_path):
    """``--env MODULE:ID`` finds ``./MODULE.py`` from the installed console script, as ``python -m`` would."""
    script = Path(sys.executable).with_name("infonav")
    assert script.is_file(), f"the infonav console script is not installed beside {sys.executable}"
    (tmp_path / "my_lab_envs.py").write_text(
        "import infonav_gym\n"
        "infonav_gym.register('mylab/Landmarks-v0', 'infonav_gym.envs.landmark_selection:LandmarkSelectionEnv')\n"
    )
    argv = ["evaluate", "--env", "my_lab_envs:mylab/Landmarks-v0", "--agents", "random", "--episodes", "1", "--json"]
    environment = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    completed = subprocess.run(
        [str(script), *argv], cwd=tmp_path, capture_output=True, text=True, env=environment, check=False
    )
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert json.loads(completed.stdout.splitlines()[-1])["env_id"] == "my_lab_envs:mylab/Landmarks-v0"
