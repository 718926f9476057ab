"""BenchMARL's MAPPO and IPPO on the team envs (``infonav train --backend benchmarl``, the ``marl`` extra).

BenchMARL's own configs (``get_from_yaml``) with the env's ppo.yml block translated (``benchmarl_settings``), no
loggers and no evaluation; one policy shared by the robots. Writes the actor's weights (``actor.pt``), ``train.json``
(with what rebuilds the actor: ``load_actor``) and a learning curve of the mean return per robot.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import math
import os
import shutil
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch
from benchmarl import algorithms
from benchmarl.experiment import Experiment, ExperimentConfig
from benchmarl.experiment.callback import Callback
from benchmarl.models.common import Model
from benchmarl.models.mlp import MlpConfig
from tensordict import TensorDict
from torchrl.data import Composite, Unbounded
from torchrl.envs.transforms import ObservationNorm

from agents.base import torch_threads
from agents.benchmarl_task import TASK_ENVS, InfonavTask, InfonavTaskClass
from agents.hyperparameters import ACTIVATIONS, checked_block
from agents.learning_curve import append_row, drawn_curve, start_curve
from agents.torchrl_env import GROUP, InfonavTorchEnv
from infonav_gym.compiled import INTERRUPTIONS, pressed_ctrl_c
from infonav_gym.registry import make_env

ALGORITHMS = {"mappo": "MappoConfig", "ippo": "IppoConfig"}  # --algorithm: its BenchMARL config class
ACTOR_FILE = "actor.pt"  # the policy's MLP weights (its state dict)
RUN_DIR = "benchmarl_run"  # BenchMARL's experiment folder inside the output, removed after training
EXPERIMENT_NAMES = {"gamma": "gamma", "learning_rate": "lr"}  # ppo.yml key: its ExperimentConfig name
ALGORITHM_NAMES = {"gae_lambda": "lmbda", "ent_coef": "entropy_coef", "clip_range": "clip_epsilon"}
ROLLOUT_DEFAULTS = {"n_envs": 8, "n_steps": 2048, "batch_size": 64, "n_epochs": 10}  # SB3's, as ppo.py's
OBSERVATION_NORM_STEPS = 200  # random-action team steps per copy whose observations set the standardization


def check_arguments(env_id: str, algorithm: str, timesteps: int, env_kwargs: dict, hyperparameters: dict) -> None:
    """``ValueError`` for an algorithm, env, config, timesteps or hyperparameter training would fail on."""
    if algorithm not in ALGORITHMS:
        raise ValueError(
            f"--algorithm must be one of {', '.join(ALGORITHMS)} with --backend benchmarl, got {algorithm!r}"
        )
    if env_id not in TASK_ENVS.values():
        raise ValueError(f"--backend benchmarl trains the team envs ({', '.join(TASK_ENVS.values())}), not {env_id!r}")
    if timesteps < 1:
        raise ValueError(f"timesteps must be >= 1, got {timesteps}")
    make_env(env_id, **env_kwargs).close()  # an unknown config key: the message ``infonav evaluate`` gives
    benchmarl_settings(hyperparameters)


def benchmarl_settings(hyperparameters: dict) -> dict:
    """The ppo.yml block as BenchMARL's settings: ``{"experiment": ..., "algorithm": ..., "model": ...,
    "observation_norm": ...}``; a rollout of ``n_envs`` copies x ``n_steps`` team steps, minibatches of ``batch_size``
    team steps, ``n_epochs`` passes; ``normalize``'s ``norm_obs``: observations standardized (``StandardizedTask``).
    ``ValueError`` for a schedule (BenchMARL takes numbers)."""
    from agents.ppo import normalization_kwargs

    block = checked_block(hyperparameters, "the hyperparameters")
    normalize = normalization_kwargs(block)
    schedules = sorted(key for key, value in block.items() if isinstance(value, str) and key != "policy")
    if schedules:
        raise ValueError(f"hyperparameter(s) {schedules} are schedules: --backend benchmarl takes numbers")
    rollout = {key: int(block.get(key, default)) for key, default in ROLLOUT_DEFAULTS.items()}
    frames = rollout["n_envs"] * rollout["n_steps"]
    minibatch = min(rollout["batch_size"], frames)
    experiment = {name: float(block[key]) for key, name in EXPERIMENT_NAMES.items() if key in block}
    experiment |= {
        "on_policy_n_envs_per_worker": rollout["n_envs"],
        "on_policy_collected_frames_per_batch": frames,
        "on_policy_minibatch_size": minibatch,
        "on_policy_n_minibatch_iters": rollout["n_epochs"] * math.ceil(frames / minibatch),
    }
    policy_kwargs = block.get("policy_kwargs") or {}
    return {
        "experiment": experiment,
        "algorithm": {name: float(block[key]) for key, name in ALGORITHM_NAMES.items() if key in block},
        "model": {
            "num_cells": list(policy_kwargs.get("net_arch", [64, 64])),
            "activation": policy_kwargs.get("activation_fn", "tanh"),
        },
        "observation_norm": normalize is not None and bool(normalize.get("norm_obs", True)),
    }


def mlp_config(model: dict) -> MlpConfig:
    """BenchMARL's ``MlpConfig`` (its yaml) with ``model``'s ``num_cells`` and ``activation``."""
    config = MlpConfig.get_from_yaml()
    config.num_cells = list(model["num_cells"])
    config.activation_class = getattr(torch.nn, ACTIVATIONS[model["activation"]])
    return config


class StandardizedTask(InfonavTaskClass):
    """A team env's task whose observations are standardized, ``(observation - loc) / scale`` (TorchRL's
    ``ObservationNorm``), with fixed ``loc`` and ``scale``."""

    def __init__(self, name: str, config: dict, loc: torch.Tensor, scale: torch.Tensor):
        super().__init__(name, config)
        self.loc, self.scale = loc, scale

    def get_env_transforms(self, env) -> list:
        return [ObservationNorm(self.loc, self.scale, in_keys=[(GROUP, "observation")], standard_normal=True)]


def observation_statistics(env_id: str, env_kwargs: dict, copies: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The mean and standard deviation (1 where it is 0) of each observation entry of ``copies`` copies' robots over
    ``OBSERVATION_NORM_STEPS`` steps of random actions (invalid ones as the env takes them)."""
    env = InfonavTorchEnv(env_id, copies, seed=seed, **env_kwargs)
    try:
        observations = env.rollout(OBSERVATION_NORM_STEPS, break_when_any_done=False)[GROUP, "observation"]
    finally:
        env.close()
    observations = observations.reshape(-1, observations.shape[-1])
    scale = observations.std(0)
    return observations.mean(0), torch.where(scale > 0, scale, torch.ones_like(scale))


def build_experiment(env_id, algorithm, timesteps, seed, env_kwargs, settings, folder: Path, callbacks) -> Experiment:
    """The BenchMARL ``Experiment`` of ``settings`` (``benchmarl_settings``), on the CPU, saving into ``folder``."""
    config = ExperimentConfig.get_from_yaml()
    config.sampling_device = config.train_device = config.buffer_device = "cpu"
    config.loggers, config.create_json, config.render, config.evaluation = [], False, False, False
    config.checkpoint_interval, config.checkpoint_at_end, config.save_folder = 0, False, str(folder)
    config.max_n_frames = timesteps
    for key, value in settings["experiment"].items():
        setattr(config, key, value)
    algorithm_config = getattr(algorithms, ALGORITHMS[algorithm]).get_from_yaml()
    for key, value in settings["algorithm"].items():
        setattr(algorithm_config, key, value)
    task = getattr(InfonavTask, next(name for name, env in TASK_ENVS.items() if env == env_id)).get_task(env_kwargs)
    if settings["observation_norm"]:
        loc, scale = observation_statistics(env_id, env_kwargs, config.on_policy_n_envs_per_worker, seed)
        task = StandardizedTask(task.name, task.config, loc, scale)
    folder.mkdir(parents=True, exist_ok=True)
    model = mlp_config(settings["model"])
    return Experiment(task, algorithm_config, model, seed, config, critic_model_config=model, callbacks=callbacks)


def actor_model(experiment: Experiment) -> Model:
    """The MLP of the experiment's policy: observations to logits."""
    return next(module for module in experiment.group_policies[GROUP].modules() if isinstance(module, Model))


def load_actor(record: dict, path: Path) -> Model:
    """The actor MLP of a ``train.json`` ``record``, its weights read from ``path`` (``ACTOR_FILE``)."""
    actor, shape = record["actor"], (record["actor"]["n_agents"], *record["actor"]["observation_shape"])
    specs = [
        Composite({GROUP: Composite({key: Unbounded(shape=size)}, shape=shape[:1])})
        for key, size in (("observation", shape), ("logits", (shape[0], actor["n_actions"])))
    ]
    model = mlp_config(record["benchmarl"]["model"]).get_model(
        input_spec=specs[0],
        output_spec=specs[1],
        agent_group=GROUP,
        input_has_agent_dim=True,
        n_agents=shape[0],
        centralised=False,
        share_params=record["benchmarl"]["share_params"],
        device="cpu",
        action_spec=None,
    )
    model.load_state_dict(torch.load(path, weights_only=True))
    return model.eval()


def observation_standardization(record: dict) -> tuple[np.ndarray, np.ndarray]:
    """``(loc, scale)`` of the observations a ``train.json`` ``record``'s actor read (0 and 1 if raw)."""
    shape = record["actor"]["observation_shape"]
    norm = record["benchmarl"].get("observation_loc"), record["benchmarl"].get("observation_scale")
    if norm[0] is None:
        return np.zeros(shape, dtype=np.float32), np.ones(shape, dtype=np.float32)
    return tuple(np.asarray(values, dtype=np.float32) for values in norm)


def robot_logits(model: Model, robot: int, loc: np.ndarray, scale: np.ndarray, observation) -> np.ndarray:
    """The logits ``model`` gives robot ``robot`` for its ``observation`` standardized by ``loc`` and ``scale`` (its
    row of the team's input, the others zero: a decentralised actor reads each robot's row alone)."""
    team = torch.zeros((model.n_agents, *model.input_spec[GROUP, "observation"].shape[1:]))
    team[robot] = torch.as_tensor((np.asarray(observation, dtype=np.float32) - loc) / scale)
    with torch.no_grad():
        return model(TensorDict({GROUP: {"observation": team[None]}}, batch_size=[1]))[GROUP, "logits"][
            0, robot
        ].numpy()


@contextlib.contextmanager
def benchmarl_output(progress: bool):
    """BenchMARL's progress bar and prints on stderr (stdout is ``--json``'s), or nowhere without ``progress``;
    TorchRL's INFO lines off (its console handler writes to stdout)."""
    logger = logging.getLogger("torchrl")
    level = logger.level
    logger.setLevel(logging.WARNING)
    try:
        with open(os.devnull, "w") as devnull:
            shown = sys.stderr if progress else devnull
            with contextlib.redirect_stdout(shown), contextlib.redirect_stderr(shown):
                yield
    finally:
        logger.setLevel(level)


def standardization(task) -> dict:
    """``observation_loc`` and ``observation_scale`` of a ``StandardizedTask`` as lists; none of a raw one."""
    if not isinstance(task, StandardizedTask):
        return {}
    return {"observation_loc": task.loc.tolist(), "observation_scale": task.scale.tolist()}


class CollectionClock(Callback):
    """When each collection ended (``times``, ``time.perf_counter`` seconds): the benchmark's training rate."""

    def __init__(self):
        super().__init__()
        self.times = []

    def on_batch_collected(self, batch):
        self.times.append(time.perf_counter())


class CurveRows(Callback):
    """A ``curve.csv`` row per collection in which episodes ended: BenchMARL's mean return (per robot)."""

    def __init__(self, path: Path):
        super().__init__()
        self.path = path

    def on_batch_collected(self, batch):
        episodes = int(batch.get(("next", "done")).sum())
        if episodes:
            append_row(self.path, self.experiment.total_frames, self.experiment.mean_return, math.nan, episodes)


def train_benchmarl(
    env_id: str,
    timesteps: int,
    output_dir: Path | str,
    algorithm: str = "mappo",
    seed: int = 0,
    env_kwargs: dict | None = None,
    hyperparameters: dict | None = None,
    progress: bool = True,
    curve_references: dict | None = None,
) -> dict:
    """Train BenchMARL's ``algorithm`` on team env ``env_id`` for at least ``timesteps`` team steps (BenchMARL's
    frames); save the actor (also on Ctrl-C: ``"interrupted": true``) and return the ``train.json`` record."""
    from agents.ppo import load_hyperparameters

    env_kwargs = dict(env_kwargs or {})
    hyperparameters = load_hyperparameters(env_id) if hyperparameters is None else hyperparameters
    check_arguments(env_id, algorithm, timesteps, env_kwargs, hyperparameters)
    settings = benchmarl_settings(hyperparameters)
    output_dir = Path(output_dir)
    curve = start_curve(output_dir, env_id, env_kwargs)
    interrupted, start = False, time.perf_counter()
    with torch_threads(), warnings.catch_warnings(), benchmarl_output(progress):
        warnings.filterwarnings("ignore", message="No episode terminated this iteration")
        experiment = build_experiment(
            env_id, algorithm, timesteps, seed, env_kwargs, settings, output_dir / RUN_DIR, [CurveRows(curve)]
        )
        try:
            experiment.run()  # BenchMARL's progress bar
        except INTERRUPTIONS as error:
            if not pressed_ctrl_c(error):
                raise
            interrupted = True
        finally:
            shutil.rmtree(output_dir / RUN_DIR, ignore_errors=True)
    seconds = time.perf_counter() - start
    model = actor_model(experiment)
    torch.save(model.state_dict(), output_dir / ACTOR_FILE)
    title = f"{env_id}: {algorithm.upper()} (BenchMARL), seed {seed}"
    record = {
        "env_id": env_id,
        "algorithm": f"{algorithm.upper()} (BenchMARL)",
        "backend": "benchmarl",
        "benchmarl_algorithm": algorithm,
        "timesteps": experiment.total_frames,
        "seed": seed,
        "n_envs": settings["experiment"]["on_policy_n_envs_per_worker"],
        "env_kwargs": env_kwargs,
        "hyperparameters": hyperparameters,
        "benchmarl": settings
        | {"algorithm_config": dataclasses.asdict(experiment.algorithm_config), "share_params": model.share_params}
        | standardization(experiment.task),
        "actor": {
            "file": str(output_dir / ACTOR_FILE),
            "n_agents": model.n_agents,
            "observation_shape": list(model.input_spec[GROUP, "observation"].shape[1:]),
            "n_actions": int(model.output_spec[GROUP, "logits"].shape[-1]),
        },
        "seconds": seconds,
        "fps": experiment.total_frames / seconds,
        "interrupted": interrupted,
        "curve": drawn_curve(output_dir, title, curve_references),
    }
    (output_dir / "train.json").write_text(json.dumps(record, indent=2) + "\n")
    return record
