"""PPO training speed on LandmarkSelection-v0 against CartPole-v1, same settings, same process.

Both envs train with the same algorithm and hyperparameters (``MaskablePPO`` with the
LandmarkSelection-v0 block of ``agents/hyperparams/ppo.yml``; CartPole gets an all-valid
mask through ``InfoActionMask``), ``n_envs`` ``DummyVecEnv`` copies and the same torch
threads. Rounds alternate between the two and time only ``learn`` (rollouts and gradient
updates), so model construction and a busy machine affect both alike; the median ratio
is reported.
"""

from __future__ import annotations

import statistics
import time

LANDMARK_ID = "infonav/LandmarkSelection-v0"
CARTPOLE_ID = "CartPole-v1"


def _masked_model(env_id: str, hyperparameters: dict, seed: int, n_envs: int):
    from sb3_contrib import MaskablePPO
    from stable_baselines3.common.env_util import make_vec_env

    from agents.ppo import InfoActionMask, _constructor_kwargs

    vec_env = make_vec_env(env_id, n_envs=n_envs, seed=seed, wrapper_class=InfoActionMask)
    kwargs = _constructor_kwargs(hyperparameters)
    return MaskablePPO(hyperparameters.get("policy", "MlpPolicy"), vec_env, seed=seed, device="cpu", **kwargs)


def ppo_fps_figures(timesteps_per_round: int = 2048, rounds: int = 3, seed: int = 0, n_envs: int = 8) -> dict:
    """Median PPO training timesteps per second on both envs and their ratio (LandmarkSelection / CartPole).

    ``n_steps`` (per env) shrinks when a round is shorter than one rollout, so a quick
    run (a few hundred timesteps) still does full rollout + update cycles.
    """
    from agents.ppo import default_num_threads, load_hyperparameters, torch_threads

    hyperparameters = load_hyperparameters(LANDMARK_ID)
    n_steps = max(1, min(int(hyperparameters.get("n_steps", 2048)), timesteps_per_round // n_envs))
    rollout = n_steps * n_envs
    hyperparameters.update(n_steps=n_steps, batch_size=min(int(hyperparameters.get("batch_size", 64)), rollout))
    timesteps = max(rollout, timesteps_per_round // rollout * rollout)
    rates = {LANDMARK_ID: [], CARTPOLE_ID: []}
    with torch_threads(default_num_threads()):
        models = {env_id: _masked_model(env_id, hyperparameters, seed, n_envs) for env_id in rates}
        for _ in range(rounds):
            for env_id, model in models.items():
                before, start = model.num_timesteps, time.perf_counter()
                model.learn(timesteps, reset_num_timesteps=False)
                rates[env_id].append((model.num_timesteps - before) / (time.perf_counter() - start))
        for model in models.values():
            model.get_env().close()
    ratios = [ours / reference for ours, reference in zip(rates[LANDMARK_ID], rates[CARTPOLE_ID])]
    return {
        "ppo_landmark_selection_fps": statistics.median(rates[LANDMARK_ID]),
        "ppo_cartpole_fps": statistics.median(rates[CARTPOLE_ID]),
        "ppo_fps_ratio_vs_cartpole": statistics.median(ratios),
        "ppo_timesteps_per_round": timesteps,
    }
