"""``infonav dataset`` writes a local Minari dataset of any agent on any env that loads and recreates the env (a team
env through its ``JointTeamEnv``); ``infonav clone`` turns it into a policy ``infonav evaluate`` plays; bad input is one
line, exit 2."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_cli_input import refused

import infonav_gym.experiments.dataset as dataset_module
from infonav_gym.envs.joint_view import JointTeamEnv
from infonav_gym.experiments.cli import main

minari = pytest.importorskip("minari", reason="minari is not installed (the data extra)")
pytest.importorskip("jax", reason="Minari's DataCollector needs jax (the data extra)")

SINGLE, TEAM = "infonav/LandmarkSelection-v0", "cooperative_localization_v0"
SHORT = {SINGLE: "horizon=5", TEAM: "max_cycles=4"}  # short episodes, robots acting at every step


def recorded(tmp_path, capsys, env_id: str, *extra: str) -> dict:
    """``infonav dataset`` of 2 random episodes of ``env_id`` into ``tmp_path``, its JSON."""
    argv = ["dataset", "--env", env_id, "--agent", "random", "--episodes", "2", "--config", SHORT[env_id]]
    assert main([*argv, "--output", str(tmp_path), "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("env_id", [SINGLE, TEAM])
def test_a_recorded_dataset_loads_with_minari_and_recreates_the_env(env_id, tmp_path, capsys, monkeypatch):
    result = recorded(tmp_path, capsys, env_id)
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    dataset = minari.load_dataset(result["dataset_id"])
    assert dataset.total_episodes == 2 and result["seeds"] == [0, 1]
    episodes = list(dataset.iterate_episodes())
    env = dataset.recover_environment()
    key, value = SHORT[env_id].split("=")
    assert env.unwrapped.config[key] == int(value)
    observation, info = env.reset(seed=0)
    np.testing.assert_array_equal(observation, episodes[0].observations[0])  # the recorded episode 0 is seed 0's
    if env_id == TEAM:
        assert isinstance(env.unwrapped, JointTeamEnv) and observation.shape[0] == len(env.unwrapped.robots)
        assert episodes[0].actions.shape == (4, len(env.unwrapped.robots))
        np.testing.assert_allclose(episodes[0].rewards, episodes[0].infos["rewards"][1:].sum(axis=1))
    else:
        assert type(env.unwrapped).__name__ == "LandmarkSelectionEnv" and len(episodes[0].actions) == 5
    env.close()


def test_a_cloned_team_dataset_is_a_policy_that_evaluate_plays(tmp_path, capsys):
    result = recorded(tmp_path, capsys, TEAM)
    assert main(["clone", result["path"], "--output", str(tmp_path / "model"), "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["timesteps"] == 0 and record["env_kwargs"] == {"max_cycles": 4}
    assert record["warm_start"]["rows"] == 2 * 4 * 4  # episodes x steps x robots
    argv = ["evaluate", "--env", TEAM, "--config", SHORT[TEAM], "--agents", f"ppo:{tmp_path / 'model'}"]
    assert main([*argv, "--episodes", "1", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["agents"][f"ppo:{tmp_path / 'model'}"]["episodes"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["dataset", "--env", "infonav/Nope-v0"], "unknown env id 'infonav/Nope-v0'"),
        (["dataset", "--agent", "sometimes"], "unknown agent 'sometimes'"),
        (["dataset", "--agent", "planner"], "agent 'planner' is not available for infonav/LandmarkSelection-v0"),
        (["dataset", "--episodes", "0"], "argument --episodes: must be an integer from 1"),
        (["dataset", "--dataset-id", "no version"], "is not a Minari dataset id"),
        (["dataset", "--config", "horizon=-1"], "horizon"),
        (["clone", "{tmp}"], "is not a Minari dataset directory"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, message):
    if argv[0] == "dataset":
        argv = [*argv, "--output", "{tmp}"]
    assert message in refused(capsys, tmp_path, argv)
    assert not list(tmp_path.rglob("*.hdf5"))  # nothing recorded


def test_an_existing_dataset_is_kept_unless_overwrite(tmp_path, capsys):
    first = recorded(tmp_path, capsys, SINGLE)
    argv = ["dataset", "--env", SINGLE, "--agent", "random", "--config", SHORT[SINGLE], "--output", str(tmp_path)]
    assert f"dataset {first['path']} exists" in refused(capsys, tmp_path, argv)
    assert recorded(tmp_path, capsys, SINGLE, "--overwrite", "--seed", "7")["seeds"] == [7, 8]


def test_ctrl_c_writes_the_finished_episodes_and_the_one_cut_short(tmp_path, capsys, monkeypatch):
    played = dataset_module.episode_infos

    def pressed_in_the_second(env, agent, seed):
        for step, info in enumerate(played(env, agent, seed)):
            if seed == 1 and step == 2:
                raise KeyboardInterrupt
            yield info

    monkeypatch.setattr(dataset_module, "episode_infos", pressed_in_the_second)
    argv = ["dataset", "--env", SINGLE, "--agent", "random", "--config", SHORT[SINGLE], "--output", str(tmp_path)]
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--episodes", "3", "--json"])
    out, err = capsys.readouterr()
    assert exit_info.value.code == 130 and "interrupted after 1 of 3 episodes" in err
    result = json.loads(out)
    assert result["seeds"] == [0] and result["episodes"] == 2
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    cut_short = list(minari.load_dataset(result["dataset_id"]).iterate_episodes())[1]
    assert len(cut_short.actions) == 2 and cut_short.truncations[-1] and not cut_short.terminations.any()
