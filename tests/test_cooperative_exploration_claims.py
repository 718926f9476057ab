"""Cooperative exploration claims: the JointEKF stays consistent on the env's observations and motions (50 Monte
Carlo runs), standing still and driving."""

import numpy as np
import pytest
from conftest import greedy_actions, random_valid_actions

from infonav_gym.envs.cooperative_exploration import N_MOTIONS
from infonav_gym.estimation import chi2_bounds
from infonav_gym.estimation.consistency import pose_error
from infonav_gym.multi import cooperative_exploration_v0

# claims over 50 runs: slow; `pytest -m "not slow"` leaves it out while developing
pytestmark = pytest.mark.slow

N_RUNS = 50
OPEN_ENDED = {"max_position_std_m": 100.0, "coverage_target": 1.0}  # no early end


def standing_greedy(env, infos, rng) -> dict:
    """The observation greedy would take (a landmark, a teammate or none), standing still."""
    return {agent: N_MOTIONS * (action // N_MOTIONS) for agent, action in greedy_actions(env, infos).items()}


def driving_greedy(env, infos, rng) -> dict:
    """Greedy's action: the GPS-less robots drive off to fresh cells, away from every reference."""
    return greedy_actions(env, infos)


def driving_random(env, infos, rng) -> dict:
    """A uniformly drawn valid action: any motion the mask allows, with any valid observation."""
    return random_valid_actions(env, infos, rng)


def joint_nees_per_step(policy, seed: int, steps: int) -> list[float]:
    """NEES of the whole team's state (12 dof) at every step of an episode of ``policy``."""
    env = cooperative_exploration_v0.parallel_env(max_cycles=steps, **OPEN_ENDED)
    _, infos = env.reset(seed=seed)
    rng, values = np.random.default_rng(seed), []
    while env.agents:
        truth = np.array([infos[name]["true_pose"] for name in env.agents])
        x, P = (part[0] for part in env.vector.joint_state())
        error = pose_error(truth, x.reshape(-1, 3)).ravel()
        values.append(float(error @ np.linalg.solve(P, error)))
        _, _, _, _, infos = env.step(policy(env, infos, rng))
    return values


@pytest.mark.parametrize(
    "policy, steps",
    [(standing_greedy, 30), (driving_greedy, 50), (driving_random, 50)],
    ids=["standing", "driving greedy", "driving random"],
)
def test_joint_ekf_is_consistent_on_the_envs_motions_and_landmark_relative_pose_and_dgps_updates(policy, steps):
    """The motion mask keeps every robot clear of contacts, so odometry sees all its motion (no unseen pushes).

    Driving runs last 50 steps: by then 8 of the 50 greedy runs have a robot past the env's
    ``max_position_std_m`` (1.5 m, lifted to 100 m here), where the env's own episode would have ended.
    """
    average = np.mean([joint_nees_per_step(policy, seed, steps) for seed in range(N_RUNS)], axis=0)
    low, high = chi2_bounds(12, N_RUNS)
    inside = (average >= low) & (average <= high)
    assert len(average) == steps
    assert low <= average.mean() <= high, f"grand mean NEES {average.mean():.2f} outside [{low:.2f}, {high:.2f}]"
    assert inside.mean() >= 0.9, f"only {inside.mean():.0%} of steps inside [{low:.2f}, {high:.2f}]"
