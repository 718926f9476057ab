"""``infonav evaluate`` and ``infonav leaderboard`` before and while they play: the run's memory and seeds are checked
first, workers are capped at the episodes, agents are named once, and Ctrl-C keeps whole seeds, quickly."""

import csv
import json
import multiprocessing
import time
import tracemalloc
from unittest.mock import Mock

import pytest
from test_cli_input import refused

from infonav_gym.experiments import episode_pool
from infonav_gym.experiments import evaluation as evaluation_module
from infonav_gym.experiments import leaderboard as leaderboard_module
from infonav_gym.experiments.arguments import SEED_LIMIT
from infonav_gym.experiments.cli import main
from infonav_gym.experiments.episode_pool import EpisodeRunner
from infonav_gym.experiments.evaluation import evaluate
from infonav_gym.experiments.evaluation_files import heading
from infonav_gym.experiments.paths import Interrupted

LANDMARK_ID = "infonav/LandmarkSelection-v0"
TINY = ["--agents", "random", "--config", "horizon=5"]  # evaluate: one cheap agent on short episodes
BOARD = ["leaderboard", "--envs", LANDMARK_ID, "--agents", "random,greedy"]  # two cells
QUICK = {"env_kwargs": {"horizon": 5}, "progress": False}


@pytest.fixture
def no_episode(monkeypatch):
    """Building an episode runner (the first work of evaluate and leaderboard) fails the test."""
    started = AssertionError("the work started before the input was checked")
    for module in (evaluation_module, leaderboard_module):
        monkeypatch.setattr(module, "EpisodeRunner", Mock(side_effect=started))


@pytest.mark.parametrize(
    ("argv", "records", "workers"),
    [
        (["evaluate", "--episodes", "1000000", "--workers", "4"], 2_000_000, 4),
        (["evaluate", "--episodes", "1000000", "--agents", "random"], 1_000_000, 0),  # no worker process
        ([*BOARD, "--episodes", "1000000", "--workers", "2"], 2_000_000, 2),
    ],
)
def test_a_run_larger_than_the_available_memory_is_refused_at_once_giving_the_estimate(
    capsys, tmp_path, monkeypatch, no_episode, argv, records, workers
):
    monkeypatch.setattr("infonav_gym.memory.available_bytes", lambda: 10**9)
    error = refused(capsys, tmp_path, [*argv, "--output", str(tmp_path / "out")])
    estimate = records * episode_pool.RECORD_BYTES + workers * episode_pool.WORKER_BYTES
    assert error.endswith(f"needs about {estimate / 1e9:.1f} GB of memory; 1.0 GB are available")
    assert "1000000 episodes" in error


@pytest.mark.parametrize("workers", [1, 2])
def test_episodes_are_handed_out_as_played_never_listed_up_front(monkeypatch, workers):
    """A million episodes interrupted after a few: no list of every episode was built (old: 2 million tuples)."""
    evaluate(LANDMARK_ID, ["random"], 1, **QUICK)  # the env's first build (kernels loaded) is not traced
    _interrupted_between_results(monkeypatch, 4)
    tracemalloc.start()
    try:
        with pytest.raises(Interrupted) as interruption:
            evaluate(LANDMARK_ID, ["random", "greedy"], 1_000_000, workers=workers, **QUICK)
        peak_bytes = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert interruption.value.result["seeds"] == [0, 1] and peak_bytes < 10e6


@pytest.mark.parametrize("command", ["evaluate", "leaderboard"])
def test_seeds_past_the_last_one_are_refused_naming_seed_and_episodes(capsys, tmp_path, no_episode, command):
    argv = [command, "--seed", str(SEED_LIMIT - 5), "--episodes", "10", "--output", str(tmp_path / "out")]
    assert refused(capsys, tmp_path, argv).endswith(
        f"error: --seed {SEED_LIMIT - 5} and --episodes 10 would play seeds up to {SEED_LIMIT + 4}, past the last "
        f"seed {SEED_LIMIT - 1} (2**32 - 1): lower --seed or --episodes"
    )


def test_the_last_seed_itself_is_played(capsys):
    assert main(["evaluate", *TINY, "--seed", str(SEED_LIMIT - 2), "--episodes", "2", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["seeds"] == [SEED_LIMIT - 2, SEED_LIMIT - 1]


@pytest.fixture
def pool_sizes(monkeypatch) -> list[int]:
    """The number of processes of each pool the episode pool starts."""
    sizes, pool = [], episode_pool.ProcessPoolExecutor

    def recorded(workers, **kwargs):
        sizes.append(workers)
        return pool(workers, **kwargs)

    monkeypatch.setattr(episode_pool, "ProcessPoolExecutor", recorded)
    return sizes


@pytest.mark.parametrize(
    ("argv", "capped"),
    [
        (["evaluate", *TINY, "--episodes", "2", "--workers", "1000"], 1000),
        (["evaluate", "--config", "horizon=5", "--episodes", "1", "--workers", "9"], 9),  # 2 agents: 2 episodes
        ([*BOARD, "--episodes", "2", "--workers", "64"], 64),
    ],
)
def test_workers_are_capped_at_the_episodes_saying_so_on_stderr_only(capsys, tmp_path, pool_sizes, argv, capped):
    assert main([*argv, "--output", str(tmp_path / "out"), "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["seeds"] and err == f"--workers {capped} capped at 2: there are 2 episodes to play\n"
    assert pool_sizes and set(pool_sizes) == {2}


@pytest.mark.parametrize(
    "argv",
    [
        ["evaluate", "--agents", "random,greedy,random"],
        ["leaderboard", "--agents", "greedy,random , random"],
        ["replay", "mrclam", "{missing}", "--policy", "greedy,random,random"],
    ],
)
def test_an_agent_named_twice_is_refused_naming_the_option_and_the_name(capsys, tmp_path, no_episode, argv):
    option = "--policy" if argv[0] == "replay" else "--agents"
    assert f"error: argument {option}: 'random' is given twice in " in refused(capsys, tmp_path, argv)


def test_the_python_api_refuses_an_agent_named_twice_too():
    with pytest.raises(ValueError, match="an agent is given twice in random, random"):
        evaluate(LANDMARK_ID, ["random", "random"], 1, **QUICK)


def test_evaluate_help_names_every_kind_of_agent_it_takes(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    for kind in ["random", "greedy", "planner", "ppo:PATH", "rllib:DIR", "benchmarl:DIR"]:
        assert f"{kind}: " in help_text


def _interrupted_in_an_episode(monkeypatch, calls: int) -> None:
    """Ctrl-C in the episode after the first ``calls`` episodes (one process)."""
    play, played = EpisodeRunner.play, []

    def ctrl_c(runner, task):
        if len(played) == calls:
            raise KeyboardInterrupt
        played.append(task)
        return play(runner, task)

    monkeypatch.setattr(EpisodeRunner, "play", ctrl_c)


def _interrupted_between_results(monkeypatch, results: int) -> None:
    """Ctrl-C after the pool returned its first ``results`` episodes (in task order)."""
    real_played = evaluation_module.played

    def ctrl_c(*args):
        yield from (metrics for count, metrics in zip(range(results), real_played(*args)))
        raise KeyboardInterrupt

    monkeypatch.setattr(evaluation_module, "played", ctrl_c)


@pytest.mark.parametrize(
    ("workers", "interrupt"), [(1, _interrupted_in_an_episode), (2, _interrupted_between_results)], ids=["one", "pool"]
)
@pytest.mark.parametrize("finished", [5, 4])
def test_ctrl_c_keeps_the_seeds_every_agent_finished_under_a_true_header(
    capsys, tmp_path, monkeypatch, workers, interrupt, finished
):
    interrupt(monkeypatch, finished)  # 5: seeds 0 and 1 and random on seed 2; 4: seeds 0 and 1
    stem = tmp_path / "out"
    argv = ["evaluate", "--config", "horizon=5", "--episodes", "10", "--workers", str(workers), "--output", str(stem)]
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--json"])
    out, err = capsys.readouterr()
    kept = json.loads(out)
    assert exit_info.value.code == 130 and err.startswith("infonav evaluate: interrupted after 2 of 10 seeds; wrote")
    assert kept["interrupted"] and kept["seeds"] == [0, 1]
    monkeypatch.undo()
    whole = evaluate(LANDMARK_ID, ["random", "greedy"], 2, **QUICK)
    assert {name: agent["episodes"] for name, agent in kept["agents"].items()} == {
        name: agent["episodes"] for name, agent in whole["agents"].items()
    }
    rows = list(csv.DictReader(stem.with_suffix(".csv").open()))
    assert sorted((row["agent"], row["seed"]) for row in rows) == [(a, s) for a in ("greedy", "random") for s in "01"]
    assert "interrupted after 2 of 10 episodes per agent, seeds 0..1" in heading(kept)
    assert heading(kept) in stem.with_suffix(".md").read_text()


def test_ctrl_c_before_every_agent_finished_a_seed_keeps_nothing(capsys, monkeypatch):
    _interrupted_in_an_episode(monkeypatch, 1)
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--config", "horizon=5", "--episodes", "3", "--json"])
    out, err = capsys.readouterr()
    assert exit_info.value.code == 130 and json.loads(out)["agents"] == {}
    assert err == "infonav evaluate: interrupted before every agent finished a seed: nothing to write\n"


def test_ctrl_c_kills_the_workers_mid_episode_rather_than_wait_for_them(monkeypatch):
    play = EpisodeRunner.play

    def slow_after_seed_0(runner, task):
        if task[1] > 0:
            time.sleep(60)
        return play(runner, task)

    monkeypatch.setattr(EpisodeRunner, "play", slow_after_seed_0)  # the forked workers play this one
    _interrupted_between_results(monkeypatch, 2)
    start = time.monotonic()
    with pytest.raises(Interrupted) as interruption:
        evaluate(LANDMARK_ID, ["random", "greedy"], 4, workers=2, **QUICK)
    assert time.monotonic() - start < 10 and multiprocessing.active_children() == []
    assert interruption.value.result["seeds"] == [0]
