"""PPO training speed on LandmarkSelection-v0 against CartPole, same MaskablePPO settings and process: 8
``DummyVecEnv`` copies each, and 64-copy vector envs; rounds alternate and time only ``learn``."""

from __future__ import annotations

import statistics
import time

import numpy as np
from gymnasium.envs.classic_control.cartpole import CartPoleVectorEnv
from gymnasium.vector import AutoresetMode

LANDMARK_ID = "infonav/LandmarkSelection-v0"
CARTPOLE_ID = "CartPole-v1"
SINGLE_ENV_N_STEPS = 256  # per env of ppo_fps_figures: 8 x 256 = 2048 transitions per rollout, as the figure began


class SameStepCartPoleVectorEnv(CartPoleVectorEnv):
    """Gymnasium's ``CartPoleVectorEnv`` in ``AutoresetMode.SAME_STEP``: last observation in ``info["final_obs"]``."""

    metadata = {**CartPoleVectorEnv.metadata, "autoreset_mode": AutoresetMode.SAME_STEP}

    def step(self, action):
        observations, rewards, terminated, truncated, info = super().step(action)
        ended = self.prev_done.copy()  # what Gymnasium would reset at the next step
        if not ended.any():
            return observations, rewards, terminated, truncated, info
        final_observations = np.full(self.num_envs, None, dtype=object)
        for index in np.flatnonzero(ended).tolist():
            final_observations[index] = observations[index]
        self.state[:, ended] = self.np_random.uniform(low=self.low, high=self.high, size=(4, int(ended.sum())))
        self.steps[ended] = 0
        self.prev_done[:] = False
        info = {"final_obs": final_observations, "_final_obs": ended, "final_info": {}, "_final_info": ended.copy()}
        return self.state.T.astype(np.float32), rewards, terminated, truncated, info


def _round_settings(timesteps_per_round: int, n_envs: int, n_steps: int | None = None) -> tuple[dict, int]:
    """The LandmarkSelection-v0 hyperparameters for rounds of about ``timesteps_per_round``, and the round's timesteps;
    ``n_steps`` (``None``: the block's) shrinks so a quick run still does whole rollout + update cycles."""
    from agents.ppo import load_hyperparameters

    hyperparameters = load_hyperparameters(LANDMARK_ID)
    n_steps = int(hyperparameters.get("n_steps", 2048)) if n_steps is None else n_steps
    n_steps = max(1, min(n_steps, timesteps_per_round // n_envs))
    rollout = n_steps * n_envs
    hyperparameters.update(n_steps=n_steps, batch_size=min(int(hyperparameters.get("batch_size", 64)), rollout))
    return hyperparameters, max(rollout, timesteps_per_round // rollout * rollout)


def _masked_model(vec_env, hyperparameters: dict, seed: int):
    from sb3_contrib import MaskablePPO

    from agents.ppo import _constructor_kwargs, without_log_folder

    kwargs = _constructor_kwargs(hyperparameters)
    model = MaskablePPO(hyperparameters.get("policy", "MlpPolicy"), vec_env, seed=seed, device="cpu", **kwargs)
    return without_log_folder(model)


def _fps_figures(infix: str, make_vec_envs: dict, hyperparameters: dict, seed: int, timesteps: int, rounds: int):
    """Median training timesteps/s on the two envs ``make_vec_envs`` makes and their median ratio."""
    from agents.ppo import torch_threads

    rates = {name: [] for name in make_vec_envs}
    with torch_threads():
        models = {name: _masked_model(make(), hyperparameters, seed) for name, make in make_vec_envs.items()}
        for _ in range(rounds):
            for name, model in models.items():
                before, start = model.num_timesteps, time.perf_counter()
                model.learn(timesteps, reset_num_timesteps=False)
                rates[name].append((model.num_timesteps - before) / (time.perf_counter() - start))
        for model in models.values():
            model.get_env().close()
    ratios = [ours / reference for ours, reference in zip(rates[LANDMARK_ID], rates[CARTPOLE_ID])]
    return {
        f"ppo_landmark_selection_{infix}fps": statistics.median(rates[LANDMARK_ID]),
        f"ppo_cartpole_{infix}fps": statistics.median(rates[CARTPOLE_ID]),
        f"ppo_{infix}fps_ratio_vs_cartpole": statistics.median(ratios),
        f"ppo_{infix}timesteps_per_round": timesteps,
    }


def ppo_fps_figures(timesteps_per_round: int = 2048, rounds: int = 3, seed: int = 0, n_envs: int = 8) -> dict:
    """Median PPO training timesteps per second on both single envs and their ratio (LandmarkSelection / CartPole)."""
    from stable_baselines3.common.env_util import make_vec_env

    from agents.ppo import InfoActionMask

    hyperparameters, timesteps = _round_settings(timesteps_per_round, n_envs, SINGLE_ENV_N_STEPS)
    make_vec_envs = {
        env_id: lambda env_id=env_id: make_vec_env(env_id, n_envs=n_envs, seed=seed, wrapper_class=InfoActionMask)
        for env_id in (LANDMARK_ID, CARTPOLE_ID)
    }
    return _fps_figures("", make_vec_envs, hyperparameters, seed, timesteps, rounds)


def ppo_vector_fps_figures(timesteps_per_round: int = 8192, rounds: int = 3, seed: int = 0, n_envs: int = 64) -> dict:
    """Median PPO training timesteps/s on the LandmarkSelection (native) and CartPole vector envs and their ratio."""
    from agents.ppo import native_vec_env
    from agents.vector_adapter import monitored_vec_env

    hyperparameters, timesteps = _round_settings(timesteps_per_round, n_envs)
    make_vec_envs = {
        LANDMARK_ID: lambda: native_vec_env(LANDMARK_ID, n_envs, seed),
        CARTPOLE_ID: lambda: monitored_vec_env(SameStepCartPoleVectorEnv(num_envs=n_envs), seed),
    }
    return {
        **_fps_figures("vector_", make_vec_envs, hyperparameters, seed, timesteps, rounds),
        "ppo_vector_n_envs": n_envs,
    }
