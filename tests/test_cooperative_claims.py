"""Cooperative localization claims: consistency of the joint filter, greedy-entropy beats random for the team."""

import numpy as np
import pytest

from agents import GreedyEntropyAgent, RandomAgent
from infonav_gym.estimation import chi2_bounds
from infonav_gym.geometry import wrap_angle
from infonav_gym.multi import cooperative_localization_v0

# claims over 50 runs: slow; `pytest -m "not slow"` leaves it out while developing
pytestmark = pytest.mark.slow

N_RUNS = 50
N_SEEDS = 20
CONVOY = {"scenario": "convoy", "n_robots": 3, "max_cycles": 120}  # robot_1 loses DGPS at 21 s


def joint_nees_per_step(estimator: str, seed: int) -> list[float]:
    """NEES of the whole team's state at every step of one greedy-team convoy episode."""
    env = cooperative_localization_v0.parallel_env(estimator=estimator, **CONVOY)
    observations, infos = env.reset(seed=seed)
    agent, values = GreedyEntropyAgent(), []
    while env.agents:
        truth = np.concatenate([infos[name]["true_pose"] for name in env.agents])
        x, P = (part[0] for part in env.vector.joint_state())
        error = x - truth
        error[2::3] = wrap_angle(error[2::3])
        values.append(float(error @ np.linalg.solve(P, error)))
        actions = {name: agent.act(observations[name], infos[name]) for name in env.agents}
        observations, _, _, _, infos = env.step(actions)
    return values


@pytest.fixture(scope="module")
def average_nees() -> dict:
    return {
        estimator: np.mean([joint_nees_per_step(estimator, seed) for seed in range(N_RUNS)], axis=0)
        for estimator in ("joint", "independent")
    }


def test_joint_ekf_with_cross_covariances_is_consistent_through_a_dgps_dropout(average_nees):
    low, high = chi2_bounds(9, N_RUNS)
    joint = average_nees["joint"]
    inside = (joint >= low) & (joint <= high)
    assert low <= joint.mean() <= high, f"grand mean NEES {joint.mean():.2f} outside [{low:.2f}, {high:.2f}]"
    assert inside.mean() >= 0.9, f"only {inside.mean():.0%} of steps inside [{low:.2f}, {high:.2f}]"


def test_independent_estimator_is_overconfident_in_the_same_scenario(average_nees):
    low, high = chi2_bounds(9, N_RUNS)
    independent = average_nees["independent"]
    inside = (independent >= low) & (independent <= high)
    assert independent.mean() > high, f"grand mean NEES {independent.mean():.2f} not above {high:.2f}"
    assert inside.mean() < 0.9, f"{inside.mean():.0%} of steps inside: the consistency test would pass"


def team_episode(policy: str, seed: int) -> tuple[float, float]:
    """Team cumulative MI [nats] and mean over robots of the position RMSE [m] of one default-env episode."""
    env = cooperative_localization_v0.parallel_env(team_reward=1.0)
    observations, infos = env.reset(seed=seed)
    n_actions = env.action_space("robot_0").n
    agents = {
        name: GreedyEntropyAgent() if policy == "greedy" else RandomAgent(n_actions, seed=100 * seed + k, noop_action=0)
        for k, name in enumerate(env.agents)
    }
    team_information, squared_errors, steps = 0.0, np.zeros(len(env.agents)), 0
    while env.agents:
        actions = {name: agents[name].act(observations[name], infos[name]) for name in env.agents}
        observations, _, _, _, infos = env.step(actions)
        team_information += infos["robot_0"]["reward_team_mutual_information"]
        squared_errors += [info["position_error_m"] ** 2 for info in infos.values()]
        steps += 1
    return team_information, float(np.mean(np.sqrt(squared_errors / steps)))


def test_team_greedy_entropy_beats_random_teammate_choice_in_information_and_rmse():
    greedy = np.array([team_episode("greedy", seed) for seed in range(N_SEEDS)])
    random = np.array([team_episode("random", seed) for seed in range(N_SEEDS)])
    assert greedy[:, 0].mean() > random[:, 0].mean() and np.all(greedy[:, 0] > random[:, 0])
    assert greedy[:, 1].mean() < random[:, 1].mean()


def test_random_agent_noop_action_is_taken_only_when_nothing_else_is_valid():
    agent = RandomAgent(5, seed=0, noop_action=0)
    some = {"action_mask": np.array([1, 0, 1, 1, 0], dtype=np.int8)}
    assert {agent.act(None, some) for _ in range(50)} == {2, 3}
    assert agent.act(None, {"action_mask": np.array([1, 0, 0, 0, 0], dtype=np.int8)}) == 0
    with pytest.raises(ValueError, match="noop_action"):
        RandomAgent(5, noop_action=5)
