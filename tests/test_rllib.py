"""RLlib PPO on the infonav envs (the ``distributed`` extra): masking, train + evaluate by the CLI, restoring.

One local Ray (2 CPUs) serves the whole module (the benchmark's RLlib figures too); the trainings are two small
batches (``SMALL_BLOCK``) of 500 env steps, enough to exercise every path, not to learn.
"""

import json

import gymnasium as gym
import numpy as np
import pytest
from conftest import unused_address

ray = pytest.importorskip("ray", reason="the distributed extra (ray[rllib]) is not installed")

import torch  # noqa: E402
from ray.rllib.core.rl_module.rl_module import RLModule, RLModuleSpec  # noqa: E402

from agents.learning_curve import CURVE_CSV, CURVE_PNG, read_curve  # noqa: E402
from agents.rllib_agent import MODULES_PATH, RLlibAgent  # noqa: E402
from agents.rllib_masking import ACTION_MASK, MaskedObservations, mask_observation  # noqa: E402
from agents.rllib_module import MaskedPPOTorchRLModule  # noqa: E402
from agents.rllib_train import (  # noqa: E402
    CHECKPOINT_DIR,
    SHARED_POLICY,
    TeamEnvCreator,
    build_config,
)
from infonav_gym.experiments import distributed_timing, training_timing  # noqa: E402
from infonav_gym.experiments.benchmark import GOALS  # noqa: E402
from infonav_gym.experiments.cli import main  # noqa: E402
from infonav_gym.multi import cooperative_exploration_v0, cooperative_localization_v0  # noqa: E402
from infonav_gym.registry import PARALLEL, api_of, make_env  # noqa: E402

# RLlib training and Ray: slow; `pytest -m "not slow"` leaves it out while developing
pytestmark = pytest.mark.slow

LANDMARK_ID, TEAM_ID = "infonav/LandmarkSelection-v0", "cooperative_localization_v0"
EXPLORATION_ID, EXPLORATION_CYCLES = "cooperative_exploration_v0", 40
SMALL_BLOCK = {"n_envs": 1, "n_steps": 500, "batch_size": 128, "n_epochs": 2, "policy_kwargs": {"net_arch": [32, 32]}}
TEAM_BLOCK = {**SMALL_BLOCK, "n_envs": 4, "n_steps": 125}  # the same 500 steps per batch, from 4 copies


@pytest.fixture(scope="module")
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def small_blocks(tmp_path_factory):
    import yaml

    path = tmp_path_factory.mktemp("hyperparams") / "ppo.yml"
    path.write_text(yaml.safe_dump({LANDMARK_ID: SMALL_BLOCK, TEAM_ID: TEAM_BLOCK, EXPLORATION_ID: TEAM_BLOCK}))
    return path


def _trained(tmp_path_factory, small_blocks, env_id, *config, timesteps: int = 1000) -> tuple:
    output = tmp_path_factory.mktemp("rllib")
    argv = ["train", "--backend", "rllib", "--env", env_id, "--timesteps", str(timesteps)]
    argv += ["--hyperparams", str(small_blocks)]
    assert main([*argv, *config, "--output", str(output), "--json"]) == 0
    return output, json.loads((output / "train.json").read_text())


@pytest.fixture(scope="module")
def landmark_run(local_ray, tmp_path_factory, small_blocks):
    return _trained(tmp_path_factory, small_blocks, LANDMARK_ID, "--config", "horizon=40")


@pytest.fixture(scope="module")
def team_run(local_ray, tmp_path_factory, small_blocks):
    return _trained(tmp_path_factory, small_blocks, TEAM_ID, "--config", "max_cycles=30")


@pytest.fixture(scope="module")
def exploration_run(local_ray, tmp_path_factory, small_blocks):
    return _trained(tmp_path_factory, small_blocks, EXPLORATION_ID, "--config", f"max_cycles={EXPLORATION_CYCLES}")


def _masked_module(env, **model_config) -> MaskedPPOTorchRLModule:
    """A fresh masked module for ``env`` (a ``MaskedObservations``), one hidden layer of 16."""
    return RLModuleSpec(
        module_class=MaskedPPOTorchRLModule,
        observation_space=env.observation_space,
        action_space=env.action_space,
        model_config={"fcnet_hiddens": [16], **model_config},
    ).build()


def test_the_masked_module_never_samples_a_masked_action_in_1000_steps():
    env = MaskedObservations(gym.make(LANDMARK_ID, horizon=100))
    module = _masked_module(env)
    observation, _ = env.reset(seed=0)
    partial, generator = 0, torch.Generator().manual_seed(0)
    for _ in range(1000):
        batch = {"obs": {key: torch.as_tensor(value)[None] for key, value in observation.items()}}
        logits = module.forward_exploration(batch)["action_dist_inputs"][0]
        action = int(torch.multinomial(torch.softmax(logits, dim=0), 1, generator=generator))
        assert observation[ACTION_MASK][action] == 1.0
        partial += observation[ACTION_MASK].sum() < observation[ACTION_MASK].size
        observation, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            observation, _ = env.reset()
    assert partial > 100  # most steps had masked actions to avoid


def test_the_module_refuses_observations_without_a_mask():
    with pytest.raises(ValueError, match="MaskedPPOTorchRLModule needs observations"):
        RLModuleSpec(
            module_class=MaskedPPOTorchRLModule,
            observation_space=gym.spaces.Box(-1, 1, (3,)),
            action_space=gym.spaces.Discrete(2),
        ).build()


def test_train_writes_a_checkpoint_and_a_record_and_evaluate_plays_it(landmark_run, capsys):
    output, record = landmark_run
    assert record["backend"] == "rllib" and record["env_id"] == LANDMARK_ID and record["timesteps"] >= 1000
    assert record["rllib_training"]["train_batch_size_per_learner"] == 500 and record["num_env_runners"] == 1
    assert record["vectorization"] == "native"  # RLlib steps the native vector env (VECTOR_ENTRY_POINT)
    agents = f"greedy,rllib:{output}"
    argv = ["evaluate", "--env", LANDMARK_ID, "--agents", agents, "--episodes", "2", "--config", "horizon=40"]
    assert main([*argv, "--json"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert main([*argv, "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == first
    assert all(episode["cumulative_mi"] > 0 for episode in first["agents"][f"rllib:{output}"]["episodes"])


def test_train_writes_the_curve_of_rllibs_episode_return_mean_without_the_metric(landmark_run):
    output, record = landmark_run
    name, rows = read_curve(output / CURVE_CSV)
    assert name == "cumulative_mi" and len(rows) >= 2 and (np.diff(rows[:, 0]) > 0).all()
    assert rows[-1, 0] == record["timesteps"] and rows[:, 3].sum() == record["timesteps"] // 40  # horizon=40 episodes
    assert (rows[:, 1] > 0).all() and np.isnan(rows[:, 2]).all()  # MI rewards; RLlib reports no main metric
    image = pytest.importorskip("matplotlib.image").imread(record["curve"])
    assert record["curve"] == str(output / CURVE_PNG) and image.shape[:2] == (350, 700)  # the return panel alone


def test_a_team_curve_holds_the_teams_main_metric(team_run):
    output, record = team_run
    name, rows = read_curve(output / CURVE_CSV)
    assert name == "cumulative_mi" and len(rows) >= 1 and np.isfinite(rows[:, 2]).all() and (rows[:, 2] > 0).all()


def test_the_team_trains_one_shared_policy_whose_agents_take_only_valid_actions(team_run):
    output, record = team_run
    assert record["policies"] == "shared" and record["vectorization"] == "native"
    assert record["envs_per_runner"] == TEAM_BLOCK["n_envs"]  # the block's copies, stepped at once by one runner
    modules = output.joinpath(CHECKPOINT_DIR, *MODULES_PATH)
    assert (modules / SHARED_POLICY).is_dir() and not (modules / "robot_0").exists()
    env = cooperative_localization_v0.parallel_env(max_cycles=30)
    robots = {robot: RLlibAgent(output, env, robot) for robot in env.possible_agents}
    observations, infos = env.reset(seed=1)
    while env.agents:
        actions = {robot: robots[robot].act(observations[robot], infos[robot]) for robot in env.agents}
        assert all(infos[robot]["action_mask"][action] for robot, action in actions.items())
        observations, _, _, _, infos = env.step(actions)


def test_a_team_runner_steps_its_copies_at_once_and_its_episodes_take_only_valid_actions(local_ray, small_blocks):
    from agents.ppo import load_hyperparameters
    from agents.rllib_team_env import BatchedTeamEnv, BatchedTeamEnvRunner

    copies, env_kwargs = 4, {"max_cycles": 30, "coverage_target": 0.05}  # copies end their episodes at different steps
    hyperparameters = load_hyperparameters(EXPLORATION_ID, small_blocks)
    config = build_config(EXPLORATION_ID, env_kwargs, 0, hyperparameters, num_env_runners=0, envs_per_runner=copies)
    algorithm = config.build_algo()
    try:
        runner = algorithm.env_runner
        assert isinstance(runner, BatchedTeamEnvRunner) and isinstance(runner.env, BatchedTeamEnv)
        team, shapes = runner.env.team, []
        team_step = team.step
        team.step = lambda actions: shapes.append(np.shape(actions)) or team_step(actions)
        episodes = runner.sample(num_timesteps=200)
        metrics = runner.get_metrics()
    finally:
        algorithm.stop()
    assert set(shapes) == {(copies, 4)} and copies * len(shapes) >= 200  # one batched step serves every copy
    steps = sum(len(episode) for episode in episodes)
    assert 200 <= steps < 200 + copies  # RLlib stops at the first step past 200
    assert len({len(episode) for episode in episodes if episode.is_done}) > 1
    # RLlib's counts, logged once per sample, as RLlib logs them step by step
    assert metrics["num_env_steps_sampled"] == metrics["num_env_steps_sampled_lifetime"] == steps
    assert metrics["num_episodes"] == sum(episode.is_done for episode in episodes)
    assert metrics["num_agent_steps_sampled"] == {robot: steps for robot in runner.env.agents}
    assert metrics["num_module_steps_sampled"] == {SHARED_POLICY: 4 * steps}
    for episode in episodes:
        for robot_episode in episode.agent_episodes.values():
            steps = slice(0, len(robot_episode))
            masks = robot_episode.get_observations(steps)[ACTION_MASK]
            actions = np.asarray(robot_episode.get_actions(steps))
            assert (masks[np.arange(len(actions)), actions] == 1).all()


def test_one_policy_per_robot_trains_a_module_for_each(local_ray, tmp_path_factory, small_blocks):
    config = ("--config", "max_cycles=20", "--policies", "per_robot", "--num-env-runners", "0")  # samples here
    output, record = _trained(tmp_path_factory, small_blocks, TEAM_ID, *config)
    modules = output.joinpath(CHECKPOINT_DIR, *MODULES_PATH)
    robots = cooperative_localization_v0.parallel_env().possible_agents
    assert record["policies"] == "per_robot" and all((modules / robot).is_dir() for robot in robots)
    assert not (modules / SHARED_POLICY).exists()
    env = cooperative_localization_v0.parallel_env(max_cycles=20)
    observations, infos = env.reset(seed=0)
    actions = {robot: RLlibAgent(output, env, robot).act(observations[robot], infos[robot]) for robot in robots}
    assert all(infos[robot]["action_mask"][action] for robot, action in actions.items())


def _play(env_id: str, env_kwargs: dict, act, steps: int) -> None:
    """``steps`` steps of the masked ``env_id`` (a team's: one copy, as RLlib sees it) from seed 3, each robot (or the
    agent) acting by ``act(obs)``."""
    if api_of(env_id) == PARALLEL:
        env = TeamEnvCreator(env_id)(env_kwargs)
        observations, _ = env.reset(seed=3)
        for _ in range(steps):
            observations, *_ = env.step([{robot: act(observation) for robot, observation in observations[0].items()}])
        return
    env = MaskedObservations(make_env(env_id, **env_kwargs))
    observation, _ = env.reset(seed=3)
    for _ in range(steps):
        observation, *_ = env.step(act(observation))


@pytest.mark.parametrize(
    ("env_id", "env_kwargs"), [(LANDMARK_ID, {"horizon": 40}), (EXPLORATION_ID, {"max_cycles": EXPLORATION_CYCLES})]
)
def test_a_restored_module_gives_the_trained_modules_actions(local_ray, tmp_path, small_blocks, env_id, env_kwargs):
    from agents.ppo import load_hyperparameters

    config = build_config(env_id, env_kwargs, 0, load_hyperparameters(env_id, small_blocks), num_env_runners=0)
    policy = SHARED_POLICY if api_of(env_id) == PARALLEL else "default_policy"
    algorithm = config.build_algo()
    try:
        algorithm.train()
        algorithm.save_to_path(str(tmp_path / CHECKPOINT_DIR))
        trained = algorithm.get_module(policy)
        restored = RLModule.from_checkpoint(tmp_path.joinpath(CHECKPOINT_DIR, *MODULES_PATH, policy))

        def act(observation: dict) -> int:
            batch = {"obs": {key: torch.as_tensor(value)[None] for key, value in observation.items()}}
            with torch.no_grad():
                expected = trained.forward_inference(batch)["action_dist_inputs"]
                actual = restored.forward_inference(batch)["action_dist_inputs"]
            torch.testing.assert_close(actual, expected, rtol=0, atol=0)
            return int(torch.argmax(actual))

        _play(env_id, env_kwargs, act, 40)
    finally:
        algorithm.stop()


def test_the_exploration_team_trains_and_evaluates_and_its_policy_never_gives_a_masked_action_weight(
    exploration_run, capsys
):
    output, record = exploration_run
    assert record["env_id"] == EXPLORATION_ID and record["policies"] == "shared" and record["timesteps"] >= 1000
    argv = ["evaluate", "--env", EXPLORATION_ID, "--agents", f"rllib:{output}", "--episodes", "2"]
    assert main([*argv, "--config", f"max_cycles={EXPLORATION_CYCLES}", "--json"]) == 0
    episodes = json.loads(capsys.readouterr().out)["agents"][f"rllib:{output}"]["episodes"]
    assert len(episodes) == 2 and all(0 < episode["episode_steps"] <= EXPLORATION_CYCLES for episode in episodes)
    env = cooperative_exploration_v0.parallel_env(max_cycles=EXPLORATION_CYCLES)
    robots = {robot: RLlibAgent(output, env, robot) for robot in env.possible_agents}
    masked_steps = 0
    for seed in range(2):  # the evaluation's seeds
        observations, infos = env.reset(seed=seed)
        while env.agents:
            actions = {robot: robots[robot].act(observations[robot], infos[robot]) for robot in env.agents}
            for robot, action in actions.items():
                mask = mask_observation(infos[robot]["action_mask"], len(infos[robot]["action_mask"]))
                batch = {"obs": {"observation": torch.as_tensor(observations[robot])[None]}}
                batch["obs"][ACTION_MASK] = torch.as_tensor(mask)[None]
                with torch.no_grad():
                    logits = robots[robot].module.forward_inference(batch)["action_dist_inputs"][0]
                assert mask[action] == 1 and float(torch.softmax(logits, 0)[mask == 0].sum()) == 0.0
                masked_steps += int(not mask.all())
            observations, _, _, _, infos = env.step(actions)
    assert masked_steps > 0


def test_an_agent_takes_a_relative_directory(landmark_run, monkeypatch):
    output, _ = landmark_run
    monkeypatch.chdir(output.parent)
    env = gym.make(LANDMARK_ID, horizon=40)
    _, info = env.reset(seed=0)
    action = RLlibAgent(output.name, env).act(env.observation_space.sample() * 0, info)
    assert info["action_mask"][action] or not info["action_mask"].any()


def test_an_agent_refuses_a_directory_without_a_checkpoint_or_another_env(landmark_run, tmp_path):
    output, _ = landmark_run
    with pytest.raises(ValueError, match="is not an RLlib training directory"):
        RLlibAgent(tmp_path, gym.make(LANDMARK_ID))
    with pytest.raises(ValueError, match=r"was trained for observations \(50,\).*has \(20,\)"):
        RLlibAgent(output, gym.make(LANDMARK_ID, n_candidates=2))


def test_bad_rllib_arguments_are_one_line_errors(local_ray, capsys, small_blocks):
    argv = ["train", "--backend", "rllib", "--env", LANDMARK_ID, "--timesteps", "10"]
    with unused_address() as address:
        for extra, message in [
            (["--num-env-runners", "-1"], "--num-env-runners: must be an integer from 0 to 1024"),
            (["--envs-per-runner", "0"], "--envs-per-runner: must be an integer from 1 to 65536"),
            (["--address", address], "cannot reach a Ray cluster at"),
        ]:
            with pytest.raises(SystemExit) as exit_info:
                main([*argv, *extra])
            error = capsys.readouterr().err.strip()
            assert exit_info.value.code == 2 and message in error and len(error.splitlines()) == 1


def test_normalization_keeps_the_running_mean_and_variance_of_the_training_batches():
    env = MaskedObservations(gym.make(LANDMARK_ID, horizon=30))
    module = _masked_module(env, normalize_observations=True)
    batches = [np.random.default_rng(seed).normal(seed, 1.0 + seed, (40, 50)).astype(np.float32) for seed in range(3)]
    for batch in batches:
        module.update_normalization(torch.as_tensor(batch))
    every = np.concatenate(batches).astype(np.float64)
    np.testing.assert_allclose(module.observation_mean.numpy(), every.mean(axis=0), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(module.observation_var.numpy(), every.var(axis=0), rtol=1e-6)
    state = module.get_state(inference_only=True)  # what the env runners and checkpoints get
    assert {"observation_mean", "observation_var", "observation_count"} <= set(state)
    observation, _ = env.reset(seed=0)
    plain, mask = module._split({"obs": {key: torch.as_tensor(value)[None] for key, value in observation.items()}})
    expected = (observation["observation"] - every.mean(axis=0)) / np.sqrt(every.var(axis=0) + 1e-8)
    np.testing.assert_allclose(plain["obs"][0].numpy(), np.clip(expected, -10, 10), rtol=1e-5, atol=1e-5)


def test_ray_tasks_give_the_numbers_of_one_process(local_ray):
    from infonav_gym.experiments.evaluation import evaluate

    kwargs = {"env_kwargs": {"horizon": 20}, "progress": False, "seed": 2}
    one = evaluate(LANDMARK_ID, ["random", "greedy"], 3, **kwargs)
    assert evaluate(LANDMARK_ID, ["random", "greedy"], 3, workers=2, use_ray=True, **kwargs) == one


def test_range_registration_trains_on_its_native_vector_env(local_ray, tmp_path_factory, small_blocks):
    import yaml

    env_id = "infonav/RangeRegistration-v0"
    path = tmp_path_factory.mktemp("registration") / "ppo.yml"
    path.write_text(yaml.safe_dump({env_id: {**SMALL_BLOCK, "n_steps": 64, "batch_size": 32}}))
    config = ("--envs-per-runner", "2", "--config", "horizon=20")
    output, record = _trained(tmp_path_factory, path, env_id, *config, timesteps=256)  # ICP every step: slow
    assert record["vectorization"] == "native" and record["timesteps"] >= 256
    env = gym.make(env_id, horizon=20)
    observation, info = env.reset(seed=0)
    assert env.action_space.contains(RLlibAgent(output, env).act(observation, info))


def test_the_benchmarks_training_figures_compare_sb3_with_rllib_in_robot_steps(local_ray, monkeypatch):
    assert training_timing.rllib_train_steps_per_s(n_envs=2) > 0  # two exploration copies, a 128-step train batch
    monkeypatch.setattr(training_timing, "sb3_train_steps_per_s", lambda seed, n_envs: 3000.0)
    monkeypatch.setattr(training_timing, "rllib_train_steps_per_s", lambda seed, n_envs: 1200.0)
    monkeypatch.setattr(training_timing, "benchmarl_train_steps_per_s", lambda seed, n_envs: 6000.0)
    monkeypatch.setattr(training_timing, "benchmarl_missing", lambda: None)
    figures = training_timing.training_figures(n_envs=2)
    assert figures == {
        "sb3_train_steps_per_s": 3000.0,
        "train_n_envs": 2,
        "rllib_train_steps_per_s": 1200.0,
        "sb3_vs_rllib_train_steps_ratio": 2.5,
        "benchmarl_train_steps_per_s": 6000.0,
        "sb3_vs_benchmarl_train_steps_ratio": 0.5,
    }


def test_the_benchmarks_rllib_figures_are_sampled_rates_named_as_its_goals(local_ray, monkeypatch):
    assert distributed_timing._sampled_steps_per_second(2, 0, 100, TEAM_ID) > 0  # two remote runners sample at once
    rates = {(1, TEAM_ID): 300.0, (2, TEAM_ID): 450.0, (1, EXPLORATION_ID): 900.0}  # one runner samples as training's
    monkeypatch.setattr(
        distributed_timing, "_sampled_steps_per_second", lambda runners, _, __, env: rates[runners, env]
    )
    figures = distributed_timing.rllib_runner_figures(steps=100)
    assert figures == {
        "rllib_team_1_runner_steps_per_s": 300.0,
        "rllib_team_2_runners_steps_per_s": 450.0,
        "rllib_team_2_runners_vs_1_ratio": 1.5,
        "rllib_exploration_1_runner_steps_per_s": 900.0,
    }
    assert {name for name in GOALS if name.startswith("rllib_")} <= set(figures)
