"""Cooperative exploration claims: the JointEKF stays consistent on the env's observations (50 Monte Carlo runs)."""

import numpy as np
from conftest import greedy_actions

from infonav_gym.estimation import chi2_bounds
from infonav_gym.estimation.consistency import pose_error
from infonav_gym.multi import cooperative_exploration_v0
from infonav_gym.multi.cooperative_exploration import N_MOTIONS

N_RUNS = 50
STEPS = 30
OPEN_ENDED = {"max_cycles": STEPS, "max_position_std_m": 100.0, "coverage_target": 1.0}  # no early end


def joint_nees_per_step(seed: int) -> list[float]:
    """NEES of the whole team's state (12 dof) at every step of an episode of greedy observations, standing still.

    Every robot takes the observation greedy would (a landmark, a teammate or none) and stays: the updates
    are the env's landmark, relative-pose and DGPS updates with noisy odometry of no motion, and no contact.
    """
    env = cooperative_exploration_v0.parallel_env(**OPEN_ENDED)
    _, infos = env.reset(seed=seed)
    values = []
    while env.agents:
        truth = np.array([infos[name]["true_pose"] for name in env.agents])
        error = pose_error(truth, env.ekf.x.reshape(-1, 3)).ravel()
        values.append(float(error @ np.linalg.solve(env.ekf.P, error)))
        actions = {agent: N_MOTIONS * (action // N_MOTIONS) for agent, action in greedy_actions(env, infos).items()}
        _, _, _, _, infos = env.step(actions)
    return values


def test_joint_ekf_is_consistent_on_the_envs_landmark_relative_pose_and_dgps_updates():
    average = np.mean([joint_nees_per_step(seed) for seed in range(N_RUNS)], axis=0)
    low, high = chi2_bounds(12, N_RUNS)
    inside = (average >= low) & (average <= high)
    assert len(average) == STEPS
    assert low <= average.mean() <= high, f"grand mean NEES {average.mean():.2f} outside [{low:.2f}, {high:.2f}]"
    assert inside.mean() >= 0.9, f"only {inside.mean():.0%} of steps inside [{low:.2f}, {high:.2f}]"
