"""Speed goals, measured as ratios against a reference run in the same process.

Env steps: LandmarkSelection-v0 (K = 8) against CartPole-v1, both made by
``gym.make`` and driven by a uniformly random policy (CartPole:
``action_space.sample()`` as in ``gymnasium.utils.performance.benchmark_step``;
LandmarkSelection: uniform over the *valid* actions, so every step does a full
EKF update). Rounds alternate between the two envs and the median ratio is
reported, so a busy machine slows both alike.
"""

from __future__ import annotations

import statistics
import time
import timeit

import gymnasium as gym
import numpy as np
from tqdm.auto import tqdm

from agents import GreedyEntropyAgent, RandomAgent

GOALS = {"landmark_selection_vs_cartpole_ratio": 0.10, "greedy_decision_us": 100.0}


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


def run_benchmark(rounds: int = 5, seconds_per_round: float = 1.0, seed: int = 0, progress: bool = True) -> dict:
    """Measure every speed goal; returns a JSON-ready dict with the figures and whether each goal is met."""
    cartpole = gym.make("CartPole-v1")
    cartpole.action_space.seed(seed)
    landmark = gym.make("infonav/LandmarkSelection-v0", n_candidates=8)
    random_agent = RandomAgent(landmark.action_space.n, seed=seed)
    cartpole_rates, landmark_rates = [], []
    for _ in tqdm(range(rounds), desc="benchmark rounds", disable=not progress):
        cartpole_rates.append(
            steps_per_second(cartpole, lambda info: cartpole.action_space.sample(), seconds_per_round, seed)
        )
        landmark_rates.append(
            steps_per_second(landmark, lambda info: random_agent.act(None, info), seconds_per_round, seed)
        )
    ratios = [ours / reference for ours, reference in zip(landmark_rates, cartpole_rates)]
    figures = {
        "cartpole_steps_per_s": statistics.median(cartpole_rates),
        "landmark_selection_steps_per_s": statistics.median(landmark_rates),
        "landmark_selection_vs_cartpole_ratio": statistics.median(ratios),
        "greedy_decision_us": greedy_decision_us(),
    }
    met = {
        "landmark_selection_vs_cartpole_ratio": figures["landmark_selection_vs_cartpole_ratio"]
        >= GOALS["landmark_selection_vs_cartpole_ratio"],
        "greedy_decision_us": figures["greedy_decision_us"] <= GOALS["greedy_decision_us"],
    }
    return {
        "figures": figures,
        "goals": GOALS,
        "goals_met": met,
        "rounds": rounds,
        "seconds_per_round": seconds_per_round,
    }
