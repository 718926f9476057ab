"""``infonav leaderboard``: its rows and columns against the registry and the committed models, its bold cells, its
intervals, its errors, and an interrupted run keeping its finished rows."""

import json
import math
import shutil
from pathlib import Path
from types import SimpleNamespace

import pytest
from scipy import stats

from infonav_gym.envs.metrics import SUCCESS_RATE
from infonav_gym.envs.traits import EnvTraits, episode_metrics_of, has_planning_model, main_metric_of
from infonav_gym.experiments import leaderboard as leaderboard_module
from infonav_gym.experiments.cli import main
from infonav_gym.experiments.evaluation import evaluate
from infonav_gym.experiments.leaderboard import (
    BASELINES,
    COLUMNS,
    MODEL_COLUMNS,
    TIE_TOLERANCE,
    best_columns,
    leaderboard,
    leaderboard_rows,
)
from infonav_gym.registry import make_env, missing_dataset, registered_envs

MODELS = Path(__file__).resolve().parents[1] / "results" / "models"
LANDMARKS, ACTIVE = "infonav/LandmarkSelection-v0", "infonav/ActiveLocalization-v0"


def committed_records() -> dict:
    """``{model directory: train.json record}`` of every committed model."""
    return {path.parent: json.loads(path.read_text()) for path in sorted(MODELS.glob("*/train.json"))}


def run_json(capsys, *argv) -> dict:
    assert main(["leaderboard", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("entry", registered_envs(), ids=lambda entry: entry.id)
def test_every_registered_env_declares_a_main_metric_among_its_episode_metrics(entry):
    env = make_env(entry.id)
    try:
        assert main_metric_of(env) in episode_metrics_of(env)
    finally:
        env.close()


def test_a_main_metric_that_is_not_an_episode_metric_is_refused_by_name():
    class Undeclared:
        episode_metrics = (SUCCESS_RATE,)
        traits = EnvTraits(main_metric="speed")
        unwrapped = property(lambda self: self)

    with pytest.raises(ValueError, match=r"^Undeclared.traits.main_metric is 'speed', .*name one of success_rate$"):
        main_metric_of(Undeclared())


def test_rows_are_every_registered_env_and_every_committed_model_is_a_cell_of_its_env_and_config():
    env_ids = [entry.id for entry in registered_envs()]
    rows = leaderboard_rows(env_ids, tuple(COLUMNS), MODELS)
    assert {row.env_id for row in rows} == set(env_ids)
    for row in rows:
        planner = has_planning_model(next(entry for entry in registered_envs() if entry.id == row.env_id).load())
        baselines = [column for column in row.agents if column in BASELINES]
        assert baselines == ["random", "greedy", "planner"][: 3 if planner else 2]
    cells = {
        (row.env_id, json.dumps(row.env_kwargs, sort_keys=True), agent) for row in rows for _, agent, _ in row.models
    }
    records = committed_records()
    assert len(records) >= 6
    records = {
        path: record
        for path, record in records.items()
        if not missing_dataset(record["env_id"], **record["env_kwargs"])
    }
    for directory, record in records.items():
        column = MODEL_COLUMNS[record.get("backend", "sb3")]
        played = directory / "best" if record.get("validation") else directory  # the policy kept on validation
        assert (record["env_id"], json.dumps(record["env_kwargs"], sort_keys=True), f"{column}:{played}") in cells
    learned = [(column, agent) for row in rows for column, agent, _ in row.models]
    assert len(learned) == len(records) and {column for column, _ in learned} == {"ppo", "rllib", "benchmarl"}
    configs = [(row.env_id, json.dumps(row.env_kwargs, sort_keys=True)) for row in rows]
    assert len(configs) == len(set(configs))  # a row per env and config: no baseline is repeated


def test_a_models_train_json_must_name_a_registered_env_and_a_second_model_of_a_column_joins_its_row(tmp_path):
    for name, validation in (("a", None), ("b", {"best": "runs/b/best"})):  # b kept its best on validation seeds
        (tmp_path / name).mkdir()
        record = {"env_id": LANDMARKS, "env_kwargs": {}, "validation": validation}
        (tmp_path / name / "train.json").write_text(json.dumps(record))
    rows = leaderboard_rows([LANDMARKS], ("greedy", "ppo"), tmp_path)
    assert [(row.agents, row.models) for row in rows] == [
        ({"greedy": "greedy"}, (("ppo", f"ppo:{tmp_path / 'a'}", "a"), ("ppo", f"ppo:{tmp_path / 'b' / 'best'}", "b")))
    ]
    (tmp_path / "b" / "train.json").write_text(json.dumps({"env_id": "infonav/Nowhere-v0"}))
    with pytest.raises(ValueError, match=r"b/train.json: not the train.json of a registered env \(unknown env id"):
        leaderboard_rows([LANDMARKS], ("ppo",), tmp_path)


def test_a_models_backend_picks_its_column_and_an_unknown_backend_is_refused(tmp_path):
    team = "cooperative_localization_v0"
    for name, backend in (("sb3", None), ("rllib", "rllib"), ("marl", "benchmarl")):
        (tmp_path / name).mkdir()
        record = {"env_id": team, "env_kwargs": {}} | ({"backend": backend} if backend else {})
        (tmp_path / name / "train.json").write_text(json.dumps(record))
    [row] = leaderboard_rows([team], ("ppo", "rllib", "benchmarl"), tmp_path)
    assert row.models == (
        ("benchmarl", f"benchmarl:{tmp_path / 'marl'}", "marl"),
        ("rllib", f"rllib:{tmp_path / 'rllib'}", "rllib"),
        ("ppo", f"ppo:{tmp_path / 'sb3'}", "sb3"),
    )
    assert COLUMNS["benchmarl"] == "BenchMARL MAPPO"
    (tmp_path / "sb3" / "train.json").write_text(json.dumps({"env_id": team, "backend": "jax"}))
    with pytest.raises(ValueError, match=r"sb3/train.json: backend 'jax' is none of sb3, rllib, benchmarl$"):
        leaderboard_rows([team], ("ppo",), tmp_path)


def test_a_row_plays_its_baselines_and_each_model_once_and_shows_each_familys_best(tmp_path, monkeypatch):
    board = leaderboard_module
    for name in ("a", "b", "c"):
        shutil.copytree(MODELS / "landmark_selection_ppo", tmp_path / name)
    means = {"greedy": 2.0, f"ppo:{tmp_path / 'a'}": 1.0, f"ppo:{tmp_path / 'b'}": 3.0, f"ppo:{tmp_path / 'c'}": 3.0}
    calls = []

    def played_cell(row, agent, *rest):
        calls.append(agent)
        summary = {"mean": means[agent], "ci95": 0.1, "interval": "t"}
        return SimpleNamespace(name="m", title="M"), {"agent": agent, "summary": summary, "seconds_per_episode": 1.0}

    monkeypatch.setattr(board, "_played_cell", played_cell)
    results = leaderboard([LANDMARKS], ("greedy", "ppo"), tmp_path, episodes=1, progress=False)
    assert sorted(calls) == sorted(means)  # each cell once
    (row,) = results["rows"]  # one row: the env's defaults, the baselines once
    assert [model["name"] for model in row["models"]] == ["a", "b", "c"]
    assert row["cells"]["ppo"]["name"] == "b" and row["best"] == ["ppo"]  # b and c tie: the first of them
    table = board.models_text(results)
    assert table.count("| infonav/LandmarkSelection-v0 | defaults | PPO ") == 3 and table.count("**") == 2
    assert "**3.000 ± 0.100** | 1 | `ppo:" + str(tmp_path / "b") in table


def test_the_best_is_the_highest_mean_and_means_within_the_tolerance_all_tie():
    def cells(*means):
        return {f"agent{k}": {"summary": {"mean": mean}} for k, mean in enumerate(means)}

    assert best_columns(cells(0.5, 2.0, 1.0)) == ["agent1"]
    assert best_columns(cells(100.0, 100.0 * (1 - TIE_TOLERANCE / 2), 100.0 * (1 - 2 * TIE_TOLERANCE))) == [
        "agent0",
        "agent1",
    ]
    assert best_columns(cells(-3.0, -3.0)) == ["agent0", "agent1"]


def wilson_closed_form(successes: int, trials: int) -> tuple[float, float]:
    """Wilson's score interval written as in Wilson (1927): (k + z²/2 ± z sqrt(k (n - k) / n + z²/4)) / (n + z²)."""
    z = stats.norm.ppf(0.975)
    center, half = successes + z * z / 2, z * math.sqrt(successes * (trials - successes) / trials + z * z / 4)
    return (center - half) / (trials + z * z), (center + half) / (trials + z * z)


def test_two_seeds_of_a_cheap_env_give_evaluates_numbers_wilson_intervals_and_the_best_in_bold(capsys, tmp_path):
    stem = tmp_path / "board"
    results = run_json(capsys, "--envs", ACTIVE, "--agents", "random,greedy,planner,ppo", "--models", str(MODELS),
                       "--episodes", "2", "--output", str(stem))  # fmt: skip
    assert results["columns"] == ["random", "greedy", "planner", "ppo"] and results["seeds"] == [0, 1]
    [row] = results["rows"]
    assert row["metric"] == {"name": "success_rate", "title": "success rate [-]"}
    assert row["cells"]["ppo"]["agent"] == f"ppo:{MODELS / 'active_localization_ppo'}"
    agents = [cell["agent"] for cell in row["cells"].values()]
    evaluated = evaluate(ACTIVE, agents, 2, progress=False)["agents"]
    for cell in row["cells"].values():
        assert cell["values"] == [episode["success_rate"] for episode in evaluated[cell["agent"]]["episodes"]]
        low, high = wilson_closed_form(int(sum(cell["values"])), 2)
        summary = cell["summary"]
        assert summary["interval"] == "wilson" and math.isclose(summary["ci95_low"], low, abs_tol=1e-12)
        assert math.isclose(summary["ci95_high"], high, abs_tol=1e-12) and cell["seconds_per_episode"] > 0
    best = max(cell["summary"]["mean"] for cell in row["cells"].values())
    assert row["best"] == [column for column, cell in row["cells"].items() if cell["summary"]["mean"] == best]
    table = stem.with_suffix(".md").read_text().splitlines()
    header, body = ([cell.strip() for cell in line.strip("|").split("|")] for line in (table[2], table[4]))
    bold = [title for title, text in zip(header[3:], body[3:]) if text.startswith("**")]
    assert bold == [COLUMNS[column] for column in row["best"]]
    assert json.loads(stem.with_suffix(".json").read_text())["command"].startswith("infonav leaderboard --envs")


def played_values(**parallel) -> dict:
    board = leaderboard([LANDMARKS], ("random", "greedy"), None, episodes=3, progress=False, **parallel)
    return {column: cell["values"] for column, cell in board["rows"][0]["cells"].items()}


def test_worker_processes_give_one_processs_numbers():
    assert played_values(workers=2) == played_values()


@pytest.mark.slow  # starts a local Ray
def test_ray_tasks_give_one_processs_numbers():
    pytest.importorskip("ray")
    assert played_values(workers=2, use_ray=True) == played_values()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--agents", "random,oracle"], "error: unknown agent 'oracle' in --agents; choose from random, greedy"),
        (["--episodes", "0"], "--episodes: must be an integer from 1 to 1000000, got '0'"),
        (["--envs", "infonav/Nowhere-v0"], "error: unknown env id 'infonav/Nowhere-v0'"),
        (["--models", "no/such/dir"], "error: --models no/such/dir: not a directory"),
        (["--output", "."], "error: --output . is a directory: give a file stem"),
        (["--address", "x:1"], "error: --address is the Ray cluster of --ray"),
    ],
)
def test_bad_input_is_a_one_line_error(capsys, tmp_path, argv, message):
    defaults = ["--envs", LANDMARKS, "--agents", "random", "--output", str(tmp_path / "board")]
    with pytest.raises(SystemExit) as exit_info:
        main(["leaderboard", *defaults, *argv])
    error = capsys.readouterr().err
    assert exit_info.value.code == 2 and message in error and error.count("\n") == 1


def test_ctrl_c_keeps_the_finished_rows(capsys, tmp_path, monkeypatch):
    played_row = leaderboard_module._played_row

    def interrupted_at_the_second_row(row, *args):
        if row.env_id == ACTIVE:
            raise KeyboardInterrupt
        return played_row(row, *args)

    monkeypatch.setattr(leaderboard_module, "_played_row", interrupted_at_the_second_row)
    stem = tmp_path / "board"
    with pytest.raises(SystemExit) as exit_info:
        main(["leaderboard", "--envs", f"{LANDMARKS},{ACTIVE}", "--agents", "random", "--episodes", "2",
              "--output", str(stem), "--json"])  # fmt: skip
    captured = capsys.readouterr()
    assert exit_info.value.code == 130 and "interrupted after 1 of 2 rows; wrote" in captured.err
    kept = json.loads(captured.out)
    assert kept["interrupted"] and [row["env_id"] for row in kept["rows"]] == [LANDMARKS]
    assert "interrupted: the finished rows" in stem.with_suffix(".md").read_text()


@pytest.mark.slow  # every env and model on two seeds: the exploration planner alone takes minutes
def test_two_seeds_of_every_env_and_model_fill_the_cells_the_registry_and_the_models_call_for(capsys, tmp_path):
    results = run_json(capsys, "--models", str(MODELS), "--episodes", "2", "--output", str(tmp_path / "board"))
    rows = leaderboard_rows([entry.id for entry in registered_envs()], tuple(COLUMNS), MODELS)
    assert [(row["env_id"], row["env_kwargs"]) for row in results["rows"]] == [(r.env_id, r.env_kwargs) for r in rows]
    for row, expected in zip(results["rows"], rows):
        baselines = {column: cell["agent"] for column, cell in row["cells"].items() if column in BASELINES}
        assert baselines == expected.agents and [model["agent"] for model in row["models"]] == [
            agent for _, agent, _ in expected.models
        ]
        assert all(len(cell["values"]) == 2 for cell in [*row["cells"].values(), *row["models"]]) and row["best"]
