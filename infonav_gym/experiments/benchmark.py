"""Speed goals, measured as ratios against a reference run in the same process.

Env steps: every registered env (``infonav_gym.registry``; a parallel env's step is one step of
every robot) against CartPole-v1, with goals for LandmarkSelection-v0 (K = 8) and the 4-robot
cooperative_localization_v0. CartPole is driven by ``action_space.sample()`` as in
``gymnasium.utils.performance.benchmark_step``; the infonav envs by agents uniform over the
*valid* actions, so steps do full EKF updates. Rounds alternate between the envs and the median
ratio is reported, so a busy machine slows them alike.

Sensors (``infonav_gym.experiments.sensor_timing``): median milliseconds of one default
``Ladar().scan`` (32 x 180) and ``Camera().capture`` (120 x 160) on a default
``make_terrain`` scene, with absolute goals, each against a pure-Pymunk
``segment_query_first`` loop over the same rays (ratio < 1: the sensor is faster).
ICP (``infonav_gym.experiments.registration_timing``): median milliseconds of point-to-point ``icp`` on a
32 x 180 LADAR frame pair from a warm start, and its errors against the true motion, beside
Open3D's ``registration_icp`` on the same pair when Open3D imports.
PPO (``infonav_gym.experiments.ppo_timing``): training timesteps per second of the same MaskablePPO
settings on LandmarkSelection-v0 and on CartPole-v1, 8 envs each, and on their vector envs (the native
LandmarkSelection one, Gymnasium's CartPoleVectorEnv), 64 copies each, alternating rounds in one run.
Figures named ``*_us`` or ``*_ms`` meet their goal at or below it, all others at or above.
"""

from __future__ import annotations

import re
import statistics
import time
import timeit

import gymnasium as gym
import numpy as np
from tqdm.auto import tqdm

from agents import GreedyEntropyAgent, RandomAgent
from infonav_gym.experiments.registration_timing import icp_figures
from infonav_gym.experiments.sensor_timing import sensor_figures
from infonav_gym.registry import PARALLEL, api_of, make_env, registered_envs

GOALS = {
    "landmark_selection_vs_cartpole_ratio": 0.10,
    "cooperative_localization_vs_cartpole_ratio": 0.05,
    "greedy_decision_us": 100.0,
    "ladar_frame_ms": 5.0,
    "camera_frame_ms": 10.0,
    "icp_frame_pair_ms": 20.0,
    "ppo_fps_ratio_vs_cartpole": 0.5,
    "ppo_vector_fps_ratio_vs_cartpole": 0.8,
}
PPO_TIMESTEPS_PER_SECOND_OF_ROUND = 2048  # --seconds 1 -> 2048 PPO timesteps per env per round, 256 at least
PPO_VECTOR_TIMESTEPS_PER_SECOND_OF_ROUND = 8192  # the same for the 64-copy vector envs: two 4096-step rollouts
MAX_STEPS_BETWEEN_CLOCK_READS = 100  # reached by doubling from 1, so a slow env's round ends near its deadline


def lower_is_better(name: str) -> bool:
    """Whether figure ``name`` meets its goal at or below it: times (``*_us``, ``*_ms``) do, rates and ratios don't."""
    return name.endswith(("_us", "_ms"))


def _timed_steps(step, seconds: float) -> float:
    """Calls of ``step()`` per second for about ``seconds`` (the clock read after 1, 2, 4, ... up to 100 calls)."""
    steps, chunk, start = 0, 1, time.perf_counter()
    deadline = start + seconds
    while True:
        for _ in range(chunk):
            step()
        steps += chunk
        now = time.perf_counter()
        if now >= deadline:
            return steps / (now - start)
        chunk = min(2 * chunk, MAX_STEPS_BETWEEN_CLOCK_READS)


def steps_per_second(env: gym.Env, policy, seconds: float, seed: int) -> float:
    """Env steps per second of ``env`` under ``policy(info) -> action`` for about ``seconds``."""
    info = env.reset(seed=seed)[1]

    def step() -> None:
        nonlocal info
        _, _, terminated, truncated, info = env.step(policy(info))
        if terminated or truncated:
            info = env.reset()[1]

    return _timed_steps(step, seconds)


def parallel_steps_per_second(env, policies: dict, seconds: float, seed: int) -> float:
    """Parallel (all-agent) steps per second of a PettingZoo ``env`` under per-agent ``policies[agent](info)``."""
    infos = env.reset(seed=seed)[1]

    def step() -> None:
        nonlocal infos
        infos = env.step({agent: policies[agent](infos[agent]) for agent in env.agents})[4]
        if not env.agents:
            infos = env.reset()[1]

    return _timed_steps(step, seconds)


def figure_name(env_id: str) -> str:
    """The env id as a figure name: ``infonav/LandmarkSelection-v0`` -> ``landmark_selection``, no version."""
    name = re.sub(r"[-_]v\d+$", "", env_id.rsplit("/", 1)[-1])
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


def benchmarked_env_ids() -> list[str]:
    """Every registered env, in registration order: each one's steps per second are measured."""
    return [entry.id for entry in registered_envs()]


def _random_stepper(env_id: str, seconds: float, seed: int):
    """A function measuring ``env_id``'s steps per second under random valid actions (robot ``k``: seed + k)."""
    env = make_env(env_id)
    if api_of(env_id) == PARALLEL:
        agents = {
            name: RandomAgent(env.action_space(name).n, seed=seed + k) for k, name in enumerate(env.possible_agents)
        }
        policies = {name: (lambda info, agent=agent: agent.act(None, info)) for name, agent in agents.items()}
        return lambda: parallel_steps_per_second(env, policies, seconds, seed)
    agent = RandomAgent(env.action_space.n, seed=seed)
    return lambda: steps_per_second(env, lambda info: agent.act(None, info), seconds, seed)


def env_step_figures(
    env_ids: list[str] | None = None, rounds: int = 5, seconds_per_round: float = 1.0, seed: int = 0, progress=True
) -> dict:
    """Median steps per second of each env (default ``benchmarked_env_ids()``) and of CartPole-v1, and their ratios.

    Returns:
        ``{"cartpole_steps_per_s", NAME + "_steps_per_s", NAME + "_vs_cartpole_ratio"}`` for each env's ``figure_name``.
    """
    cartpole = gym.make("CartPole-v1")
    cartpole.action_space.seed(seed)
    steppers = {
        "cartpole": lambda: steps_per_second(
            cartpole, lambda info: cartpole.action_space.sample(), seconds_per_round, seed
        )
    }
    for env_id in benchmarked_env_ids() if env_ids is None else env_ids:
        steppers[figure_name(env_id)] = _random_stepper(env_id, seconds_per_round, seed)
    rates = {name: [] for name in steppers}
    for _ in tqdm(range(rounds), desc="benchmark rounds", disable=not progress):
        for name, stepper in steppers.items():
            rates[name].append(stepper())
    figures = {f"{name}_steps_per_s": statistics.median(values) for name, values in rates.items()}
    for name in list(steppers)[1:]:
        ratios = [ours / reference for ours, reference in zip(rates[name], rates["cartpole"])]
        figures[f"{name}_vs_cartpole_ratio"] = statistics.median(ratios)
    return figures


def greedy_decision_us(n_candidates: int = 16, seed: int = 0, repeats: int = 20000) -> float:
    """Microseconds per ``GreedyEntropyAgent.act`` over ``n_candidates`` with a random mask."""
    rng = np.random.default_rng(seed)
    info = {
        "action_mask": (rng.random(n_candidates) < 0.5).astype(np.int8),
        "action_information_gain": rng.random(n_candidates),
    }
    agent = GreedyEntropyAgent()
    best = min(timeit.repeat(lambda: agent.act(None, info), number=repeats, repeat=5))
    return best / repeats * 1e6


def _ppo_figures(rounds: int, seconds_per_round: float, seed: int) -> dict:
    """PPO fps figures; at most 3 rounds (each trains both envs), ``seconds_per_round`` sets their length."""
    from infonav_gym.experiments.ppo_timing import ppo_fps_figures, ppo_vector_fps_figures

    timesteps = max(256, round(seconds_per_round * PPO_TIMESTEPS_PER_SECOND_OF_ROUND))
    vector_timesteps = max(1024, round(seconds_per_round * PPO_VECTOR_TIMESTEPS_PER_SECOND_OF_ROUND))
    rounds = min(rounds, 3)
    return {
        **ppo_fps_figures(timesteps_per_round=timesteps, rounds=rounds, seed=seed),
        **ppo_vector_fps_figures(timesteps_per_round=vector_timesteps, rounds=rounds, seed=seed),
    }


def run_benchmark(rounds: int = 5, seconds_per_round: float = 1.0, seed: int = 0, progress: bool = True) -> dict:
    """Measure every speed goal; returns a JSON-ready dict with the figures and whether each goal is met."""
    figures = env_step_figures(None, rounds, seconds_per_round, seed, progress)
    figures["greedy_decision_us"] = greedy_decision_us()
    figures.update(sensor_figures(seconds_per_round, seed))
    figures.update(icp_figures(seconds_per_round, seed))
    figures.update(_ppo_figures(rounds, seconds_per_round, seed))
    met = {
        name: figures[name] <= goal if lower_is_better(name) else figures[name] >= goal for name, goal in GOALS.items()
    }
    return {
        "figures": figures,
        "goals": GOALS,
        "goals_met": met,
        "rounds": rounds,
        "seconds_per_round": seconds_per_round,
    }
