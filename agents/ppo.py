"""Stable-Baselines3 PPO for the infonav envs: train, save, load, act (the ``rl`` extra).

``MaskablePPO`` where the env has action masks (a team env: one policy shared by its robots, ``team_vec_env``),
else ``PPO``; copies run ``native`` (the env's own vector env), ``sync`` or ``subprocess``. Hyperparameters are
rl-zoo style blocks keyed by env id (``agents/hyperparams/ppo.yml`` or a file); ``normalize`` adds ``VecNormalize``.
"""

from __future__ import annotations

import contextlib
import copy
import importlib.util
import inspect
import json
import math
import pickle
import shutil
import sys
import time
import zipfile
from importlib import resources
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from gymnasium.vector import AutoresetMode
from sb3_contrib import MaskablePPO
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.utils import LinearSchedule
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor, VecNormalize
from tqdm.auto import tqdm

import infonav_gym  # noqa: F401  (registers the envs, also in SubprocVecEnv workers that unpickle this module)
from agents.base import TORCH_THREADS, checked_action_count, torch_threads, usable_mask
from agents.hyperparameters import ACTIVATIONS, LINEAR, checked_block
from agents.imitation import (
    DEMONSTRATION_SEEDS,
    DEMONSTRATIONS_FILE,
    Demonstrations,
    agreement,
    clone_planner,
    planner_demonstrations,
)
from agents.learning_curve import (
    METRIC_KEY,
    CurveCallback,
    MetricVectorWrapper,
    MetricWrapper,
    drawn_curve,
    start_curve,
)
from agents.planner import planning_model
from agents.validation import VALIDATION_SEEDS, ValidationCallback
from agents.vector_adapter import monitored_vec_env
from infonav_gym.compiled import INTERRUPTIONS, pressed_ctrl_c
from infonav_gym.memory import check_memory
from infonav_gym.registry import PARALLEL, api_of, has_native_vector_env, make_env, resolve_env_id

HYPERPARAMETERS_RESOURCE = ("agents", "hyperparams/ppo.yml")  # (package, file in it): the tuned blocks
SCHEDULED = ("learning_rate", "clip_range")  # may be rl-zoo's "lin_<start>": annealed linearly to 0 over training
DEFAULT_N_ENVS, DEFAULT_N_STEPS = 8, 2048  # without them in the block: ours, SB3's
ROLLOUT_FLOATS = 7  # float32 of a MaskableRolloutBuffer slot beside observation and mask (action, reward, ...)
MODEL_FILE = "model.zip"
NORMALIZATION_FILE = "vecnormalize.pkl"  # VecNormalize statistics, beside MODEL_FILE, when trained with ``normalize``
NATIVE, SYNC, SUBPROCESS = "native", "sync", "subprocess"
VECTORIZATIONS = (NATIVE, SYNC, SUBPROCESS)  # the env's own VectorEnv, DummyVecEnv, SubprocVecEnv


class InfoActionMask(gym.Wrapper):
    """Gives an env ``action_masks()`` from its last ``info["action_mask"]`` (all valid without one, or none valid)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self._mask = np.ones(env.action_space.n, dtype=bool)

    def _remember(self, info: dict) -> None:
        self._mask = np.array(usable_mask(info.get("action_mask"), self.action_space.n))

    def reset(self, **kwargs):
        observation, info = self.env.reset(**kwargs)
        self._remember(info)
        return observation, info

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        self._remember(info)
        return observation, reward, terminated, truncated, info

    def action_masks(self) -> np.ndarray:
        return self._mask


def mask_wrapper(env_id: str, env_kwargs: dict | None = None) -> tuple[bool, type | None]:
    """Whether ``env_id`` has action masks (``MaskablePPO``), and ``InfoActionMask`` if they are only in its infos."""
    env = make_env(env_id, **(env_kwargs or {}))
    try:
        if callable(getattr(env.unwrapped, "action_masks", None)):
            return True, None
        masked = "action_mask" in env.reset(seed=0)[1]
        return masked, InfoActionMask if masked else None
    finally:
        env.close()


def load_hyperparameters(env_id: str, path: Path | str | None = None) -> dict:
    """The block for ``env_id`` (else the ``default`` block) of a ppo.yml-style file at ``path`` (``None``: the blocks
    shipped in the package), a fresh dict; ``ValueError`` naming the file, block and key of any fault."""
    import yaml

    if path is None:
        package, name = HYPERPARAMETERS_RESOURCE
        source, text = f"{package}/{name} (package data)", resources.files(package).joinpath(name).read_text()
    else:
        source = str(path)
        try:
            text = Path(path).read_text()
        except (OSError, UnicodeDecodeError) as error:
            raise ValueError(f"cannot read hyperparameter file {source}: {error.strerror or error}") from None
    try:
        blocks = yaml.safe_load(text)
    except yaml.YAMLError as error:
        message = " ".join(str(error).split())
        raise ValueError(f"hyperparameter file {source} is not valid YAML: {message}") from None
    if not isinstance(blocks, dict):
        raise ValueError(f"hyperparameter file {source} must map env ids to blocks of PPO settings, got {blocks!r}")
    key = env_id if env_id in blocks else "default"
    if key not in blocks:
        raise ValueError(f"hyperparameter file {source} has no block for {env_id!r} and no 'default' block")
    if not isinstance(blocks[key], dict):
        raise ValueError(f"block {key!r} of hyperparameter file {source} must be a mapping, got {blocks[key]!r}")
    return checked_block(copy.deepcopy(blocks[key]), f"block {key!r} of hyperparameter file {source}")


def _constructor_kwargs(hyperparameters: dict) -> dict:
    """Hyperparameters as PPO constructor keywords: drop the others (``not_constructor``), resolve the activation."""
    not_constructor = ("n_envs", "policy", "n_timesteps", "normalize")
    kwargs = {key: value for key, value in hyperparameters.items() if key not in not_constructor}
    for key, value in scheduled(hyperparameters).items():  # rl-zoo's lin_<start>: from start to 0 over training
        kwargs[key] = LinearSchedule(schedule_start(value), 0.0, 1.0)
    policy_kwargs = dict(kwargs.get("policy_kwargs") or {})
    if "activation_fn" in policy_kwargs:
        policy_kwargs["activation_fn"] = getattr(torch.nn, ACTIVATIONS[policy_kwargs["activation_fn"]])
    if policy_kwargs:
        kwargs["policy_kwargs"] = policy_kwargs
    return kwargs


def schedule_start(value: str) -> float:
    """The start of rl-zoo's ``lin_<start>`` schedule."""
    return float(value.removeprefix(LINEAR))


def scheduled(hyperparameters: dict) -> dict:
    """The hyperparameters given as a schedule (``lin_<start>``), not a number: ``{key: value}`` of ``SCHEDULED``."""
    return {key: hyperparameters[key] for key in SCHEDULED if isinstance(hyperparameters.get(key), str)}


def _constructor_arguments(hyperparameters: dict, seed: int, tensorboard_log: str | None) -> tuple[str, dict]:
    """The policy and the keywords ``build_model`` hands the PPO / MaskablePPO constructor."""
    fixed = {"seed": seed, "device": "cpu", "verbose": 0, "tensorboard_log": tensorboard_log}
    return hyperparameters.get("policy", "MlpPolicy"), {**fixed, **_constructor_kwargs(hyperparameters)}


def _json_name(value) -> str:
    """A class or function by its qualified name, anything else by ``repr``: for ``json.dumps(default=...)``."""
    if inspect.isclass(value) or inspect.isfunction(value):
        return f"{value.__module__}.{value.__qualname__}"
    return repr(value)


def constructor_values(algorithm, policy: str, kwargs: dict) -> dict:
    """Every keyword of ``algorithm``'s constructor as called with ``policy`` and ``kwargs``, defaults included,
    JSON-ready (classes by qualified name); ``ValueError`` for a keyword it does not take, listing those it takes."""
    parameters = inspect.signature(algorithm.__init__).parameters
    public = [name for name in parameters if name not in ("self", "env") and not name.startswith("_")]
    unknown = sorted(set(kwargs) - set(public))
    if unknown:
        raise ValueError(
            f"unknown PPO hyperparameter(s) {unknown}: {algorithm.__name__} takes {', '.join(public)} "
            "(and n_envs, normalize)"
        )
    empty = inspect.Parameter.empty
    values = {name: parameters[name].default for name in public if parameters[name].default is not empty}
    return json.loads(json.dumps({**values, "policy": policy, **kwargs}, default=_json_name))


class TqdmCallback(BaseCallback):
    """A tqdm progress bar over training timesteps (SB3's own bar needs ``rich`` as well)."""

    def __init__(self, total: int, disable: bool = False):
        super().__init__()
        self._total, self._disable, self._bar = total, disable, None

    def _on_training_start(self) -> None:
        self._bar = tqdm(total=self._total, desc="training PPO", unit="step", disable=self._disable)

    def _on_step(self) -> bool:
        self._bar.update(self.training_env.num_envs)
        return True

    def _on_training_end(self) -> None:
        self.close()

    def close(self) -> None:
        """End the bar's line (also when training stops early)."""
        if self._bar is not None:
            self._bar.close()


def normalization_kwargs(hyperparameters: dict) -> dict | None:
    """``VecNormalize`` keywords from rl-zoo's ``normalize`` (true, false or a dict of them); ``None`` when off."""
    normalize = hyperparameters.get("normalize", False)
    return dict(normalize) if isinstance(normalize, dict) else ({} if normalize is True else None)


def vectorizations(env_id: str) -> tuple[str, ...]:
    """The vectorizations ``env_id`` trains with, its default first (a team env: ``native`` only)."""
    if api_of(env_id) == PARALLEL:
        return (NATIVE,)
    return (NATIVE, SYNC, SUBPROCESS) if has_native_vector_env(env_id) else (SYNC, SUBPROCESS)


def checked_vectorization(env_id: str, vectorization: str | None) -> str:
    """``vectorization`` if ``env_id`` has it, ``None``: its default (else ``ValueError`` naming the env's modes)."""
    available = vectorizations(env_id)
    if vectorization is None:
        return available[0]
    if vectorization not in VECTORIZATIONS:
        raise ValueError(f"vectorization must be one of {', '.join(VECTORIZATIONS)}, got {vectorization!r}")
    if vectorization not in available:
        why = "no native vector env in the registry"
        if api_of(env_id) == PARALLEL:
            why = "a team trains on its robots' slots of its batched vector env"
        raise ValueError(
            f"env {env_id!r} cannot train with vectorization {vectorization!r} ({why}); it has: {', '.join(available)}"
        )
    return vectorization


def native_vec_env(
    env_id: str, n_envs: int, seed: int, env_kwargs: dict | None = None, record_metric: bool = False
) -> VecMonitor:
    """``env_id``'s own vector env of ``n_envs`` copies in SAME_STEP autoreset as an SB3 ``VecEnv`` (sub-env ``i``
    seeded ``seed + i``); ``record_metric``: an episode's last infos hold its main metric (``METRIC_KEY``)."""
    vector_env = gym.make_vec(
        resolve_env_id(env_id),
        num_envs=n_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode=AutoresetMode.SAME_STEP,
        **(env_kwargs or {}),
    )
    if record_metric:
        return monitored_vec_env(MetricVectorWrapper(vector_env), seed, (METRIC_KEY,))
    return monitored_vec_env(vector_env, seed)


def training_vec_env(
    env_id: str, n_envs: int, seed: int, env_kwargs: dict | None = None, vectorization: str | None = None
) -> tuple[bool, VecMonitor]:
    """Whether ``env_id`` trains with action masks, and ``n_envs`` copies as ``native_vec_env``'s with the metric."""
    vectorization = checked_vectorization(env_id, vectorization)
    if api_of(env_id) == PARALLEL:
        from agents.team_vec_env import make_team_vec_env

        return True, make_team_vec_env(n_envs, seed, env_kwargs, env_id)
    masked, wrapper = mask_wrapper(env_id, env_kwargs)
    if vectorization == NATIVE:
        return masked, native_vec_env(env_id, n_envs, seed, env_kwargs, record_metric=True)
    return masked, make_vec_env(
        env_id,
        n_envs=n_envs,
        seed=seed,
        env_kwargs=env_kwargs,
        wrapper_class=lambda env: MetricWrapper(wrapper(env) if wrapper else env),
        vec_env_cls=SubprocVecEnv if vectorization == SUBPROCESS else DummyVecEnv,
    )


def build_model(
    env_id: str,
    seed: int = 0,
    n_envs: int | None = None,
    hyperparameters: dict | None = None,
    env_kwargs: dict | None = None,
    vectorization: str | None = None,
    tensorboard_log: str | None = None,
):
    """A fresh ``MaskablePPO`` (env with action masks) or ``PPO`` on ``n_envs`` seeded copies of ``env_id``
    (``hyperparameters`` ``None``: the env's block; ``vectorization`` ``None``: the env's default)."""
    hyperparameters = training_block(env_id, hyperparameters, n_envs)
    masked, vec_env = training_vec_env(env_id, hyperparameters["n_envs"], seed, env_kwargs, vectorization)
    normalize = normalization_kwargs(hyperparameters)
    if normalize is not None:
        vec_env = VecNormalize(vec_env, gamma=hyperparameters.get("gamma", 0.99), **normalize)
    policy, kwargs = _constructor_arguments(hyperparameters, seed, tensorboard_log)
    model = (MaskablePPO if masked else PPO)(policy, vec_env, **kwargs)
    return model if tensorboard_log is not None else without_log_folder(model)


def without_log_folder(model):
    """``model`` logging nowhere: SB3's default logger would make an empty SB3-<time> folder in the temp folder."""
    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def training_block(env_id: str, hyperparameters: dict | None, n_envs: int | None) -> dict:
    """The checked hyperparameters training uses (``None``: the env's block), ``n_envs`` as given or the block's."""
    block = load_hyperparameters(env_id) if hyperparameters is None else hyperparameters
    block = {**block, "n_envs": block.get("n_envs", DEFAULT_N_ENVS) if n_envs is None else n_envs}
    return checked_block(block, "the hyperparameters" + (", n_envs as given (--n-envs)" if n_envs is not None else ""))


def rollout_steps(
    env_id: str, hyperparameters: dict, env_kwargs: dict | None, planner: bool = False
) -> tuple[int, str]:
    """The env steps of one PPO rollout (``n_steps x n_envs``, x robots in a team env) and that product in words; builds
    one env, which checks the id, the config and (with ``planner``) that it offers the planner's model."""
    n_steps, n_envs, robots = hyperparameters.get("n_steps", DEFAULT_N_STEPS), hyperparameters["n_envs"], 1
    factors = f"n_steps {n_steps} x n_envs {n_envs}"
    env = make_env(env_id, **(env_kwargs or {}))  # an unknown id or config key: its one-line error, before any work
    if planner:
        planning_model(env)
    observation_space, action_space = env.observation_space, env.action_space
    if api_of(env_id) == PARALLEL:  # PettingZoo: a space per robot
        robots, agent = len(env.possible_agents), env.possible_agents[0]
        observation_space, action_space = observation_space(agent), action_space(agent)
        factors += f" x {robots} robots"
    env.close()
    rollout = n_steps * n_envs * robots
    floats = gym.spaces.flatdim(observation_space) + int(action_space.n) + ROLLOUT_FLOATS
    check_memory(4 * floats * rollout, f"a rollout of {rollout} env steps ({factors}, {floats} float32 each)")
    return rollout, factors


def planned_steps(timesteps: int, rollout: int, factors: str, hyperparameters: dict) -> int:
    """The env steps PPO will train for ``timesteps``: whole rollouts (said on stderr when more). ``ValueError`` for
    fewer than one rollout (but 0: cloning alone), or a ``batch_size`` leaving a 1-step minibatch (NaN advantages)."""
    if 0 < timesteps < rollout:
        raise ValueError(
            f"--timesteps {timesteps} is less than one rollout of {rollout} env steps ({factors}): PPO learns from "
            f"whole rollouts; ask for {rollout} or more, or lower n_steps or --n-envs"
        )
    batch_size = hyperparameters.get("batch_size", 64)
    if hyperparameters.get("normalize_advantage", True) and rollout % batch_size == 1:
        raise ValueError(
            f"hyperparameter batch_size {batch_size} leaves a minibatch of 1 step in each rollout of {rollout} env "
            f"steps ({factors}): its advantage cannot be normalized; choose a batch_size that divides {rollout}"
        )
    planned = -(-timesteps // rollout) * rollout
    if planned != timesteps:
        print(
            f"note: --timesteps {timesteps} is not a whole number of rollouts of {rollout} env steps ({factors}): "
            f"PPO will train {planned}",
            file=sys.stderr,
        )
    return planned


@contextlib.contextmanager
def removed_on_error(directory: Path):
    """Removes what the block adds to ``directory`` if it raises an ``Exception`` (Ctrl-C keeps what was saved)."""
    before = set(directory.iterdir()) if directory.is_dir() else None
    try:
        yield
    except Exception:
        added = [directory] if before is None else sorted(set(directory.iterdir()) - before)
        for path in added:
            if path.is_dir():
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)
        raise


def train(
    env_id: str,
    timesteps: int,
    seed: int = 0,
    n_envs: int | None = None,
    output_dir: Path | str = Path("models"),
    hyperparameters: dict | None = None,
    progress: bool = True,
    tensorboard: bool = False,
    vectorization: str | None = None,
    env_kwargs: dict | None = None,
    checkpoints: int = 4,
    curve_references: dict | None = None,
    init_from_planner: int | Path | str | Demonstrations | None = None,
    planner_workers: int = 1,
    validation_episodes: int = 0,
    validation_every: int | None = None,
    validation_stop_at: float | None = None,
) -> Path:
    """Train PPO on ``env_id`` for ``timesteps`` env steps; save ``output_dir/model.zip`` and return its path.

    Also writes ``train.json`` (settings, every constructor keyword, time, fps), ``checkpoints/``, the learning curve
    (``curve.csv``, ``curve.png``) and with ``tensorboard`` its event files. ``init_from_planner``: warm start by
    behaviour cloning of the planner, on that many episodes (seeds from ``DEMONSTRATION_SEEDS + seed``, saved as
    ``demonstrations.npz``), such a file, or ``Demonstrations`` (a dataset's); ``timesteps=0`` keeps the cloned
    policy. ``validation_episodes`` > 0 keeps the policy best on them in ``best/``; ``validation_stop_at`` stops
    training once a validation's mean main metric reaches it. Ctrl-C saves the model so far (train.json:
    ``"interrupted": true``).
    """
    if timesteps < (0 if init_from_planner is not None else 1):
        raise ValueError(f"timesteps must be >= 1 (0 only with a planner warm start: cloning alone), got {timesteps}")
    if validation_episodes < 0 or (validation_every is not None and validation_every < 1):
        raise ValueError(
            f"validation needs episodes >= 0 and every >= 1 env steps, got {validation_episodes} and {validation_every}"
        )
    if validation_stop_at is not None and not (validation_episodes and math.isfinite(validation_stop_at)):
        raise ValueError(
            f"stopping at a validation mean needs validation episodes and a finite mean, got {validation_stop_at}"
        )
    if tensorboard and importlib.util.find_spec("tensorboard") is None:  # SB3's TensorBoard writer
        raise ValueError("TensorBoard logging needs the tensorboard package: pip install tensorboard")
    output_dir = Path(output_dir)
    tensorboard_log = str(output_dir / "tensorboard") if tensorboard else None
    hyperparameters = training_block(env_id, hyperparameters, n_envs)
    vectorization = checked_vectorization(env_id, vectorization)
    demonstrations = init_from_planner if isinstance(init_from_planner, Demonstrations) else None
    if isinstance(init_from_planner, Path | str):
        demonstrations = Demonstrations.load(init_from_planner)
    rollout, factors = rollout_steps(env_id, hyperparameters, env_kwargs, planner=isinstance(init_from_planner, int))
    planned = planned_steps(timesteps, rollout, factors, hyperparameters)
    with removed_on_error(output_dir), torch_threads():
        model = build_model(env_id, seed, None, hyperparameters, env_kwargs, vectorization, tensorboard_log)
        warm_start = None
        if init_from_planner is not None:
            source = (init_from_planner, demonstrations)
            warm_start = _cloned_planner(model, env_id, source, env_kwargs, output_dir, planner_workers)
        progress_bar = TqdmCallback(planned, disable=not progress)
        callbacks = [progress_bar, CurveCallback(start_curve(output_dir, env_id, env_kwargs))]
        if checkpoints > 0:
            every = max(timesteps // (checkpoints * model.n_envs), 1)  # in vec-env steps
            callbacks.append(
                CheckpointCallback(every, str(output_dir / "checkpoints"), name_prefix="ppo", save_vecnormalize=True)
            )
        validation = None
        if validation_episodes and timesteps:
            copies = training_vec_env(env_id, validation_episodes, 0, env_kwargs, vectorization)[1]
            period = validation_every or max(timesteps // 20, 1)
            first_seed = VALIDATION_SEEDS + seed
            validation = ValidationCallback(
                copies, validation_episodes, period, first_seed, output_dir, save_policy, validation_stop_at
            )
            callbacks.append(validation)
        start, interrupted = time.perf_counter(), False
        try:
            if timesteps:
                model.learn(timesteps, callback=callbacks, tb_log_name="ppo")
        except INTERRUPTIONS as error:
            if not pressed_ctrl_c(error):
                raise
            interrupted = True
            progress_bar.close()
        seconds = time.perf_counter() - start
        model_path = save_policy(model, output_dir)
        model.get_env().close()
        if validation is not None:
            validation.close()
        title = f"{env_id}: {type(model).__name__}, seed {seed}, gamma {model.gamma}"
        title += "".join(f", {key.replace('_', ' ')} {value}" for key, value in scheduled(hyperparameters).items())
        if warm_start is not None:
            title += f", cloned from {len(warm_start['seeds'])} planner episodes"
        curve = drawn_curve(output_dir, title, curve_references)
        record = {
            "env_id": env_id,
            "algorithm": type(model).__name__,
            "timesteps": int(model.num_timesteps),
            "timesteps_asked": timesteps,
            "rollout": rollout,  # env steps: PPO trains whole rollouts
            "seed": seed,
            "n_envs": model.n_envs,
            "vectorization": vectorization,
            "env_kwargs": env_kwargs or {},
            "hyperparameters": hyperparameters,
            "constructor": constructor_values(
                type(model), *_constructor_arguments(hyperparameters, seed, tensorboard_log)
            ),
            "seconds": seconds,
            "fps": model.num_timesteps / seconds if model.num_timesteps else 0.0,
            "torch_threads": TORCH_THREADS,
            "model": str(model_path),
            "interrupted": interrupted,
            "curve": curve,
            "warm_start": warm_start,
            "validation": validation.record() if validation is not None else None,
        }
        (output_dir / "train.json").write_text(json.dumps(record, indent=2) + "\n")
    return model_path


def save_policy(model, directory: Path) -> Path:
    """``model`` as ``directory/model.zip``, with its ``VecNormalize`` statistics beside it when it has them."""
    directory.mkdir(parents=True, exist_ok=True)
    model.save(directory / MODEL_FILE)
    if isinstance(model.get_env(), VecNormalize):
        model.get_env().save(str(directory / NORMALIZATION_FILE))
    return directory / MODEL_FILE


def _cloned_planner(model, env_id: str, source, env_kwargs: dict | None, output_dir: Path, workers: int) -> dict:
    """Warm-start ``model`` from the planner (``source``: episodes or a file, and its ``Demonstrations``)."""
    start = time.perf_counter()
    source, demonstrations = source
    if isinstance(source, int):
        first = DEMONSTRATION_SEEDS + model.seed
        demonstrations = planner_demonstrations(env_id, source, first, model.gamma, env_kwargs, workers)
        origin = f"{source} planner episodes, seeds {first}..{first + source - 1}"
    else:
        origin = f"{len(demonstrations.seeds)} recorded episodes" if source is demonstrations else str(source)
    output_dir.mkdir(parents=True, exist_ok=True)
    demonstrations.save(output_dir / DEMONSTRATIONS_FILE)
    played = time.perf_counter()
    epochs = clone_planner(model, demonstrations)
    return {
        "demonstrations": origin,
        "seeds": demonstrations.seeds.tolist(),
        "rows": len(demonstrations.actions),
        "cloning_epochs": epochs,
        "agreement": agreement(model, demonstrations),
        "demonstration_seconds": played - start,
        "cloning_seconds": time.perf_counter() - played,
    }


def model_file(path: Path | str) -> Path:
    """``path``, or ``path/model.zip`` for a directory; ``ValueError`` naming a path that is neither."""
    path = Path(path)
    if path.is_dir():
        if not (path / MODEL_FILE).is_file():
            raise ValueError(f"PPO model directory {str(path)!r} holds no {MODEL_FILE} (train one with: infonav train)")
        return path / MODEL_FILE
    if not path.is_file():
        raise ValueError(f"PPO model {str(path)!r} does not exist (train one with: infonav train --env ENV_ID)")
    return path


def load_model(path: Path | str):
    """A saved ``MaskablePPO`` / ``PPO`` model from a zip or its directory (``ValueError`` naming a bad one)."""
    path = model_file(path)
    try:
        with zipfile.ZipFile(path) as archive:  # MaskablePPO or PPO: the policy class recorded in the zip's data
            policy_class = json.loads(archive.read("data")).get("policy_class")
        module = policy_class.get("__module__", "") if isinstance(policy_class, dict) else ""
        return (MaskablePPO if module.startswith("sb3_contrib") else PPO).load(path, device="cpu")
    except Exception as error:  # zipfile, pickle, torch and KeyError failures all mean "not a model"
        message = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise ValueError(f"cannot load PPO model {str(path)!r}: {message}") from None


def load_normalization(model_path: Path) -> VecNormalize | None:
    """The ``VecNormalize`` statistics beside ``model_path`` (``None`` without; ``ValueError`` if not such)."""
    path = Path(model_path).parent / NORMALIZATION_FILE
    if not path.is_file():
        return None
    try:
        normalization = pickle.loads(path.read_bytes())
    except Exception as error:  # truncated or foreign pickles fail in many ways
        raise ValueError(f"cannot load observation normalization {str(path)!r}: {error}") from None
    if not isinstance(normalization, VecNormalize):
        raise ValueError(
            f"observation normalization {str(path)!r} holds a {type(normalization).__name__}, "
            "not VecNormalize statistics"
        )
    return normalization


class PPOAgent:
    """A trained PPO policy (``model_file``) acting deterministically among the valid actions (of robot ``agent``)."""

    def __init__(self, model_path: Path | str, env, agent: str | None = None):
        self.model_path = model_file(model_path)
        self.model = load_model(self.model_path)
        self.n_actions = checked_action_count(
            f"PPO model {str(self.model_path)!r}",
            self.model.observation_space.shape,
            self.model.action_space,
            env,
            agent,
        )
        self.normalization = load_normalization(self.model_path)

    def reset(self, seed: int | None = None) -> None:
        """Deterministic: nothing to reset."""

    def act(self, observation, info: dict) -> int:
        mask = usable_mask(info.get("action_mask"), self.n_actions)
        observation = np.asarray(observation)
        if self.normalization is not None:
            observation = self.normalization.normalize_obs(observation)
        with torch.no_grad():
            obs_tensor, _ = self.model.policy.obs_to_tensor(observation)
            logits = self.model.policy.get_distribution(obs_tensor).distribution.logits[0].cpu().numpy()
        return int(np.argmax(np.where(mask, logits, -np.inf)))
