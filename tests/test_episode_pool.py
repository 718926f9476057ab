"""Evaluation episodes played by worker processes (``episode_pool``) equal one process's, seed for seed."""

import importlib.util

import pytest
from conftest import unused_address

from agents.ray_support import check_reachable
from infonav_gym.experiments.cli import main
from infonav_gym.experiments.episode_pool import _start_method
from infonav_gym.experiments.evaluation import evaluate

LANDMARK_ID = "infonav/LandmarkSelection-v0"
RAY_INSTALLED = importlib.util.find_spec("ray") is not None


@pytest.mark.parametrize(
    "env_id, env_kwargs",
    [(LANDMARK_ID, {"horizon": 25}), ("cooperative_localization_v0", {"max_cycles": 15})],
    ids=["landmark_selection", "team"],
)
def test_two_workers_give_the_numbers_of_one(env_id, env_kwargs):
    kwargs = {"env_kwargs": env_kwargs, "progress": False, "seed": 3}
    one = evaluate(env_id, ["random", "greedy"], 5, **kwargs)
    two = evaluate(env_id, ["random", "greedy"], 5, workers=2, **kwargs)
    assert one == two
    assert one["agents"]["random"]["episodes"] != one["agents"]["greedy"]["episodes"]  # the order would show


def test_the_cli_takes_workers_and_refuses_bad_ones(capsys):
    argv = ["evaluate", "--episodes", "3", "--config", "horizon=10", "--json"]
    assert main([*argv, "--workers", "2"]) == 0
    two = capsys.readouterr().out
    assert main(argv) == 0
    assert capsys.readouterr().out == two
    for extra, message in [
        (["--address", "127.0.0.1:6379"], "--address is the Ray cluster of --ray"),
    ]:
        with pytest.raises(SystemExit) as exit_info:
            main([*argv, *extra])
        assert exit_info.value.code == 2 and message in capsys.readouterr().err


@pytest.mark.skipif(RAY_INSTALLED, reason="Ray is installed: the missing-extra message cannot show")
@pytest.mark.parametrize(
    "argv",
    [
        ["evaluate", "--episodes", "1", "--config", "horizon=5", "--ray"],
        ["evaluate", "--episodes", "1", "--agents", "rllib:models/none"],
        ["train", "--backend", "rllib", "--env", LANDMARK_ID, "--timesteps", "100"],
    ],
    ids=["evaluate --ray", "rllib agent", "train --backend rllib"],
)
def test_ray_without_the_extra_is_a_one_line_error_saying_what_to_install(capsys, tmp_path, argv):
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--output", str(tmp_path / "out")] if argv[0] == "train" else argv)
    assert exit_info.value.code == 2
    error = capsys.readouterr().err.strip()
    assert 'pip install "infonav-gym[distributed]"' in error and len(error.splitlines()) == 1


def test_an_unreachable_ray_address_fails_fast_naming_it():
    with unused_address() as address:
        with pytest.raises(ValueError, match=f"cannot reach a Ray cluster at '{address}'"):
            check_reachable(address, timeout_s=2.0)
    with pytest.raises(ValueError, match="is not HOST:PORT"):
        check_reachable("localhost:port")


def test_workers_are_forked_until_torch_is_imported_then_come_from_a_fork_server(monkeypatch):
    import sys

    monkeypatch.delitem(sys.modules, "torch", raising=False)
    assert _start_method() == "fork"
    monkeypatch.setitem(sys.modules, "torch", object())
    assert _start_method() == "forkserver"


def test_a_fork_server_gives_the_numbers_of_one_worker_too(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "torch", sys.modules.get("torch", object()))
    kwargs = {"env_kwargs": {"horizon": 15}, "progress": False}
    assert evaluate(LANDMARK_ID, ["random"], 3, workers=2, **kwargs) == evaluate(LANDMARK_ID, ["random"], 3, **kwargs)
