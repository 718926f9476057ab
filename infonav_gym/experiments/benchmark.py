"""Speed goals, measured as ratios against a reference run in the same process.

Env steps: LandmarkSelection-v0 (K = 8), the 4-robot cooperative_localization_v0
(parallel steps: every robot acts) and SensorSelection-v0 (no goal: a step renders a
LADAR or camera frame) against CartPole-v1. CartPole is driven by
``action_space.sample()`` as in ``gymnasium.utils.performance.benchmark_step``; the
infonav envs by agents uniform over the *valid* actions, so steps do full EKF
updates. Rounds alternate between the envs and the median ratio is reported, so a
busy machine slows them alike.

Sensors (``infonav_gym.experiments.sensor_timing``): median milliseconds of one default
``Ladar().scan`` (32 x 180) and ``Camera().capture`` (120 x 160) on a default
``make_terrain`` scene, with absolute goals, each against a pure-Pymunk
``segment_query_first`` loop over the same rays (ratio < 1: the sensor is faster).
ICP (``infonav_gym.experiments.registration_timing``): median milliseconds of point-to-point ``icp`` on a
32 x 180 LADAR frame pair from a warm start, and its errors against the true motion, beside
Open3D's ``registration_icp`` on the same pair when Open3D imports.
PPO (``infonav_gym.experiments.ppo_timing``): training timesteps per second of the same MaskablePPO
settings on LandmarkSelection-v0 and on CartPole-v1, 8 envs each, alternating rounds in one run.
Figures named ``*_us`` or ``*_ms`` meet their goal at or below it, all others at or above.
"""

from __future__ import annotations

import statistics
import time
import timeit

import gymnasium as gym
import numpy as np
from tqdm.auto import tqdm

from agents import GreedyEntropyAgent, RandomAgent
from infonav_gym.experiments.registration_timing import icp_figures
from infonav_gym.experiments.sensor_timing import sensor_figures
from infonav_gym.multi import cooperative_localization_v0

GOALS = {
    "landmark_selection_vs_cartpole_ratio": 0.10,
    "cooperative_localization_vs_cartpole_ratio": 0.05,
    "greedy_decision_us": 100.0,
    "ladar_frame_ms": 5.0,
    "camera_frame_ms": 10.0,
    "icp_frame_pair_ms": 20.0,
    "ppo_fps_ratio_vs_cartpole": 0.5,
}
PPO_TIMESTEPS_PER_SECOND_OF_ROUND = 2048  # --seconds 1 -> 2048 PPO timesteps per env per round, 256 at least


def lower_is_better(name: str) -> bool:
    """Whether figure ``name`` meets its goal at or below it: times (``*_us``, ``*_ms``) do, rates and ratios don't."""
    return name.endswith(("_us", "_ms"))


def steps_per_second(env: gym.Env, policy, seconds: float, seed: int) -> float:
    """Env steps per second of ``env`` under ``policy(info) -> action`` for about ``seconds``."""
    _, info = env.reset(seed=seed)
    steps, start = 0, time.perf_counter()
    deadline = start + seconds
    while True:
        for _ in range(100):
            _, _, terminated, truncated, info = env.step(policy(info))
            if terminated or truncated:
                _, info = env.reset()
        steps += 100
        now = time.perf_counter()
        if now >= deadline:
            return steps / (now - start)


def parallel_steps_per_second(env, policies: dict, seconds: float, seed: int) -> float:
    """Parallel (all-agent) steps per second of a PettingZoo ``env`` under per-agent ``policies[agent](info)``."""
    _, infos = env.reset(seed=seed)
    steps, start = 0, time.perf_counter()
    deadline = start + seconds
    while True:
        for _ in range(100):
            _, _, _, _, infos = env.step({agent: policies[agent](infos[agent]) for agent in env.agents})
            if not env.agents:
                _, infos = env.reset()
        steps += 100
        now = time.perf_counter()
        if now >= deadline:
            return steps / (now - start)


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
    from infonav_gym.experiments.ppo_timing import ppo_fps_figures

    timesteps = max(256, round(seconds_per_round * PPO_TIMESTEPS_PER_SECOND_OF_ROUND))
    return ppo_fps_figures(timesteps_per_round=timesteps, rounds=min(rounds, 3), seed=seed)


def run_benchmark(rounds: int = 5, seconds_per_round: float = 1.0, seed: int = 0, progress: bool = True) -> dict:
    """Measure every speed goal; returns a JSON-ready dict with the figures and whether each goal is met."""
    cartpole = gym.make("CartPole-v1")
    cartpole.action_space.seed(seed)
    landmark = gym.make("infonav/LandmarkSelection-v0", n_candidates=8)
    random_agent = RandomAgent(landmark.action_space.n, seed=seed)
    team = cooperative_localization_v0.parallel_env()
    team_agents = {
        name: RandomAgent(team.action_space(name).n, seed=seed + k) for k, name in enumerate(team.possible_agents)
    }
    team_policies = {name: (lambda info, agent=agent: agent.act(None, info)) for name, agent in team_agents.items()}
    sensor = gym.make("infonav/SensorSelection-v0")
    sensor_agent = RandomAgent(sensor.action_space.n, seed=seed)
    rates = {"cartpole": [], "landmark_selection": [], "cooperative_localization": [], "sensor_selection": []}
    for _ in tqdm(range(rounds), desc="benchmark rounds", disable=not progress):
        rates["cartpole"].append(
            steps_per_second(cartpole, lambda info: cartpole.action_space.sample(), seconds_per_round, seed)
        )
        rates["landmark_selection"].append(
            steps_per_second(landmark, lambda info: random_agent.act(None, info), seconds_per_round, seed)
        )
        rates["cooperative_localization"].append(
            parallel_steps_per_second(team, team_policies, seconds_per_round, seed)
        )
        rates["sensor_selection"].append(
            steps_per_second(sensor, lambda info: sensor_agent.act(None, info), seconds_per_round, seed)
        )
    figures = {f"{name}_steps_per_s": statistics.median(values) for name, values in rates.items()}
    for name in ("landmark_selection", "cooperative_localization", "sensor_selection"):
        ratios = [ours / reference for ours, reference in zip(rates[name], rates["cartpole"])]
        figures[f"{name}_vs_cartpole_ratio"] = statistics.median(ratios)
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
