"""Decisions that do not flip on rounding (``infonav_gym.decisions``): the near-tie rule against its definition,
and whole episodes of every deciding agent with its inputs perturbed by 1e-13 relative, as another CPU's BLAS
kernels round them, against the same episodes unperturbed."""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents import GreedyEntropyAgent, NearestAgent, PlannerAgent
from infonav_gym.decisions import (
    DECISION_ATOL,
    DECISION_RTOL,
    argmax_tied,
    descending_tied,
    is_positive,
    top_k_tied,
)
from infonav_gym.multi import cooperative_exploration_v0
from infonav_gym.registration.control_points import DEFAULT_POSE_COVARIANCE, select_control_points
from infonav_gym.sensors.ladar import Ladar
from infonav_gym.world.terrain import Box
from infonav_gym.world.terrain_generation import flat_terrain, make_terrain

PERTURBATION = 1e-13  # relative: far above a step's rounding (~1e-15), far below the tie band (1e-9)
TEAM_CONFIG = {"max_cycles": 20}  # a short whole episode of the four-robot team planner


def nudged(values, rng: np.random.Generator) -> np.ndarray:
    """``values`` each times ``1 + PERTURBATION u``, ``u`` uniform in [-1, 1] (infinities stay)."""
    values = np.asarray(values, dtype=float)
    return values * (1.0 + PERTURBATION * rng.uniform(-1.0, 1.0, values.shape))


def nudged_symmetric(matrices, rng: np.random.Generator) -> np.ndarray:
    """Symmetric matrices (..., n, n) nudged entry by entry, staying symmetric."""
    factors = PERTURBATION * rng.uniform(-1.0, 1.0, np.shape(matrices))
    return np.asarray(matrices) * (1.0 + 0.5 * (factors + np.swapaxes(factors, -1, -2)))


class PerturbedModel:
    """A planning model whose beliefs, gains, rewards and stds come out nudged (``nudged``), as on another CPU."""

    def __init__(self, model, rng: np.random.Generator):
        self.model, self.rng = model, rng

    def __getattr__(self, name):
        return getattr(self.model, name)

    def _belief(self, belief):
        changes = {"covariance": nudged_symmetric(belief.covariance, self.rng)}
        for name in ("pose", "x", "map_variances"):
            if hasattr(belief, name):
                changes[name] = nudged(getattr(belief, name), self.rng)
        return dataclasses.replace(belief, **changes)

    def belief(self):
        return self._belief(self.model.belief())

    def plan_decision(self, belief, *robot):
        mask, gains = self.model.plan_decision(belief, *robot)
        return mask, nudged(gains, self.rng)

    def plan_step(self, belief, actions):
        following, rewards = self.model.plan_step(belief, actions)
        return self._belief(following), nudged(rewards, self.rng)

    def position_std(self, covariances):
        return nudged(self.model.position_std(covariances), self.rng)


def nudged_info(info: dict, rng: np.random.Generator | None) -> dict:
    """``info`` with its expected gains nudged (unchanged without ``rng``)."""
    if rng is None:
        return info
    return {**info, "action_information_gain": nudged(info["action_information_gain"], rng)}


def perturb(agent, rng: np.random.Generator) -> None:
    """Give a ``PlannerAgent`` (single or team) a ``PerturbedModel``."""
    if hasattr(agent.model, "plans"):  # a robot's view of the team model
        agent.model.model = PerturbedModel(agent.model.model, rng)
    else:
        agent.model = PerturbedModel(agent.model, rng)


def episode_actions(env_id: str, make_agent, seed: int, rng: np.random.Generator | None) -> list[int]:
    """The actions of one whole seeded episode of a Gymnasium env (``rng``: perturb the agent's inputs)."""
    env = gym.make(env_id)
    agent = make_agent(env)
    if rng is not None and isinstance(agent, PlannerAgent):
        perturb(agent, rng)
    observation, info = env.reset(seed=seed)
    actions, done = [], False
    while not done:
        actions.append(agent.act(observation, nudged_info(info, rng)))
        observation, _, terminated, truncated, info = env.step(actions[-1])
        done = terminated or truncated
    env.close()
    return actions


def team_episode_actions(seed: int, rng: np.random.Generator | None) -> list[dict]:
    """The team planner's actions along one whole seeded episode of a small cooperative_exploration_v0."""
    env = cooperative_exploration_v0.parallel_env(**TEAM_CONFIG)
    planners = {robot: PlannerAgent(env, robot, rollout_steps=8, detour_steps=(0,)) for robot in env.possible_agents}
    for planner in planners.values():
        if rng is not None:
            perturb(planner, rng)
    observations, infos = env.reset(seed=seed)
    chosen = []
    while env.agents:
        actions = {
            robot: planners[robot].act(observations[robot], nudged_info(infos[robot], rng)) for robot in env.agents
        }
        chosen.append(actions)
        observations, _, _, _, infos = env.step(actions)
    env.close()
    return chosen


# ----------------------------------------------------------------------------- the rule


def test_values_inside_the_band_tie_and_the_lowest_index_wins():
    best = 2.0
    inside, outside = best * (1 - 0.5 * DECISION_RTOL), best * (1 - 2 * DECISION_RTOL)
    assert argmax_tied([0.0, inside, best]) == 1
    assert argmax_tied([0.0, outside, best]) == 2
    assert argmax_tied([0.5 * DECISION_ATOL, 0.0]) == 0, "gains of a few ulps around 0 are no preference"
    assert argmax_tied([2 * DECISION_ATOL, 0.0]) == 0 and argmax_tied([0.0, 2 * DECISION_ATOL]) == 1
    assert argmax_tied([-np.inf, -np.inf]) == 0 and argmax_tied([np.nan, 1.0, np.nan]) == 1
    assert argmax_tied(np.array([[1.0, 3.0], [3.0, 1.0]]), axis=0).tolist() == [1, 0]
    assert top_k_tied([1.0, best, inside, -np.inf], 4).tolist() == [1, 2, 0, 3]
    assert top_k_tied(np.array([[1.0, 2.0, 3.0]]), 5, axis=1).tolist() == [[2, 1, 0]]
    assert is_positive([0.0, DECISION_ATOL / 2, 1e-6]).tolist() == [False, False, True]
    assert descending_tied([1.0, inside, best, 3.0, best * (1 + 0.5 * DECISION_RTOL)]).tolist() == [3, 1, 2, 4, 0]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-50, 50), min_size=1, max_size=12), st.integers(1, 12))
def test_apart_from_near_ties_top_k_is_the_stable_descending_order(levels, k):
    """Values on a grid 1e-3 apart (no near-ties but exact ones): the stable sort's order."""
    values = np.array(levels) * 1e-3
    assert top_k_tied(values, k).tolist() == np.argsort(-values, kind="stable")[:k].tolist()
    assert descending_tied(values).tolist() == np.argsort(-values, kind="stable").tolist()
    assert argmax_tied(values) == int(np.argmax(values))


# ----------------------------------------------------------------------------- whole episodes, perturbed


@pytest.mark.parametrize(
    "env_id, make_agent, seed",
    [
        ("infonav/LandmarkSelection-v0", lambda env: GreedyEntropyAgent(), 0),
        ("infonav/LandmarkSelection-v0", lambda env: GreedyEntropyAgent(), 1),
        ("infonav/ActiveLocalization-v0", lambda env: GreedyEntropyAgent(), 0),
        ("infonav/ActiveLocalization-v0", lambda env: GreedyEntropyAgent(), 1),
        ("infonav/ActiveLocalization-v0", lambda env: PlannerAgent(env), 0),
    ],
    ids=["greedy-landmarks-0", "greedy-landmarks-1", "greedy-active-0", "greedy-active-1", "planner-active-0"],
)
def test_decisions_along_a_whole_episode_survive_a_1e_13_perturbation(env_id, make_agent, seed):
    reference = episode_actions(env_id, make_agent, seed, None)
    assert reference == episode_actions(env_id, make_agent, seed, np.random.default_rng(seed))


def test_the_team_planner_decides_the_same_along_a_whole_perturbed_episode():
    reference = team_episode_actions(0, None)
    assert len(reference) > 5
    assert reference == team_episode_actions(0, np.random.default_rng(0))


@pytest.mark.parametrize("seed", range(5))
def test_the_nearest_reading_is_the_same_from_perturbed_ranges(seed):
    """Readings in repeated pairs (equal ranges in exact arithmetic), the ranges nudged."""
    rng = np.random.default_rng(seed)
    ranges = np.concatenate([[0.0], np.repeat(rng.uniform(1.0, 5.0, 4), 2)])  # action 0 fuses nothing: no range
    info = {"action_range_m": ranges, "action_mask": np.ones(len(ranges), dtype=np.int8)}
    pick = NearestAgent().act(None, info)
    perturbed = np.random.default_rng(100 + seed)
    for _ in range(3):
        assert NearestAgent().act(None, info | {"action_range_m": nudged(ranges, perturbed)}) == pick


def test_the_control_point_picks_are_the_same_under_a_perturbed_pose_prior():
    """The greedy chunk picks of ``"entropy"`` on level ground with a wall (many patches equal in exact
    arithmetic) and on rugged terrain, with the motion prior nudged."""
    flat = flat_terrain(size_m=120.0, cell_m=1.0).with_obstacles(boxes=[Box((12.0, -3.0, 0.0), (14.0, 3.0, 6.0))])
    rugged = make_terrain(np.random.default_rng(3), roughness=1.0, n_trees=25, n_rocks=8)
    rng = np.random.default_rng(0)
    for terrain in (flat, rugged):
        scan = Ladar().scan(terrain, [0.0, 0.0, 0.3], np.random.default_rng(0))
        for k in (50, 400):
            reference = select_control_points(scan, k, "entropy", pose_covariance=DEFAULT_POSE_COVARIANCE)
            again = select_control_points(
                scan, k, "entropy", pose_covariance=nudged_symmetric(DEFAULT_POSE_COVARIANCE, rng)
            )
            np.testing.assert_array_equal(again, reference)


@pytest.mark.parametrize("strategy", ["covariance", "normal_space"])
def test_the_standard_selectors_pick_the_same_from_a_perturbed_scan(strategy):
    """Level ground with a wall: thousands of returns whose constraints are equal in exact arithmetic."""
    flat = flat_terrain(size_m=120.0, cell_m=1.0).with_obstacles(boxes=[Box((12.0, -3.0, 0.0), (14.0, 3.0, 6.0))])
    rugged = make_terrain(np.random.default_rng(3), roughness=1.0, n_trees=25, n_rocks=8)
    rng = np.random.default_rng(1)
    for terrain in (flat, rugged):
        scan = Ladar().scan(terrain, [0.0, 0.0, 0.3], np.random.default_rng(0))
        nudged = dataclasses.replace(
            scan, ranges_m=scan.ranges_m * (1 + 1e-13 * rng.standard_normal(scan.ranges_m.shape))
        )
        for k in (50, 400):
            reference = select_control_points(scan, k, strategy, np_random=np.random.default_rng(2))
            again = select_control_points(nudged, k, strategy, np_random=np.random.default_rng(2))
            np.testing.assert_array_equal(again, reference)
