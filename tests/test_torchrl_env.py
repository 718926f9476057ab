"""The suite's TorchRL env (``agents.torchrl_env``) and BenchMARL tasks (``agents.benchmarl_task``): TorchRL's spec
check on every env, the same trajectory as the native vector env across episode ends, its partial resets, and
BenchMARL's MAPPO, IPPO and QMIX training on the team envs."""

import numpy as np
import pytest

pytest.importorskip("torchrl")
import torch  # noqa: E402
from torchrl.envs.utils import check_env_specs  # noqa: E402

from agents.torchrl_env import GROUP, InfonavTorchEnv  # noqa: E402
from infonav_gym.experiments.vector_timing import random_valid_actions  # noqa: E402
from infonav_gym.registry import PARALLEL, available_envs, make_vector_env  # noqa: E402


def short_config(entry) -> dict:
    """Four-step episodes: a team's ``max_cycles``, a single env's ``horizon``."""
    return {"max_cycles": 4} if entry.api == PARALLEL else {"horizon": 4}


CHECKED = [entry for entry in available_envs() if entry.api == PARALLEL or entry.id == "infonav/LandmarkSelection-v0"]


@pytest.mark.parametrize("entry", CHECKED, ids=lambda entry: entry.id)
def test_torchrl_checks_the_specs_of_the_team_envs_and_a_single_env(entry):
    env = InfonavTorchEnv(entry.id, 2, seed=0, **short_config(entry))
    try:
        check_env_specs(env, seed=None)
        assert env.batch_size == torch.Size([2]) and (GROUP in env.observation_spec.keys()) == (entry.api == PARALLEL)
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ["cooperative_exploration_v0", "infonav/LandmarkSelection-v0"])
def test_a_rollout_is_the_native_vector_envs_trajectory_across_episode_ends(env_id):
    team = env_id == "cooperative_exploration_v0"
    config = {"max_cycles": 3} if team else {"horizon": 3}
    env = InfonavTorchEnv(env_id, 2, seed=5, **config)
    native = make_vector_env(env_id, 2, autoreset_mode="SameStep", **config)
    key = (lambda name: (GROUP, name)) if team else (lambda name: name)
    rng = np.random.default_rng(0)
    td = env.reset()
    observation, _ = native.reset(seed=5)
    ends = 0
    for _ in range(7):  # two episode ends and a step into the third episode
        np.testing.assert_array_equal(td.get(key("observation")).numpy(), observation)
        np.testing.assert_array_equal(td.get(key("action_mask")).numpy(), native.action_masks())
        actions = random_valid_actions(native.action_masks(), rng)
        td.set(key("action"), torch.from_numpy(actions))
        stepped, td = env.step_and_maybe_reset(td)
        observation, reward, terminated, truncated, info = native.step(actions)
        done = np.logical_or(terminated, truncated)
        done = done[:, 0] if team else done
        reward = reward.astype(np.float32)  # TorchRL's rewards are float32
        np.testing.assert_array_equal(stepped.get(("next", *np.atleast_1d(key("reward"))))[..., 0].numpy(), reward)
        np.testing.assert_array_equal(stepped.get(("next", "done"))[:, 0].numpy(), done)
        if done.any():
            ends += 1
            last = np.stack(list(info["final_obs"][done]))
            np.testing.assert_array_equal(stepped.get(("next", *np.atleast_1d(key("observation"))))[done], last)
    assert ends == 2
    env.close()


def test_only_ended_copies_restart_alone():
    env = InfonavTorchEnv("cooperative_localization_v0", 2, seed=0, max_cycles=5)
    td = env.reset()
    td = env.rand_step(td)
    marks = torch.tensor([[True], [False]])
    with pytest.raises(ValueError, match="only copies whose episode ended restart alone; reset them all"):
        env.reset(td.set("_reset", marks))
    everything = env.reset(td.set("_reset", torch.ones(2, 1, dtype=torch.bool)))
    assert not everything.get("done").any()
    env.close()


@pytest.mark.slow  # short trainings: about 20 s together
@pytest.mark.parametrize(
    "algorithm, task",
    [
        ("MappoConfig", "COOPERATIVE_EXPLORATION"),
        ("MappoConfig", "COOPERATIVE_LOCALIZATION"),
        ("IppoConfig", "COOPERATIVE_LOCALIZATION"),
        ("QmixConfig", "COOPERATIVE_LOCALIZATION"),
    ],
)
def test_benchmarl_trains_on_the_team_envs(algorithm, task, tmp_path):
    benchmarl = pytest.importorskip("benchmarl")
    from benchmarl import algorithms
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.models.mlp import MlpConfig

    from agents.benchmarl_task import InfonavTask

    config = ExperimentConfig.get_from_yaml()
    config.sampling_device = config.train_device = config.buffer_device = "cpu"
    config.max_n_frames = 400  # two collections of 200 frames (10 copies of 20 steps)
    for prefix in ("on_policy", "off_policy"):
        setattr(config, f"{prefix}_collected_frames_per_batch", 200)
        setattr(config, f"{prefix}_n_envs_per_worker", 10)
    config.on_policy_n_minibatch_iters, config.on_policy_minibatch_size = 1, 100
    config.off_policy_init_random_frames, config.off_policy_n_optimizer_steps = 0, 2
    config.off_policy_train_batch_size = 50
    config.evaluation, config.evaluation_interval, config.evaluation_episodes = True, 200, 2
    config.render, config.loggers, config.create_json = False, ["csv"], True
    config.checkpoint_interval, config.checkpoint_at_end, config.save_folder = 0, False, str(tmp_path)
    experiment = Experiment(
        task=getattr(InfonavTask, task).get_task({"max_cycles": 20}),
        algorithm_config=getattr(algorithms, algorithm).get_from_yaml(),
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=config,
    )
    experiment.run()
    assert benchmarl.__version__ and experiment.total_frames == 400
    returns = sorted(tmp_path.rglob("eval_reward_episode_reward_mean.csv"))
    assert returns, "BenchMARL wrote no evaluation returns"
    values = [float(line.split(",")[-1]) for line in returns[0].read_text().splitlines() if line]
    assert len(values) == 2 and all(np.isfinite(values))
