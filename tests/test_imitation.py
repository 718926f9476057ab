"""The planner's demonstrations and behaviour cloning as PPO's warm start (``agents.imitation``,
``infonav train --init-from-planner``): against the planner ``infonav evaluate`` plays, and closed forms."""

import json

import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

import infonav_gym  # noqa: E402, F401  (registers the envs)
from agents.imitation import (  # noqa: E402
    Demonstrations,
    agreement,
    clone_planner,
    discounted_returns,
    planner_demonstrations,
    planner_episode,
)
from agents.ppo import build_model  # noqa: E402
from infonav_gym.experiments.cli import main  # noqa: E402
from infonav_gym.experiments.episodes import (  # noqa: E402
    episode_infos,
    make_agent,
    make_team_agents,
    parallel_episode_infos,
)
from infonav_gym.registry import make_env  # noqa: E402

ACTIVE_ID = "infonav/ActiveLocalization-v0"
SHORT_ACTIVE = {"horizon": 12}
SHORT_TEAM = {"max_cycles": 3}  # cooperative_exploration_v0: 3 steps of 4 planners, about 2 s


def test_discounted_returns_match_the_sum_of_discounted_rewards():
    rewards = np.random.default_rng(0).normal(size=(7, 3))
    expected = [[sum(0.9**k * rewards[t + k, r] for k in range(7 - t)) for r in range(3)] for t in range(7)]
    np.testing.assert_allclose(discounted_returns(rewards, 0.9), expected, rtol=1e-12)


def test_a_single_env_episode_records_what_the_evaluated_planner_chose_and_its_returns():
    demonstrations = planner_episode(ACTIVE_ID, 4, 0.9, SHORT_ACTIVE)
    env = make_env(ACTIVE_ID, **SHORT_ACTIVE)
    planner = make_agent("planner", env.action_space.n, env=env)
    chosen = [info["chosen_action"] for info in list(episode_infos(env, planner, 4))[1:]]
    np.testing.assert_array_equal(demonstrations.actions, chosen)
    assert demonstrations.action_masks[np.arange(len(chosen)), demonstrations.actions].all()
    assert demonstrations.seeds.tolist() == [4]
    observation, _ = env.reset(seed=4)
    rewards = []
    for row, action in enumerate(chosen):  # the same seed and actions: the recorded observations and rewards
        np.testing.assert_array_equal(demonstrations.observations[row], observation)
        observation, reward, *_ = env.step(action)
        rewards.append(reward)
    returns = [sum(0.9**k * r for k, r in enumerate(rewards[t:])) for t in range(len(rewards))]
    np.testing.assert_allclose(demonstrations.returns, returns, rtol=1e-12, atol=1e-12)


def test_a_team_episode_records_every_robots_planner_choice_robot_by_robot():
    demonstrations = planner_episode("cooperative_exploration_v0", 2, 0.9, SHORT_TEAM)
    env = make_env("cooperative_exploration_v0", **SHORT_TEAM)
    steps = list(parallel_episode_infos(env, make_team_agents("planner", env), 2))[1:]
    chosen = [[step[robot]["chosen_action"] for step in steps] for robot in env.possible_agents]
    np.testing.assert_array_equal(demonstrations.actions, np.ravel(chosen))
    assert demonstrations.observations.shape == (4 * len(steps), *env.observation_space("robot_0").shape)
    assert len(demonstrations.returns) == len(demonstrations.action_masks) == 4 * len(steps)


def test_demonstrations_round_trip_through_a_file_and_a_bad_file_is_named(tmp_path):
    demonstrations = planner_demonstrations(ACTIVE_ID, 2, seed=5, env_kwargs=SHORT_ACTIVE, progress=False)
    assert demonstrations.seeds.tolist() == [5, 6]
    demonstrations.save(tmp_path / "d.npz")
    for saved, loaded in zip(demonstrations, Demonstrations.load(tmp_path / "d.npz")):
        np.testing.assert_array_equal(saved, loaded)
    (tmp_path / "bad.npz").write_text("not numpy")
    with pytest.raises(ValueError, match="--init-from-planner '.*bad.npz' is not planner demonstrations"):
        Demonstrations.load(tmp_path / "bad.npz")
    with pytest.raises(ValueError, match="episodes and workers must be >= 1"):
        planner_demonstrations(ACTIVE_ID, 0)


@pytest.mark.slow  # spawns two interpreters
def test_two_workers_play_the_same_demonstrations_as_one():
    one = planner_demonstrations(ACTIVE_ID, 2, env_kwargs=SHORT_ACTIVE, progress=False)
    two = planner_demonstrations(ACTIVE_ID, 2, env_kwargs=SHORT_ACTIVE, workers=2, progress=False)
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a, b)


def test_cloning_fits_the_planners_actions_and_values():
    demonstrations = planner_demonstrations(ACTIVE_ID, 3, env_kwargs=SHORT_ACTIVE, progress=False)
    model = build_model(ACTIVE_ID, seed=0, n_envs=2, env_kwargs=SHORT_ACTIVE)
    before = agreement(model, demonstrations)
    epochs = clone_planner(model, demonstrations, epochs=200, batch_size=16)
    assert epochs[-1]["action_nll"] < 0.5 * epochs[0]["action_nll"]
    assert epochs[-1]["value_mse"] < 0.1 * epochs[0]["value_mse"]
    assert agreement(model, demonstrations) >= 0.9 > before
    with pytest.raises(ValueError, match="do not fit a model"):
        clone_planner(model, demonstrations._replace(observations=demonstrations.observations[:, 1:]))


def test_train_init_from_planner_records_the_warm_start_and_saves_the_demonstrations(tmp_path, capsys):
    argv = ["train", "--env", ACTIVE_ID, "--timesteps", "256", "--n-envs", "2", "--init-from-planner", "2"]
    assert main([*argv, "--config", "horizon=12", "--output", str(tmp_path / "a"), "--json"]) == 0
    record = json.loads((tmp_path / "a" / "train.json").read_text())["warm_start"]
    assert record["seeds"] == [1_000_000, 1_000_001] and record["rows"] == 24
    assert len(record["cloning_epochs"]) == 50 and 0 <= record["agreement"] <= 1
    again = ["--init-from-planner", str(tmp_path / "a" / "demonstrations.npz"), "--output", str(tmp_path / "b")]
    assert main([*argv[:-2], *again, "--config", "horizon=12", "--json"]) == 0
    assert json.loads((tmp_path / "b" / "train.json").read_text())["warm_start"]["seeds"] == record["seeds"]
    alone = ["train", "--env", ACTIVE_ID, "--timesteps", "0", "--n-envs", "2", "--config", "horizon=12"]
    alone += ["--init-from-planner", str(tmp_path / "a" / "demonstrations.npz"), "--output", str(tmp_path / "c")]
    assert main([*alone, "--json"]) == 0
    cloned = json.loads((tmp_path / "c" / "train.json").read_text())
    assert cloned["timesteps"] == 0 and cloned["warm_start"]["rows"] == 24 and (tmp_path / "c" / "model.zip").is_file()
    capsys.readouterr()


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--init-from-planner", "0"], "must be an integer from 1 to 100000, got '0'"),
        (["--init-from-planner", "no/such.npz"], "must be a number of episodes >= 1 or an existing file"),
        (["--init-from-planner", "2", "--backend", "rllib"], "use it with --backend sb3"),
        (["--timesteps", "0"], "timesteps must be >= 1 (0 only with a planner warm start"),
    ],
)
def test_a_bad_warm_start_is_one_line_exit_2(capsys, extra, message):
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "--env", ACTIVE_ID, "--timesteps", "64", *extra])
    error = capsys.readouterr().err
    assert exit_info.value.code == 2 and message in error and error.count("\n") == 1
