"""How fast each training backend learns on the exploration env: robot steps per second of PPO training (rollouts
and updates), every backend with the same hyperparameters (the env's ``ppo.yml`` block), timed after a warm-up
iteration, in one process: Stable-Baselines3, and RLlib and BenchMARL where installed. A team step of R robots counts
R steps, as SB3's slots count them."""

from __future__ import annotations

import importlib.util
import tempfile
import time
from pathlib import Path

from infonav_gym.experiments.distributed_timing import EXPLORATION_ID, rllib_missing

EXPLORATION_CONFIG = {"observe_gains": True}  # the config the exploration models are trained on


def training_block(n_envs: int | None = None) -> dict:
    """The exploration env's shipped PPO block, a schedule at its start value (RLlib takes numbers); ``n_envs``
    (``None``: the block's) copies per rollout, the minibatch at most a rollout."""
    from agents.ppo import load_hyperparameters, schedule_start, scheduled

    block = load_hyperparameters(EXPLORATION_ID)
    block.update({key: schedule_start(value) for key, value in scheduled(block).items()})
    if n_envs is None:
        return block
    return {**block, "n_envs": n_envs, "batch_size": min(block["batch_size"], n_envs * block["n_steps"])}


def sb3_train_steps_per_s(seed: int = 0, iterations: int = 2, n_envs: int | None = None) -> float:
    """Robot steps/s of Stable-Baselines3's MaskablePPO over ``iterations`` rollouts and updates."""
    from agents.ppo import build_model, torch_threads

    with torch_threads():
        model = build_model(EXPLORATION_ID, seed, None, training_block(n_envs), EXPLORATION_CONFIG)
        rollout = model.n_steps * model.n_envs
        try:
            model.learn(rollout)  # warm-up: the compiled kernels, the first episodes
            before, start = model.num_timesteps, time.perf_counter()
            model.learn(iterations * rollout, reset_num_timesteps=False)
            return (model.num_timesteps - before) / (time.perf_counter() - start)
        finally:
            model.get_env().close()


def rllib_train_steps_per_s(seed: int = 0, iterations: int = 1, n_envs: int | None = None) -> float:
    """Robot steps/s of RLlib's PPO (one env runner, as ``infonav train --backend rllib`` by default) over
    ``iterations`` training iterations."""
    from agents.ppo import torch_threads
    from agents.ray_support import local_or_cluster_ray
    from agents.rllib_train import build_config
    from infonav_gym.registry import make_env

    robots = len(make_env(EXPLORATION_ID, **EXPLORATION_CONFIG).possible_agents)
    with local_or_cluster_ray(), torch_threads():
        algorithm = build_config(EXPLORATION_ID, EXPLORATION_CONFIG, seed, training_block(n_envs)).build_algo()
        try:
            sampled = [algorithm.train()["env_runners"]["num_env_steps_sampled_lifetime"]]  # warm-up
            start = time.perf_counter()
            for _ in range(iterations):
                sampled.append(algorithm.train()["env_runners"]["num_env_steps_sampled_lifetime"])
            return robots * (sampled[-1] - sampled[0]) / (time.perf_counter() - start)
        finally:
            algorithm.stop()


def benchmarl_missing() -> str | None:
    """Why the BenchMARL figure is absent (BenchMARL does not import), or None."""
    if importlib.util.find_spec("benchmarl") is None:
        return 'BenchMARL figure absent: benchmarl is not installed; pip install "infonav-gym[marl]"'
    return None


def benchmarl_train_steps_per_s(seed: int = 0, iterations: int = 2, n_envs: int | None = None) -> float:
    """Robot steps/s of BenchMARL's MAPPO (its critic centralised) over ``iterations`` collections and updates,
    timed from the end of the first collection to the end of the last."""
    from agents.base import torch_threads
    from agents.benchmarl_train import CollectionClock, benchmarl_output, benchmarl_settings, build_experiment
    from infonav_gym.registry import make_env

    robots = len(make_env(EXPLORATION_ID, **EXPLORATION_CONFIG).possible_agents)
    settings, clock = benchmarl_settings(training_block(n_envs)), CollectionClock()
    frames = settings["experiment"]["on_policy_collected_frames_per_batch"]  # team steps per collection
    with tempfile.TemporaryDirectory() as folder, torch_threads(), benchmarl_output(False):
        args = (EXPLORATION_ID, "mappo", (iterations + 1) * frames, seed, EXPLORATION_CONFIG, settings, Path(folder))
        build_experiment(*args, [clock]).run()
    return robots * frames * iterations / (clock.times[iterations] - clock.times[0])


def training_figures(seed: int = 0, n_envs: int | None = None) -> dict:
    """``{backend}_train_steps_per_s`` of every backend installed here, and SB3's ratio over each other one;
    ``n_envs`` (``None``: the block's) copies per rollout, fewer for a quick run."""
    sb3 = sb3_train_steps_per_s(seed, n_envs=n_envs)
    figures = {"sb3_train_steps_per_s": sb3, "train_n_envs": n_envs or training_block()["n_envs"]}
    if not rllib_missing():
        rllib = rllib_train_steps_per_s(seed, n_envs=n_envs)
        figures.update(rllib_train_steps_per_s=rllib, sb3_vs_rllib_train_steps_ratio=sb3 / rllib)
    if not benchmarl_missing():
        benchmarl = benchmarl_train_steps_per_s(seed, n_envs=n_envs)
        figures.update(benchmarl_train_steps_per_s=benchmarl, sb3_vs_benchmarl_train_steps_ratio=sb3 / benchmarl)
    return figures
