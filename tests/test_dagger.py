"""``infonav clone --dagger``: DAgger's data are the planner's labels on the states the clone drives to; every round's
policy is one ``infonav evaluate`` plays; Ctrl-C keeps the finished rounds; bad input is one line, exit 2."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_cli_input import refused

import infonav_gym.experiments.dagger as dagger_module
from agents import GreedyEntropyAgent
from agents.imitation import Demonstrations, planner_episode
from agents.ppo import PPOAgent
from infonav_gym.experiments.cli import main
from infonav_gym.registry import make_env

minari = pytest.importorskip("minari", reason="minari is not installed (the data extra)")
pytest.importorskip("jax", reason="Minari's DataCollector needs jax (the data extra)")

TEAM, SHORT = "cooperative_exploration_v0", {"max_cycles": 3}  # 3 steps of 4 robots: 12 decisions an episode


def recorded(tmp_path, capsys, env_id: str, agent: str, config: str) -> str:
    """The directory of a 1-episode dataset of ``agent`` on ``env_id`` recorded into ``tmp_path``."""
    argv = ["dataset", "--env", env_id, "--agent", agent, "--episodes", "1", "--config", config, "--json"]
    assert main([*argv, "--output", str(tmp_path / "datasets")]) == 0
    return json.loads(capsys.readouterr().out)["path"]


def test_the_labels_are_the_planners_on_the_states_the_actor_drives_to():
    labelled = planner_episode(TEAM, 5, 0.99, SHORT, actor=lambda env, robot: GreedyEntropyAgent())
    planned = planner_episode(TEAM, 5, 0.99, SHORT)
    env = make_env(TEAM, **SHORT)
    observations, infos = env.reset(seed=5)
    driven = []
    while env.agents:
        driven.append([observations[robot] for robot in env.possible_agents])
        actions = {robot: GreedyEntropyAgent().act(observations[robot], infos[robot]) for robot in env.agents}
        observations, _, _, _, infos = env.step(actions)
    env.close()
    rows = np.swapaxes(np.array(driven, dtype=np.float32), 0, 1).reshape(len(labelled.actions), -1)  # robot by robot
    np.testing.assert_array_equal(labelled.observations, rows)
    first = np.arange(0, len(rows), len(driven))  # each robot's first decision: the same state either way
    np.testing.assert_array_equal(labelled.actions[first], planned.actions[first])


@pytest.mark.slow
def test_dagger_rounds_fit_the_planners_labels_and_play_in_evaluate(tmp_path, capsys):
    dataset = recorded(tmp_path, capsys, TEAM, "planner", "max_cycles=3")
    output = tmp_path / "dagger"
    argv = ["clone", dataset, "--dagger", "1", "--dagger-episodes", "1", "--eval-episodes", "1", "--json"]
    assert main([*argv, "--output", str(output)]) == 0
    record = json.loads(capsys.readouterr().out)
    done = record["dagger"]["done"]
    assert [entry["round"] for entry in done] == [0, 1] and done[1]["seeds"] == "5000000..5000000"
    assert done[1]["labelled_rows"] == 12 and done[1]["rows"] == 24 and done[1]["model"] == str(output)
    best = record["dagger"]["best_round"]
    assert done[best]["validation_mean"] == max(entry["validation_mean"] for entry in done)
    labels = Demonstrations.load(output / "demonstrations.npz")[:3]  # the dataset's 12 rows, then round 1's
    env = make_env(TEAM, **SHORT)
    round_0 = PPOAgent(output / "round_0", env, "robot_0")
    chosen = [round_0.act(row, {"action_mask": mask}) for row, mask in zip(*(column[12:] for column in labels[:2]))]
    env.close()
    assert done[0]["agreement_on_own_states"] == pytest.approx(np.mean(np.array(chosen) == labels[2][12:]))
    evaluate = ["evaluate", "--env", TEAM, "--config", "max_cycles=3", "--agents", f"ppo:{output}", "--episodes", "1"]
    assert main([*evaluate, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["agents"][f"ppo:{output}"]["episodes"]


def test_ctrl_c_keeps_the_finished_rounds(tmp_path, capsys, monkeypatch):
    dataset = recorded(tmp_path, capsys, TEAM, "random", "max_cycles=3")

    def pressed(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(dagger_module, "planner_demonstrations", pressed)
    with pytest.raises(SystemExit) as exit_info:
        main(["clone", dataset, "--dagger", "2", "--eval-episodes", "0", "--output", str(tmp_path / "m"), "--json"])
    out, err = capsys.readouterr()
    assert exit_info.value.code == 130 and "interrupted in DAgger round 1" in err
    assert [entry["round"] for entry in json.loads(out)["done"]] == [0]
    assert (tmp_path / "m" / "round_0" / "model.zip").is_file()
    assert json.loads((tmp_path / "m" / "dagger.json").read_text())["interrupted"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--dagger", "0"], "argument --dagger: must be an integer from 1"),
        (["--dagger-episodes", "3"], "--dagger-episodes only go with --dagger ROUNDS"),
        (["--workers", "2", "--eval-episodes", "0"], "--workers, --eval-episodes only go with --dagger ROUNDS"),
        (["--dagger", "1", "--eval-episodes", "-1"], "argument --eval-episodes: must be an integer from 0"),
    ],
)
def test_bad_dagger_options_are_one_line_and_exit_2(tmp_path, capsys, argv, message):
    assert message in refused(capsys, tmp_path, ["clone", "{missing}", *argv])


def test_dagger_needs_an_env_with_a_planner(tmp_path, capsys):
    dataset = recorded(tmp_path, capsys, "infonav/LandmarkSelection-v0", "random", "horizon=3")
    message = refused(capsys, tmp_path, ["clone", dataset, "--dagger", "1", "--output", "{tmp}/model"])
    assert "infonav/LandmarkSelection-v0 has no planning model" in message
    assert not (tmp_path / "model").exists()


def test_dagger_checks_its_counts():
    with pytest.raises(ValueError, match="DAgger needs rounds >= 1"):
        dagger_module.dagger(TEAM, {}, None, 0, 1, "unused")
