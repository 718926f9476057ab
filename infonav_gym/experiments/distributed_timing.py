"""What the benchmark measures of parallel evaluation (2 workers against 1) and of RLlib's env runners (on the team
env with 2 against 1, and on the exploration env with 1), when Ray imports."""

from __future__ import annotations

import importlib.util
import statistics
import time

from infonav_gym.experiments.evaluation import evaluate

EVALUATION_ENV_ID, EVALUATION_AGENTS, EVALUATION_EPISODES = "infonav/LandmarkSelection-v0", ("random", "greedy"), 20
TEAM_ID, EXPLORATION_ID = "cooperative_localization_v0", "cooperative_exploration_v0"
RLLIB_SAMPLE_STEPS = 2000  # env steps each runner samples per measurement (at --seconds 1)


def evaluation_workers_figures(rounds: int = 3, seed: int = 0, episodes: int = EVALUATION_EPISODES) -> dict:
    """Median wall times of the evaluation with 1 and 2 workers and their median ratio (2 / 1)."""
    times = {1: [], 2: []}
    for _ in range(rounds):
        for workers in times:
            start = time.perf_counter()
            evaluate(EVALUATION_ENV_ID, list(EVALUATION_AGENTS), episodes, seed, progress=False, workers=workers)
            times[workers].append(time.perf_counter() - start)
    ratios = [two / one for one, two in zip(times[1], times[2])]
    return {
        "evaluation_1_worker_s": statistics.median(times[1]),
        "evaluation_2_workers_s": statistics.median(times[2]),
        "evaluation_2_workers_time_ratio": statistics.median(ratios),
        "evaluation_episodes_per_agent": episodes,
    }


def rllib_missing() -> str | None:
    """Why the RLlib figures are absent (Ray does not import), or None."""
    if importlib.util.find_spec("ray") is None:
        return 'RLlib figures absent: ray is not installed; pip install "infonav-gym[distributed]"'
    return None


def _sampled_steps_per_second(num_env_runners: int, seed: int, steps: int, env_id: str) -> float:
    """Env steps/s the ``num_env_runners`` runners of a fresh PPO on ``env_id`` sample at once."""
    from agents.ppo import load_hyperparameters
    from agents.rllib_train import build_config

    config = build_config(env_id, {}, seed, load_hyperparameters(env_id), num_env_runners=num_env_runners)
    algorithm = config.build_algo()
    try:
        group = algorithm.env_runner_group

        def sample(runner):
            return sum(len(episode) for episode in runner.sample(num_timesteps=steps))

        group.foreach_env_runner(sample, local_env_runner=False)  # warm-up: modules, envs, first episodes
        start = time.perf_counter()
        steps = sum(group.foreach_env_runner(sample, local_env_runner=False))
        return steps / (time.perf_counter() - start)
    finally:
        algorithm.stop()


def rllib_runner_figures(seed: int = 0, steps: int = RLLIB_SAMPLE_STEPS, env_id: str = TEAM_ID) -> dict:
    """Sampled env-steps/s on ``env_id`` with 1 and 2 runners, their ratio, and on the exploration env with 1."""
    if rllib_missing():
        return {}
    from agents.ray_support import local_or_cluster_ray

    with local_or_cluster_ray():
        one, two = (_sampled_steps_per_second(runners, seed, steps, env_id) for runners in (1, 2))
        exploration = _sampled_steps_per_second(1, seed, steps, EXPLORATION_ID)
    return {
        "rllib_team_1_runner_steps_per_s": one,
        "rllib_team_2_runners_steps_per_s": two,
        "rllib_team_2_runners_vs_1_ratio": two / one,
        "rllib_exploration_1_runner_steps_per_s": exploration,
    }
