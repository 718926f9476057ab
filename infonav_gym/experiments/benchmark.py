"""Speed goals as ratios against a reference run in the same process (rounds alternate; median ratios): env steps
against CartPole-v1 here; vector envs, sensors, ICP, PPO, parallel evaluation and start-up in the ``*_timing``
modules. A goal is a maximum where ``lower_is_better``; one not measured (a peer or Ray absent) is met ``None``."""

from __future__ import annotations

import os
import re
import statistics
import time
import timeit
from pathlib import Path

import gymnasium as gym
import numpy as np
from tqdm.auto import tqdm

from agents import GreedyEntropyAgent, RandomAgent
from infonav_gym.experiments.distributed_timing import (
    EVALUATION_EPISODES,
    RLLIB_SAMPLE_STEPS,
    evaluation_workers_figures,
    rllib_missing,
    rllib_runner_figures,
)
from infonav_gym.experiments.registration_timing import icp_figures, map_step_figures, registration_peers_missing
from infonav_gym.experiments.sensor_timing import sensor_figures
from infonav_gym.experiments.startup_timing import startup_figures
from infonav_gym.experiments.training_timing import training_figures
from infonav_gym.experiments.vector_timing import (
    DEFAULT_VECTOR_SIZES,
    MEMORY_SECONDS,
    MEMORY_STEPS,
    VectorRun,
    cartpole_vector_run,
    check_vector_sizes,
    kb_per_env,
    memory_missing,
    torchrl_env_run,
    torchrl_missing,
    vector_env_ids,
    vector_env_run,
    vmas_missing,
    vmas_navigation_run,
)
from infonav_gym.registry import PARALLEL, api_of, available_envs, make_env
from infonav_gym.rendering import matplotlib_figure, save_figure

GOALS = {
    "landmark_selection_vs_cartpole_ratio": 0.10,
    "cooperative_localization_vs_cartpole_ratio": 0.05,
    "sensor_selection_vs_cartpole_ratio": 0.01,
    "greedy_decision_us": 100.0,
    "ladar_frame_ms": 5.0,
    "camera_frame_ms": 10.0,
    "icp_frame_pair_ms": 20.0,
    "icp_vs_open3d_icp_scan_40k_time_ratio": 1.0,
    "gicp_vs_small_gicp_scan_40k_time_ratio": 1.0,
    "ppo_fps_ratio_vs_cartpole": 0.5,
    "ppo_vector_fps_ratio_vs_cartpole": 0.85,
    "landmark_selection_vector_256_vs_cartpole_ratio": 2.0,
    "active_localization_vector_256_vs_cartpole_ratio": 1.0,
    "sensor_selection_vector_256_vs_cartpole_ratio": 0.05,
    "cooperative_localization_vector_256_vs_vmas_ratio": 2.0,
    "cooperative_exploration_vector_256_vs_vmas_ratio": 1.0,
    "range_registration_vector_256_vs_single_ratio": 10.0,
    "landmark_selection_vector_1024_kb_per_env": 200.0,
    "active_localization_vector_1024_kb_per_env": 200.0,
    "cooperative_localization_vector_1024_kb_per_env": 200.0,
    "evaluation_2_workers_time_ratio": 0.65,
    "rllib_team_2_runners_vs_1_ratio": 1.5,
    "rllib_exploration_1_runner_steps_per_s": 1000.0,
    "landmark_selection_vector_4096_threads_2_vs_1_ratio": 1.7,
    "warm_start_s": 2.0,
    # issue 42: the whole step compiled, every core used, a start that does not make a user wait
    "landmark_selection_vector_1024_vs_cartpole_ratio": 8.0,
    "active_localization_vector_1024_vs_cartpole_ratio": 4.0,
    "cooperative_localization_vector_1024_vs_vmas_ratio": 5.0,
    "cooperative_exploration_vector_1024_vs_vmas_ratio": 3.0,
    "sensor_selection_vector_256_vs_single_ratio": 10.0,
    "range_registration_vector_64_vs_single_ratio": 4.0,
    "cold_start_s": 5.0,
    "cold_start_all_envs_s": 15.0,
    # issue 44: registration to an a-priori map
    "map_registration_step_vs_range_registration_registering_step_time_ratio": 1.0,
    # issue 45: TorchRL's view of the team envs, as BenchMARL trains on them
    "cooperative_localization_torchrl_256_vs_native_ratio": 0.8,
    "cooperative_exploration_torchrl_256_vs_native_ratio": 0.8,
    # issue 45: infonav train's default backend trains at least as fast as the others, the same block on one core
    "sb3_vs_rllib_train_steps_ratio": 1.0,
    "sb3_vs_benchmarl_train_steps_ratio": 1.0,
}
PPO_TIMESTEPS_PER_SECOND_OF_ROUND = 2048  # --seconds 1 -> 2048 PPO timesteps per env per round, 256 at least
PPO_VECTOR_TIMESTEPS_PER_SECOND_OF_ROUND = 8192  # the same for the 64-copy vector envs: two 4096-step rollouts
QUICK_TRAINING_COPIES = 2  # exploration copies per training rollout in a quick run (--seconds below 1)
MAX_STEPS_BETWEEN_CLOCK_READS = 100  # reached by doubling from 1, so a slow env's round ends near its deadline
# e.g. landmark_selection_vector_256_steps_per_s
CURVE_FIGURE = re.compile(r"^(?P<curve>.+)_(?P<size>\d+)_steps_per_s$")
SINGLE_CARTPOLE_FIGURE = "cartpole_steps_per_s"


def lower_is_better(name: str) -> bool:
    """Whether figure ``name`` meets its goal at or below it (times, time ratios, memory, start-up), not above."""
    return name.endswith(("_us", "_ms", "_kb_per_env", "_time_ratio", "_start_s", "_all_envs_s"))


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


def steps_per_second(env, policy, seconds: float, seed: int, parallel: bool = False) -> float:
    """Env steps per second of ``env`` under ``policy(info) -> action`` for about ``seconds``; ``parallel``: of a
    PettingZoo parallel env, ``policy(infos) -> actions`` (a step of every robot)."""
    info = env.reset(seed=seed)[1]

    def step() -> None:
        nonlocal info
        _, _, terminated, truncated, info = env.step(policy(info))
        if (not env.agents) if parallel else (terminated or truncated):
            info = env.reset()[1]

    return _timed_steps(step, seconds)


def figure_name(env_id: str) -> str:
    """The env id as a figure name: ``infonav/LandmarkSelection-v0`` -> ``landmark_selection``, no version."""
    name = re.sub(r"[-_]v\d+$", "", env_id.rsplit("/", 1)[-1])
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


def benchmarked_env_ids() -> list[str]:
    """Every registered env that can be made here (``available_envs``), in registration order: each one's steps per
    second are measured."""
    return [entry.id for entry in available_envs()]


def _random_stepper(env_id: str, seconds: float, seed: int):
    """A function measuring ``env_id``'s steps per second under random valid actions (robot ``k``: seed + k)."""
    env = make_env(env_id)
    if api_of(env_id) == PARALLEL:
        agents = {
            name: RandomAgent(env.action_space(name).n, seed=seed + k) for k, name in enumerate(env.possible_agents)
        }

        def policy(infos: dict) -> dict:
            return {name: agents[name].act(None, infos[name]) for name in env.agents}

        return lambda: steps_per_second(env, policy, seconds, seed, parallel=True)
    agent = RandomAgent(env.action_space.n, seed=seed)
    return lambda: steps_per_second(env, lambda info: agent.act(None, info), seconds, seed)


def _vector_stepper(run: VectorRun, seconds: float):
    """``run``'s env-steps per second; reset once, so the rounds go on where the last stopped (autoresets timed too)."""
    run.start()
    return lambda: _timed_steps(run.step, seconds) * run.num_envs


def vector_runs(env_ids: list[str], vector_sizes, seed: int) -> dict[str, VectorRun]:
    """The vector envs timed at each size N: ``cartpole_vector_N``, ``vmas_navigation_N`` (when vmas imports) and
    ``NAME_vector_N`` for each of ``env_ids`` with a native vector env."""
    vector_ids = [env_id for env_id in vector_env_ids() if env_id in env_ids]
    runs = {}
    for size in vector_sizes:
        runs[f"cartpole_vector_{size}"] = cartpole_vector_run(size, seed)
        if vmas_missing() is None:
            runs[f"vmas_navigation_{size}"] = vmas_navigation_run(size, seed)
        for env_id in vector_ids:
            runs[f"{figure_name(env_id)}_vector_{size}"] = vector_env_run(env_id, size, seed)
    return runs


def _rates_in_rounds(steppers: dict, rounds: int, progress: bool = False) -> dict:
    """Each of ``steppers``' rates, one a round: every round calls each stepper once, in turn."""
    rates = {name: [] for name in steppers}
    for _ in tqdm(range(rounds), desc="benchmark rounds", disable=not progress):
        for name, stepper in steppers.items():
            rates[name].append(stepper())
    return rates


def _median_ratio(rates: dict, name, reference) -> float:
    """The median over rounds of ``name``'s rate over ``reference``'s in the same round."""
    return statistics.median(ours / theirs for ours, theirs in zip(rates[name], rates[reference]))


def env_step_figures(
    env_ids: list[str] | None = None,
    rounds: int = 5,
    seconds_per_round: float = 1.0,
    seed: int = 0,
    progress=True,
    vector_sizes=DEFAULT_VECTOR_SIZES,
) -> dict:
    """Median steps/s of each env (default: all), CartPole-v1 and the vector envs: ``NAME_steps_per_s``,
    ``NAME_vs_cartpole_ratio`` and, for our vector envs, ``NAME_vector_N_vs_single_ratio`` / ``_vs_vmas_ratio``."""
    vector_sizes = check_vector_sizes(vector_sizes)
    env_ids = benchmarked_env_ids() if env_ids is None else env_ids
    cartpole = gym.make("CartPole-v1")
    cartpole.action_space.seed(seed)
    steppers = {
        "cartpole": lambda: steps_per_second(
            cartpole, lambda info: cartpole.action_space.sample(), seconds_per_round, seed
        )
    }
    for env_id in env_ids:
        steppers[figure_name(env_id)] = _random_stepper(env_id, seconds_per_round, seed)
    for name, run in vector_runs(env_ids, vector_sizes, seed).items():
        steppers[name] = _vector_stepper(run, seconds_per_round)
    rates = _rates_in_rounds(steppers, rounds, progress)
    figures = {f"{name}_steps_per_s": statistics.median(values) for name, values in rates.items()}
    for name in list(steppers)[1:]:
        figures[f"{name}_vs_cartpole_ratio"] = _median_ratio(rates, name, "cartpole")
    for env_id in env_ids:
        for size in vector_sizes:
            name, vmas = f"{figure_name(env_id)}_vector_{size}", f"vmas_navigation_{size}"
            if name in rates:
                figures[f"{name}_vs_single_ratio"] = _median_ratio(rates, name, figure_name(env_id))
            if name in rates and vmas in rates:
                figures[f"{name}_vs_vmas_ratio"] = _median_ratio(rates, name, vmas)
    return figures


TORCHRL_ENV_IDS, TORCHRL_COPIES = ("cooperative_localization_v0", "cooperative_exploration_v0"), 256


def torchrl_figures(rounds: int, seconds_per_round: float, seed: int) -> dict:
    """Each of ``TORCHRL_ENV_IDS`` as the suite's TorchRL env against its native vector env, ``TORCHRL_COPIES``
    copies each, in alternating rounds: ``NAME_torchrl_N_steps_per_s``, ``NAME_torchrl_N_native_steps_per_s`` and
    ``NAME_torchrl_N_vs_native_ratio``; none without torchrl."""
    if torchrl_missing():
        return {}
    makeable = {entry.id for entry in available_envs(PARALLEL)}
    steppers = {}
    for env_id in (env_id for env_id in TORCHRL_ENV_IDS if env_id in makeable):
        name = f"{figure_name(env_id)}_torchrl_{TORCHRL_COPIES}"
        steppers[f"{name}_native"] = _vector_stepper(vector_env_run(env_id, TORCHRL_COPIES, seed), seconds_per_round)
        steppers[name] = _vector_stepper(torchrl_env_run(env_id, TORCHRL_COPIES, seed), seconds_per_round)
    rates = _rates_in_rounds(steppers, rounds)
    figures = {f"{name}_steps_per_s": statistics.median(values) for name, values in rates.items()}
    for name in steppers:
        if not name.endswith("_native"):
            figures[f"{name}_vs_native_ratio"] = _median_ratio(rates, name, f"{name}_native")
    return figures


THREADED_ENV, THREADED_COPIES = "infonav/LandmarkSelection-v0", 4096  # the 2-thread against 1-thread figure's


def threads_figures(rounds: int, seconds_per_round: float, seed: int) -> dict:
    """``THREADED_ENV``'s vector env of ``THREADED_COPIES`` copies on 2 threads against 1, in alternating rounds:
    ``NAME_vector_4096_threads_2_vs_1_ratio`` (median of the rounds' ratios); none on a single CPU."""
    if (os.cpu_count() or 1) < 2:
        return {}
    runs = {threads: vector_env_run(THREADED_ENV, THREADED_COPIES, seed, threads) for threads in (1, 2)}
    rates = _rates_in_rounds({count: _vector_stepper(run, seconds_per_round) for count, run in runs.items()}, rounds)
    return {f"{figure_name(THREADED_ENV)}_vector_{THREADED_COPIES}_threads_2_vs_1_ratio": _median_ratio(rates, 2, 1)}


def memory_figures(
    num_envs: int,
    env_ids: list[str] | None = None,
    seed: int = 0,
    steps: int = MEMORY_STEPS,
    seconds: float = MEMORY_SECONDS,
) -> dict:
    """``NAME_vector_N_kb_per_env`` at N = ``num_envs`` of each of ``env_ids`` (default: ``benchmarked_env_ids``) with
    a native vector env (``vector_timing.kb_per_env``); none where ``memory_missing`` says so."""
    if memory_missing():
        return {}
    env_ids = benchmarked_env_ids() if env_ids is None else env_ids
    vector_ids = [env_id for env_id in vector_env_ids() if env_id in env_ids]
    return {
        f"{figure_name(env_id)}_vector_{num_envs}_kb_per_env": kb_per_env(env_id, num_envs, steps, seed, seconds)
        for env_id in vector_ids
    }


def greedy_decision_us(n_candidates: int = 16, seed: int = 0, repeats: int = 20000) -> float:
    """Microseconds per ``GreedyEntropyAgent.act`` over ``n_candidates`` with a random mask."""
    rng = np.random.default_rng(seed)
    info = {
        "action_mask": (rng.random(n_candidates) < 0.5).astype(np.int8),
        "action_information_gain": rng.random(n_candidates),
    }
    agent = GreedyEntropyAgent()
    return min(timeit.repeat(lambda: agent.act(None, info), number=repeats, repeat=5)) / repeats * 1e6


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


def _missing_peers() -> tuple:
    """Why figures against VMAS, the registration peers or of memory are absent (None each where they are not)."""
    return vmas_missing(), registration_peers_missing(), memory_missing()


def run_benchmark(
    rounds: int = 5,
    seconds_per_round: float = 1.0,
    seed: int = 0,
    progress: bool = True,
    vector_sizes=DEFAULT_VECTOR_SIZES,
) -> dict:
    """Measure every speed goal: the figures, whether each goal is met and ``notes`` on what is absent, JSON-ready."""
    vector_sizes = check_vector_sizes(vector_sizes)
    figures = env_step_figures(None, rounds, seconds_per_round, seed, progress, vector_sizes)
    figures.update(threads_figures(rounds, seconds_per_round, seed))
    figures.update(torchrl_figures(rounds, seconds_per_round, seed))
    scale = min(seconds_per_round, 1.0)  # --seconds below 1 (quick runs) shortens the memory, evaluation and RLlib runs
    figures.update(memory_figures(max(vector_sizes), seed=seed, seconds=MEMORY_SECONDS * scale))
    figures["greedy_decision_us"] = greedy_decision_us()
    figures.update(sensor_figures(seconds_per_round, seed))
    figures.update(icp_figures(seconds_per_round, seed))
    figures.update(map_step_figures(min(rounds, 3), 2 * seconds_per_round, seed))
    figures.update(_ppo_figures(rounds, seconds_per_round, seed))
    figures.update(evaluation_workers_figures(min(rounds, 3), seed, max(2, round(EVALUATION_EPISODES * scale))))
    figures.update(rllib_runner_figures(seed, max(100, round(RLLIB_SAMPLE_STEPS * scale))))
    figures.update(training_figures(seed, None if scale >= 1 else QUICK_TRAINING_COPIES))
    figures.update(startup_figures(benchmarked_env_ids()))
    met = {}
    for name, goal in GOALS.items():  # None: not measured
        value = figures.get(name)
        met[name] = None if value is None else (value <= goal if lower_is_better(name) else value >= goal)
    return {
        "figures": figures,
        "goals": GOALS,
        "goals_met": met,
        "notes": [note for note in (*_missing_peers(), rllib_missing(), torchrl_missing()) if note],
        "rounds": rounds,
        "seconds_per_round": seconds_per_round,
        "vector_sizes": list(vector_sizes),
    }


def throughput_curves(figures: dict) -> dict[str, dict[int, float]]:
    """``{curve: {N: env-steps/s}}`` of every ``CURVE_N_steps_per_s`` figure (vector envs, CartPoleVectorEnv, VMAS)."""
    curves: dict[str, dict[int, float]] = {}
    for name, value in figures.items():
        if match := CURVE_FIGURE.match(name):
            curves.setdefault(match["curve"], {})[int(match["size"])] = value
    return curves


def plot_throughput(figures: dict, path: Path | str) -> Path:
    """Write ``figure_throughput(figures)`` to ``path`` (needs matplotlib)."""
    return save_figure(figure_throughput(figures), path, dpi=120)


def goal_fractions(figures: dict) -> dict[str, float]:
    """How far each measured figure of ``GOALS`` is along its goal: figure / goal, goal / figure where
    ``lower_is_better`` (>= 1: met)."""
    return {
        name: goal / figures[name] if lower_is_better(name) else figures[name] / goal
        for name, goal in GOALS.items()
        if figures.get(name, 0) > 0
    }


def figure_throughput(figures: dict):
    """``throughput_curves(figures)`` log-log, CartPole-v1's single-env rate as a horizontal line; beside them the
    ``goal_fractions`` of the measured goals (log scale, met right of 1)."""
    curves, fractions = throughput_curves(figures), goal_fractions(figures)
    if not curves:
        raise ValueError(f"the throughput plot needs figures named CURVE_N_steps_per_s, got {sorted(figures)}")
    figure = matplotlib_figure("the throughput plot", figsize=(15 if fractions else 9, 4.8), layout="constrained")
    axes, goals = figure.subplots(1, 2, width_ratios=(3, 2)) if fractions else (figure.add_subplot(), None)
    if goals is not None:
        names = list(fractions)
        colors = ["tab:green" if fractions[name] >= 1 else "tab:red" for name in names]
        goals.barh(names, [fractions[name] for name in names], color=colors)
        goals.axvline(1.0, color="black", linewidth=1)
        goals.set(xscale="log", xlabel="figure / goal [-] (inverted where lower is better)\nmet at >= 1")
        goals.tick_params(axis="y", labelsize="x-small")
        goals.invert_yaxis()
        goals.set_title("Speed goals (infonav benchmark)")
    for curve, rates in curves.items():
        sizes = sorted(rates)
        axes.loglog(sizes, [rates[size] for size in sizes], marker="o", label=curve)
    if SINGLE_CARTPOLE_FIGURE in figures:
        axes.axhline(figures[SINGLE_CARTPOLE_FIGURE], color="black", linestyle="--", label="CartPole-v1 (single env)")
    axes.set(xlabel="sub-envs per vector env, N [-]", ylabel="throughput [env-steps/s]")
    axes.set_title("Throughput, one process (infonav benchmark)")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.02, 1.0))
    return figure
