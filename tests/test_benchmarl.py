"""BenchMARL training (``infonav train --backend benchmarl``) and its agent (``benchmarl:DIR``): the ppo.yml block
translated, the arguments checked, and a tiny trained actor playing as BenchMARL's own deterministic policy does."""

import contextlib
import io
import json

import numpy as np
import pytest
import yaml

pytest.importorskip("benchmarl", reason="the marl extra (BenchMARL, TorchRL) is not installed")

from torchrl.envs.utils import ExplorationType, set_exploration_type  # noqa: E402

from agents import benchmarl_train  # noqa: E402
from agents.benchmarl_train import benchmarl_settings, check_arguments  # noqa: E402
from agents.learning_curve import CURVE_CSV, read_curve  # noqa: E402
from agents.torchrl_env import GROUP, InfonavTorchEnv  # noqa: E402
from infonav_gym.experiments.cli import main  # noqa: E402
from infonav_gym.experiments.episodes import make_agent, make_team_agents  # noqa: E402
from infonav_gym.experiments.evaluation import evaluate  # noqa: E402
from infonav_gym.experiments.training_timing import benchmarl_train_steps_per_s  # noqa: E402
from infonav_gym.registry import make_env  # noqa: E402

TEAM_ID, CONFIG = "cooperative_localization_v0", {"team_reward": 1.0, "observe_gains": True, "max_cycles": 20}
TINY_BLOCK = {"n_envs": 4, "n_steps": 25, "batch_size": 50, "n_epochs": 1, "policy_kwargs": {"net_arch": [16]},
              "normalize": {"norm_obs": True}}  # fmt: skip


def test_the_ppo_yml_block_is_translated_into_benchmarls_names():
    block = {**TINY_BLOCK, "n_epochs": 3, "gamma": 0.8, "learning_rate": 1e-3, "ent_coef": 0.01, "normalize": False}
    settings = benchmarl_settings(block)
    assert settings["experiment"] == {
        "gamma": 0.8,
        "lr": 1e-3,
        "on_policy_n_envs_per_worker": 4,
        "on_policy_collected_frames_per_batch": 100,  # 4 copies x 25 team steps
        "on_policy_minibatch_size": 50,
        "on_policy_n_minibatch_iters": 6,  # 3 passes of 2 minibatches
    }
    assert settings["algorithm"] == {"entropy_coef": 0.01}
    assert settings["model"] == {"num_cells": [16], "activation": "tanh"} and not settings["observation_norm"]
    assert benchmarl_settings(TINY_BLOCK)["observation_norm"]
    assert benchmarl_settings({"normalize": True})["observation_norm"]
    assert not benchmarl_settings({"normalize": {"norm_obs": False, "norm_reward": True}})["observation_norm"]


@pytest.mark.parametrize(
    "arguments, message",
    [
        ((TEAM_ID, "qmix", 10, {}, {}), "--algorithm must be one of mappo, ippo with --backend benchmarl, got 'qmix'"),
        (("infonav/LandmarkSelection-v0", "mappo", 10, {}, {}), "trains the team envs (cooperative_localization_v0, "),
        ((TEAM_ID, "mappo", 0, {}, {}), "timesteps must be >= 1, got 0"),
        ((TEAM_ID, "mappo", 10, {"n_robotz": 2}, {}), "unknown config key 'n_robotz'"),
        ((TEAM_ID, "mappo", 10, {}, {"learning_rate": "lin_3e-4"}), "['learning_rate'] are schedules"),
    ],
)
def test_bad_arguments_are_refused_before_training(arguments, message):
    with pytest.raises(ValueError) as error:
        check_arguments(*arguments)
    assert message in str(error.value)


def test_a_directory_without_a_trained_actor_is_refused(tmp_path):
    env = make_env(TEAM_ID)
    with pytest.raises(ValueError, match="is not a BenchMARL training directory .*infonav train --backend benchmarl"):
        make_agent(f"benchmarl:{tmp_path}", 5, env=env, agent="robot_0")


@pytest.fixture(scope="module")
def trained(tmp_path_factory, monkeypatch_module):
    """A tiny training by the CLI (two collections of 100 team steps) and its BenchMARL experiment."""
    blocks = tmp_path_factory.mktemp("hyperparams") / "benchmarl.yml"
    blocks.write_text(yaml.safe_dump({TEAM_ID: TINY_BLOCK}))
    experiments = []

    def kept(*args):
        experiments.append(build(*args))
        return experiments[-1]

    build = benchmarl_train.build_experiment
    monkeypatch_module.setattr(benchmarl_train, "build_experiment", kept)
    output = tmp_path_factory.mktemp("benchmarl")
    config = [flag for key, value in CONFIG.items() for flag in ("--config", f"{key}={value}")]
    with contextlib.redirect_stdout(io.StringIO()) as stdout:
        assert main(["train", "--backend", "benchmarl", "--env", TEAM_ID, *config, "--timesteps", "200",
                     "--hyperparams", str(blocks), "--output", str(output), "--json"]) == 0  # fmt: skip
    assert json.loads(stdout.getvalue()) == json.loads((output / "train.json").read_text())  # stdout: the JSON alone
    return output, experiments[0]


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as patch:
        yield patch


@pytest.mark.slow  # a BenchMARL training: about 10 s
def test_training_writes_the_record_the_actor_and_a_curve_without_benchmarls_folder(trained):
    output, experiment = trained
    record = json.loads((output / "train.json").read_text())
    assert record["backend"] == "benchmarl" and record["algorithm"] == "MAPPO (BenchMARL)"
    assert record["env_id"] == TEAM_ID and record["env_kwargs"] == CONFIG and record["timesteps"] == 200
    assert record["actor"] | {"file": None} == {"file": None, "n_agents": 4, "observation_shape": [35], "n_actions": 5}
    assert not record["interrupted"] and experiment.total_frames == 200
    norm = record["benchmarl"]
    assert norm["observation_loc"] == experiment.task.loc.tolist() and len(norm["observation_loc"]) == 35
    assert norm["observation_scale"] == experiment.task.scale.tolist() and min(norm["observation_scale"]) > 0
    assert sorted(path.name for path in output.iterdir()) == [
        "actor.pt", "curve.csv", "curve.png", "curve_labels.json", "train.json"
    ]  # fmt: skip
    _, rows = read_curve(output / CURVE_CSV)
    assert rows[:, 0].tolist() == [100.0, 200.0] and rows[:, 3].tolist() == [4.0, 4.0]  # 4 episodes of 20 steps each


@pytest.mark.slow
def test_each_robot_acts_as_benchmarls_deterministic_policy_on_the_torchrl_envs_observations(trained):
    output, experiment = trained
    env = make_env(TEAM_ID, **CONFIG)
    agents = make_team_agents(f"benchmarl:{output}", env)
    torch_env = InfonavTorchEnv(TEAM_ID, num_envs=1, seed=7, **CONFIG)
    observations, infos = env.reset(seed=7)
    state = torch_env.reset()
    [standardize] = experiment.task.get_env_transforms(torch_env)  # the observations the policy was trained on
    for _ in range(5):
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            actions = experiment.policy(standardize(state.clone()))[GROUP, "action"]
        state[GROUP, "action"] = actions
        for k, robot in enumerate(env.possible_agents):
            assert np.array_equal(observations[robot], state[GROUP, "observation"][0, k].numpy())
            assert np.array_equal(infos[robot]["action_mask"].astype(bool), state[GROUP, "action_mask"][0, k].numpy())
        actions = {robot: agents[robot].act(observations[robot], infos[robot]) for robot in env.possible_agents}
        assert list(actions.values()) == state[GROUP, "action"][0].tolist()
        observations, _, _, _, infos = env.step(actions)
        state = torch_env.step(state)["next"]
    torch_env.close()


@pytest.mark.slow
def test_the_agent_plays_valid_episodes_in_evaluate_and_refuses_an_env_it_was_not_trained_for(trained):
    output, _ = trained
    results = evaluate(TEAM_ID, [f"benchmarl:{output}"], 2, env_kwargs=CONFIG, progress=False)
    episodes = results["agents"][f"benchmarl:{output}"]["episodes"]
    assert len(episodes) == 2 and all(np.isfinite(episode["cumulative_mi"]) for episode in episodes)
    exploration = make_env("cooperative_exploration_v0")
    with pytest.raises(ValueError, match=r"\(env 'cooperative_localization_v0'\) was trained for observations \(35,\)"):
        make_agent(f"benchmarl:{output}", 45, env=exploration, agent="robot_0")
    with pytest.raises(ValueError, match="was trained for a team of 4 robots, but the env has one robot"):
        make_agent(f"benchmarl:{output}", 5, env=make_env("infonav/LandmarkSelection-v0"))


@pytest.mark.slow  # three collections of 2 exploration copies and two MAPPO updates
def test_the_benchmarks_benchmarl_rate_times_whole_collections_and_updates():
    assert benchmarl_train_steps_per_s(n_envs=2) > 0
