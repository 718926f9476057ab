"""PPO training, the PPO agent and ``infonav evaluate`` with it: smoke runs, reproducibility, errors for people."""

import json
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

import infonav_gym  # noqa: E402, F401  (registers the envs)
from agents.ppo import InfoActionMask, PPOAgent, load_hyperparameters  # noqa: E402
from infonav_gym.experiments.cli import main  # noqa: E402

# PPO training: slow; `pytest -m "not slow"` leaves it out while developing
pytestmark = pytest.mark.slow

LANDMARK_ID = "infonav/LandmarkSelection-v0"


def run_json(capsys, *argv) -> dict:
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> dict:
    """One ``infonav train`` run shared by the tests of this module (about 2 s)."""
    output = tmp_path_factory.mktemp("ppo")
    assert main(["train", "--env", LANDMARK_ID, "--timesteps", "4096", "--output", str(output), "--json"]) == 0
    return json.loads((output / "train.json").read_text())


def test_train_writes_a_maskable_model_checkpoints_and_a_record(trained):
    model = trained["model"]
    assert trained["algorithm"] == "MaskablePPO" and trained["env_id"] == LANDMARK_ID
    assert (
        trained["timesteps"] == 4096 == trained["rollout"] and trained["n_envs"] == 64 and trained["torch_threads"] == 1
    )
    assert trained["vectorization"] == "native", "the default where the env has a native vector env"
    assert trained["hyperparameters"] == {**load_hyperparameters(LANDMARK_ID), "n_envs": 64}
    assert zipfile.is_zipfile(model)
    assert len(list(Path(model).parent.glob("checkpoints/ppo_*_steps.zip"))) >= 3


def test_ppo_agent_acts_deterministically_and_never_picks_a_masked_action(trained):
    env = gym.make(LANDMARK_ID)
    agent = PPOAgent(trained["model"], env)
    observation, info = env.reset(seed=3)
    for _ in range(40):
        action = agent.act(observation, info)
        assert info["action_mask"][action] or not info["action_mask"].any()
        assert agent.act(observation, info) == action
        observation, _, _, _, info = env.step(action)
    only = np.zeros(env.action_space.n, dtype=np.int8)
    only[5] = 1
    assert agent.act(observation, {**info, "action_mask": only}) == 5


def test_action_mask_wrapper_hands_the_last_info_mask_to_maskable_ppo():
    env = InfoActionMask(gym.make(LANDMARK_ID))
    _, info = env.reset(seed=0)
    partial_masks = 0
    for _ in range(60):
        mask = info["action_mask"].astype(bool)
        expected = mask if mask.any() else np.ones_like(mask)  # nothing visible: every action is a no-op
        np.testing.assert_array_equal(env.action_masks(), expected)
        partial_masks += 0 < mask.sum() < mask.size
        _, _, _, _, info = env.step(int(np.flatnonzero(expected)[0]))
    assert partial_masks > 0


def test_evaluate_with_ppo_is_reproducible_and_writes_tables_and_a_plot(capsys, tmp_path, trained):
    agents = f"random,greedy,ppo:{trained['model']}"
    argv = ["evaluate", "--env", LANDMARK_ID, "--agents", agents, "--episodes", "3", "--config", "horizon=40"]
    first, second = run_json(capsys, *argv), run_json(capsys, *argv)
    assert first == second
    assert list(first["agents"]) == ["random", "greedy", f"ppo:{trained['model']}"] and first["seeds"] == [0, 1, 2]
    ppo = first["agents"][f"ppo:{trained['model']}"]
    assert len(ppo["episodes"]) == 3 and all(episode["cumulative_mi"] > 0 for episode in ppo["episodes"])
    written = run_json(capsys, *argv, "--output", str(tmp_path / "eval"))["files"]
    assert [path.rsplit(".", 1)[-1] for path in written] == ["md", "csv", "json", "png"]
    assert (tmp_path / "eval.png").stat().st_size > 10_000


@pytest.mark.parametrize(
    "argv, message",
    [
        (["evaluate", "--env", "infonav/Nowhere-v0", "--episodes", "1"], "unknown env id 'infonav/Nowhere-v0'"),
        (["evaluate", "--agents", "greedy,oracle", "--episodes", "1"], "unknown agent 'oracle'"),
        (["evaluate", "--agents", "ppo:", "--episodes", "1"], "unknown agent 'ppo:'"),
        (["evaluate", "--agents", "ppo:/no/such/model.zip", "--episodes", "1"], "'/no/such/model.zip' does not exist"),
        (["train", "--env", "infonav/Nowhere-v0", "--timesteps", "10"], "unknown env id 'infonav/Nowhere-v0'"),
    ],
)
def test_bad_input_exits_2_with_one_line_naming_it(capsys, argv, message):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    error = capsys.readouterr().err
    assert exit_info.value.code == 2 and message in error
    assert error.count("\n") == 1 and "Traceback" not in error


@pytest.mark.parametrize(
    "env_id, vectorization, why, available",
    [
        ("CartPole-v1", "native", "no native vector env in the registry", "sync, subprocess"),
        (
            "cooperative_localization_v0",
            "sync",
            "a team trains on its robots' slots of its batched vector env",
            "native",
        ),
        (
            "cooperative_localization_v0",
            "subprocess",
            "a team trains on its robots' slots of its batched vector env",
            "native",
        ),
    ],
)
def test_a_vectorization_the_env_lacks_is_one_line_naming_the_env_and_its_modes(
    capsys, tmp_path, env_id, vectorization, why, available
):
    argv = ["train", "--env", env_id, "--timesteps", "8", "--vectorization", vectorization]
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--output", str(tmp_path / "out")])
    error = capsys.readouterr().err
    expected = f"env {env_id!r} cannot train with vectorization {vectorization!r} ({why}); it has: {available}"
    assert exit_info.value.code == 2 and expected in error and error.count("\n") == 1


def test_the_default_vectorization_is_native_where_the_registry_has_a_native_vector_env():
    from agents.ppo import checked_vectorization, vectorizations

    assert vectorizations(LANDMARK_ID) == ("native", "sync", "subprocess")
    assert checked_vectorization(LANDMARK_ID, None) == "native"
    assert checked_vectorization("infonav/ActiveLocalization-v0", None) == "native"
    assert checked_vectorization("infonav/RangeRegistration-v0", None) == "native"
    assert vectorizations("cooperative_localization_v0") == ("native",)  # its robots' slots of the batched env
    assert checked_vectorization("CartPole-v1", None) == "sync"
    with pytest.raises(ValueError, match="vectorization must be one of native, sync, subprocess, got 'threads'"):
        checked_vectorization(LANDMARK_ID, "threads")


@pytest.mark.parametrize("vectorization", ["native", "sync"])
def test_each_vectorization_seeds_sub_env_i_with_seed_plus_i_and_records_its_mode(tmp_path, vectorization):
    from stable_baselines3.common.vec_env import DummyVecEnv

    from agents.ppo import build_model, train
    from agents.vector_adapter import VectorEnvAdapter
    from infonav_gym.envs.landmark_selection import LandmarkSelectionVectorEnv

    small = {**load_hyperparameters(LANDMARK_ID), "n_steps": 16, "batch_size": 32, "n_epochs": 1}
    model = build_model(LANDMARK_ID, seed=4, n_envs=3, hyperparameters=small, vectorization=vectorization)
    vec_env = model.get_env()
    if vectorization == "native":
        assert isinstance(vec_env.venv, VectorEnvAdapter)
        assert isinstance(vec_env.venv.vector_env.unwrapped, LandmarkSelectionVectorEnv)
        seeds = vec_env.venv._seeds
    else:
        assert isinstance(vec_env, DummyVecEnv)
        seeds = vec_env._seeds
    assert seeds == [4, 5, 6]
    vec_env.close()
    path = train(
        LANDMARK_ID,
        48,
        seed=4,
        n_envs=3,
        output_dir=tmp_path,
        hyperparameters=small,
        progress=False,
        vectorization=vectorization,
        checkpoints=0,
    )
    record = json.loads((path.parent / "train.json").read_text())
    assert record["vectorization"] == vectorization and record["n_envs"] == 3 and record["timesteps"] == 48


def test_a_corrupt_or_mismatched_model_is_an_error_not_a_traceback(capsys, tmp_path, trained):
    corrupt = tmp_path / "corrupt.zip"
    corrupt.write_bytes(b"not a zip file")
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--agents", f"ppo:{corrupt}", "--episodes", "1"])
    error = capsys.readouterr().err
    assert exit_info.value.code == 2 and f"cannot load PPO model '{corrupt}'" in error and error.count("\n") == 1
    with pytest.raises(SystemExit) as exit_info:  # trained with 8 candidates, evaluated with 4
        main(["evaluate", "--agents", f"ppo:{trained['model']}", "--config", "n_candidates=4", "--episodes", "1"])
    error = capsys.readouterr().err
    assert exit_info.value.code == 2 and "was trained for observations (50,)" in error


def test_planner_is_imported_lazily_and_named_in_the_error_when_missing(capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "agents.planner", None)  # makes ``import agents.planner`` fail
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--env", "infonav/ActiveLocalization-v0", "--agents", "greedy,planner", "--episodes", "1"])
    error = capsys.readouterr().err
    assert exit_info.value.code == 2 and "agent 'planner' is not available" in error and error.count("\n") == 1


# ---------------------------------------------------------------- observation normalization (VecNormalize)


@pytest.fixture(scope="module")
def normalized(tmp_path_factory) -> Path:
    """A model trained with ``normalize`` (observations only): its ``model.zip`` path."""
    from agents.ppo import train

    hyperparameters = {**load_hyperparameters(LANDMARK_ID), "normalize": {"norm_obs": True, "norm_reward": False}}
    hyperparameters.update(n_steps=64, batch_size=64)
    output = tmp_path_factory.mktemp("ppo_normalized")
    return train(LANDMARK_ID, 1024, n_envs=4, output_dir=output, hyperparameters=hyperparameters, progress=False)


def test_normalized_training_saves_the_statistics_and_the_agent_applies_them(normalized):
    import torch

    from agents.ppo import NORMALIZATION_FILE

    assert (normalized.parent / NORMALIZATION_FILE).is_file()
    assert list(normalized.parent.glob("checkpoints/ppo_vecnormalize_*_steps.pkl"))
    env = gym.make(LANDMARK_ID)
    agent = PPOAgent(normalized, env)
    statistics = agent.normalization.obs_rms
    assert statistics.count > 1000 and not np.allclose(statistics.mean, 0.0)
    observation, info = env.reset(seed=1)
    scaled = np.clip((observation - statistics.mean) / np.sqrt(statistics.var + 1e-8), -10.0, 10.0)
    with torch.no_grad():
        tensor, _ = agent.model.policy.obs_to_tensor(scaled.astype(np.float32))
        logits = agent.model.policy.get_distribution(tensor).distribution.logits[0].numpy()
    assert agent.act(observation, info) == int(np.argmax(np.where(info["action_mask"], logits, -np.inf)))

    class Replace:  # the policy must see what normalize_obs returns, whatever the raw observation
        @staticmethod
        def normalize_obs(_):
            return np.full(env.observation_space.shape, 3.0, dtype=np.float32)

    agent.normalization = Replace()
    with torch.no_grad():
        tensor, _ = agent.model.policy.obs_to_tensor(Replace.normalize_obs(None))
        logits = agent.model.policy.get_distribution(tensor).distribution.logits[0].numpy()
    every = {**info, "action_mask": np.ones(env.action_space.n, dtype=np.int8)}
    assert agent.act(observation, every) == int(np.argmax(logits))
    assert agent.act(np.zeros_like(observation), every) == int(np.argmax(logits))


def test_corrupt_statistics_or_a_bad_normalize_setting_is_a_clear_error(tmp_path, normalized):
    from agents.ppo import NORMALIZATION_FILE, build_model

    model = tmp_path / "model.zip"
    model.write_bytes(normalized.read_bytes())
    (tmp_path / NORMALIZATION_FILE).write_bytes(b"not a pickle")
    with pytest.raises(ValueError, match="cannot load observation normalization .*vecnormalize.pkl"):
        PPOAgent(model, gym.make(LANDMARK_ID))
    with pytest.raises(
        ValueError, match="unknown hyperparameter 'norm_observations' of normalize: the keys are norm_obs"
    ):
        build_model(LANDMARK_ID, hyperparameters={"normalize": {"norm_observations": True}}, n_envs=1)
