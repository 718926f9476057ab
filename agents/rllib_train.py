"""RLlib PPO for the infonav envs (``infonav train --backend rllib``, the ``distributed`` extra).

A single-agent env trains one policy on its (native or sync) vector env per runner, a team env multi-agent PPO on
its native vector env (``rllib_team_env``), one policy shared by the robots or one per robot; every policy is a
``MaskedPPOTorchRLModule`` with the env's ppo.yml block translated. Writes ``checkpoint/``, ``train.json``, a curve.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import gymnasium as gym
from gymnasium.vector import AutoresetMode
from tqdm.auto import tqdm

from agents.hyperparameters import checked_block
from agents.rllib_masking import (
    NORMALIZE_OBSERVATIONS,
    MaskedObservations,
    MaskedVectorObservations,
)
from infonav_gym.registry import PARALLEL, api_of, has_native_vector_env, make_env, make_vector_env

CHECKPOINT_DIR = "checkpoint"
RLLIB_ENV_PREFIX = "infonav-rllib:"  # + env id: the name the env creator is registered under in Ray's registry
SHARED_POLICY = "shared_policy"
POLICY_LAYOUTS = ("shared", "per_robot")


class SingleEnvCreator:
    """RLlib's env creator of a single-agent env: the masked env, or its masked native vector env for ``num_envs`` (in
    ``NEXT_STEP`` autoreset, RLlib's env runner's convention)."""

    def __init__(self, env_id: str):
        self.env_id = env_id

    def __call__(self, env_config: dict):
        import infonav_gym  # noqa: F401  (registers the envs in an env runner's process)

        config = dict(env_config)
        if "num_envs" in config:
            return MaskedVectorObservations(
                make_vector_env(self.env_id, autoreset_mode=AutoresetMode.NEXT_STEP, **config)
            )
        return MaskedObservations(make_env(self.env_id, **config))


class TeamEnvCreator(SingleEnvCreator):
    """RLlib's env creator of a team env: ``num_envs`` copies (default 1) of its native vector env, batched, as
    ``BatchedTeamEnv`` (the env of ``BatchedTeamEnvRunner``)."""

    def __call__(self, env_config: dict):
        import infonav_gym  # noqa: F401
        from agents.rllib_team_env import BatchedTeamEnv

        config = dict(env_config)
        num_envs = config.pop("num_envs", 1)
        return BatchedTeamEnv(make_vector_env(self.env_id, num_envs, autoreset_mode=AutoresetMode.NEXT_STEP, **config))


TRAINING_NAMES = {  # ppo.yml key: (its name in RLlib's PPOConfig.training, type, SB3's default)
    "batch_size": ("minibatch_size", int, 64),
    "n_epochs": ("num_epochs", int, 10),
    "gamma": ("gamma", float, 0.99),
    "gae_lambda": ("lambda_", float, 0.95),
    "learning_rate": ("lr", float, 3e-4),
    "ent_coef": ("entropy_coeff", float, 0.0),
    "clip_range": ("clip_param", float, 0.2),
}
ROLLOUT_KEYS = {"n_steps": 2048, "n_envs": 1}  # their product is the train batch (SB3's defaults)
MODEL_KEYS = ("policy", "policy_kwargs", "normalize")  # policy: MlpPolicy, the only one RLlib's module mirrors
POLICY_KWARGS = ("net_arch", "activation_fn")


def _model_settings(hyperparameters: dict) -> dict:
    """The module's settings from ``policy``, ``policy_kwargs`` and ``normalize``; ``ValueError`` for the SB3 ones
    RLlib's module does not mirror."""
    from agents.ppo import normalization_kwargs

    policy_kwargs = hyperparameters.get("policy_kwargs") or {}
    hidden = policy_kwargs.get("net_arch", [64, 64])
    if set(policy_kwargs) - set(POLICY_KWARGS) or not isinstance(hidden, list):
        raise ValueError(
            f"the rllib backend trains an MLP: policy_kwargs with {' and '.join(POLICY_KWARGS)}, net_arch a list of "
            f"layer widths shared by the policy and the value function; got policy_kwargs {policy_kwargs!r}"
        )
    normalize = normalization_kwargs(hyperparameters)
    return {
        "fcnet_hiddens": list(hidden),
        "fcnet_activation": policy_kwargs.get("activation_fn", "tanh"),
        NORMALIZE_OBSERVATIONS: normalize is not None and bool(normalize.get("norm_obs", True)),
    }


def rllib_training_settings(hyperparameters: dict) -> dict:
    """The PPO settings of a ppo.yml block in RLlib's names (``PPOConfig.training``), the rollout ``n_steps * n_envs``
    as train batch; ``ValueError`` naming a key out of range, without an RLlib translation, or a schedule."""
    from agents.ppo import scheduled

    hyperparameters = checked_block(hyperparameters, "the hyperparameters")
    unknown = sorted(set(hyperparameters) - set(TRAINING_NAMES) - set(ROLLOUT_KEYS) - set(MODEL_KEYS))
    if unknown:
        known = ", ".join([*TRAINING_NAMES, *ROLLOUT_KEYS, *MODEL_KEYS])
        raise ValueError(f"hyperparameter(s) {unknown} have no RLlib translation; the rllib backend takes {known}")
    if scheduled(hyperparameters):
        raise ValueError(f"hyperparameter(s) {sorted(scheduled(hyperparameters))} are schedules: rllib takes numbers")
    rollout = math.prod(hyperparameters.get(key, default) for key, default in ROLLOUT_KEYS.items())
    training = {name: kind(hyperparameters.get(key, default)) for key, (name, kind, default) in TRAINING_NAMES.items()}
    return {"train_batch_size_per_learner": rollout, **training, "model": _model_settings(hyperparameters)}


def check_arguments(env_id: str, env_kwargs: dict, hyperparameters: dict, policies: str) -> None:
    """``ValueError`` for an env id, config, hyperparameter or policy layout that training would fail on, before Ray
    starts (which takes a minute)."""
    check_policies(policies)
    make_env(env_id, **env_kwargs).close()  # an unknown id or config key: the message ``infonav evaluate`` gives
    if policies != "shared" and api_of(env_id) != PARALLEL:
        raise ValueError(
            f"policies {policies!r} is for a team env (a PettingZoo parallel env); {env_id!r} has one robot"
        )
    rllib_training_settings(hyperparameters)


def check_policies(policies: str) -> str:
    if policies not in POLICY_LAYOUTS:
        raise ValueError(f"policies must be one of {', '.join(POLICY_LAYOUTS)}, got {policies!r}")
    return policies


def build_config(
    env_id: str,
    env_kwargs: dict,
    seed: int,
    hyperparameters: dict,
    num_env_runners: int = 1,
    envs_per_runner: int | None = None,
    policies: str = "shared",
):
    """The ``PPOConfig`` of ``env_id`` (see the module); its train batch covers every runner's envs."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec
    from ray.tune.registry import register_env

    from agents.rllib_module import MaskedPPOTorchRLModule

    check_policies(policies)
    team = api_of(env_id) == PARALLEL
    settings = rllib_training_settings(hyperparameters)
    module = RLModuleSpec(module_class=MaskedPPOTorchRLModule, model_config=settings.pop("model"))

    register_env(RLLIB_ENV_PREFIX + env_id, (TeamEnvCreator if team else SingleEnvCreator)(env_id))
    config = (
        PPOConfig()
        .environment(RLLIB_ENV_PREFIX + env_id, env_config=dict(env_kwargs))
        .env_runners(
            num_env_runners=num_env_runners,
            num_envs_per_env_runner=copies_per_runner(env_id, hyperparameters, num_env_runners, envs_per_runner),
        )
        .training(**settings)
        .debugging(seed=seed, log_level="ERROR")
        .reporting(metrics_num_episodes_for_smoothing=20)
    )
    if not team:
        if has_native_vector_env(env_id):
            config = config.env_runners(gym_env_vectorize_mode=gym.VectorizeMode.VECTOR_ENTRY_POINT)
        return config.rl_module(rl_module_spec=module)
    from agents.rllib_team_env import BatchedTeamEnvRunner, CurveMetricCallback

    robots = make_env(env_id, **env_kwargs).possible_agents
    policy_ids = {robot: SHARED_POLICY if policies == "shared" else robot for robot in robots}
    return (
        config.env_runners(env_runner_cls=BatchedTeamEnvRunner)
        .callbacks(CurveMetricCallback)
        .multi_agent(policies=set(policy_ids.values()), policy_mapping_fn=PolicyMapping(policy_ids))
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs={policy: module for policy in policy_ids.values()}))
    )


def copies_per_runner(env_id: str, hyperparameters: dict, num_env_runners: int, envs_per_runner: int | None) -> int:
    """Env copies each runner steps: ``envs_per_runner``, else a team env's ``n_envs`` (its ``ppo.yml`` block: the
    copies stepped at once) shared out over the runners, and 1 of a single-agent env."""
    if envs_per_runner is not None:
        return envs_per_runner
    if api_of(env_id) != PARALLEL:
        return 1
    return math.ceil(hyperparameters.get("n_envs", ROLLOUT_KEYS["n_envs"]) / max(num_env_runners, 1))


class PolicyMapping:
    """RLlib's ``policy_mapping_fn``: each robot's policy id (picklable, unlike a lambda)."""

    def __init__(self, policy_ids: dict):
        self.policy_ids = dict(policy_ids)

    def __call__(self, agent_id, episode=None, **kwargs) -> str:
        return self.policy_ids[agent_id]


def train_rllib(
    env_id: str,
    timesteps: int,
    output_dir: Path | str,
    seed: int = 0,
    env_kwargs: dict | None = None,
    hyperparameters: dict | None = None,
    num_env_runners: int = 1,
    envs_per_runner: int | None = None,
    policies: str = "shared",
    address: str | None = None,
    progress: bool = True,
    curve_references: dict | None = None,
) -> dict:
    """Train RLlib PPO on ``env_id`` for at least ``timesteps`` env steps on the Ray at ``address`` (or a local one);
    checkpoint it and return the ``train.json`` record (also written to ``output_dir``)."""
    from agents.learning_curve import METRIC_KEY, append_row, drawn_curve, start_curve
    from agents.ppo import load_hyperparameters, torch_threads
    from agents.ray_support import local_or_cluster_ray

    if timesteps < 1:
        raise ValueError(f"timesteps must be >= 1, got {timesteps}")
    if num_env_runners < 0 or (envs_per_runner is not None and envs_per_runner < 1):
        raise ValueError(
            f"--num-env-runners must be >= 0 and --envs-per-runner >= 1, got {num_env_runners}, {envs_per_runner}"
        )
    env_kwargs = dict(env_kwargs or {})
    hyperparameters = load_hyperparameters(env_id) if hyperparameters is None else hyperparameters
    check_arguments(env_id, env_kwargs, hyperparameters, policies)
    envs_per_runner = copies_per_runner(env_id, hyperparameters, num_env_runners, envs_per_runner)
    output_dir = Path(output_dir)
    curve = start_curve(output_dir, env_id, env_kwargs)
    with local_or_cluster_ray(address), torch_threads():  # the learner runs here
        config = build_config(env_id, env_kwargs, seed, hyperparameters, num_env_runners, envs_per_runner, policies)
        algorithm = config.build_algo()
        try:
            steps, start = 0, time.perf_counter()
            with tqdm(total=timesteps, desc="training PPO (RLlib)", unit="step", disable=not progress) as bar:
                while steps < timesteps:
                    runners = algorithm.train().get("env_runners", {})
                    # env steps sampled so far (a team step counts once: RLlib's env steps)
                    now = int(runners.get("num_env_steps_sampled_lifetime", 0))
                    bar.update(min(now, timesteps) - min(steps, timesteps))
                    bar.set_postfix(episode_return=runners.get("episode_return_mean"))
                    steps = now
                    if runners.get("num_episodes", 0) > 0:
                        metric = runners.get(METRIC_KEY, math.nan)  # a team env's (``CurveMetricCallback``)
                        append_row(curve, steps, runners["episode_return_mean"], metric, runners["num_episodes"])
            seconds = time.perf_counter() - start
            algorithm.save_to_path(str((output_dir / CHECKPOINT_DIR).resolve()))
        finally:
            algorithm.stop()
            drawn = drawn_curve(output_dir, f"{env_id}: PPO (RLlib), seed {seed}", curve_references)  # also on Ctrl-C
    record = {
        "env_id": env_id,
        "algorithm": "PPO (RLlib)",
        "backend": "rllib",
        "timesteps": steps,
        "seed": seed,
        "num_env_runners": num_env_runners,
        "envs_per_runner": envs_per_runner,
        "policies": policies if api_of(env_id) == PARALLEL else "single",
        "vectorization": "native" if has_native_vector_env(env_id) else "sync",
        "env_kwargs": env_kwargs,
        "hyperparameters": hyperparameters,
        "rllib_training": rllib_training_settings(hyperparameters),
        "seconds": seconds,
        "fps": steps / seconds,
        "checkpoint": str(output_dir / CHECKPOINT_DIR),  # as given, as the SB3 record's model path
        "curve": drawn,
    }
    (output_dir / "train.json").write_text(json.dumps(record, indent=2) + "\n")
    return record
