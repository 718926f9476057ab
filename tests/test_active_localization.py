"""ActiveLocalization-v0: goal and failure terms, the sensing budget, costs, exact gains, the planning model.

The checks every registered env passes (checkers, determinism, pickle, spawn, info
contract) live in ``test_envs.py``; these are the semantics of this env alone, and
the direction of the baseline ranking (planner > greedy > random) on a few seeds.
"""

import pickle

import gymnasium as gym
import numpy as np
import pytest

import infonav_gym  # noqa: F401
from agents import GreedyEntropyAgent, PlannerAgent, RandomAgent
from infonav_gym.envs.active_localization import N_PRIMITIVES, REWARD_TERMS
from infonav_gym.envs.vector_infos import reward_terms_of
from infonav_gym.world import active_scenarios

ENV_ID = "infonav/ActiveLocalization-v0"
TO_GOAL = 0  # primitive 0, no observation


def observe(landmark: int, primitive: int = 0) -> int:
    return (1 + landmark) * N_PRIMITIVES + primitive


def first_visible_step(env, info, max_steps: int = 30):
    """Drive to the goal without observing until some landmark is observable; return that info."""
    for _ in range(max_steps):
        if info["action_mask"][N_PRIMITIVES:].any():
            return info
        info = env.step(TO_GOAL)[4]
    pytest.fail(f"no landmark became observable within {max_steps} steps")


def run_episode(env, agent, seed: int) -> dict:
    observation, info = env.reset(seed=seed)
    agent.reset(seed=seed)
    total = 0.0
    while True:
        action = agent.act(observation, info)
        assert info["action_mask"][action] == 1, f"agent chose masked action {action}"
        observation, reward, terminated, truncated, info = env.step(action)
        total += reward
        if terminated or truncated:
            return {"success": info["goal_reached"], "entropy": info["pose_entropy"], "return": total}


def test_the_goal_fields_obstacle_attempts_drawn_ahead_change_neither_the_field_nor_the_generator(monkeypatch):
    """As many attempts as obstacles drawn at once (more drawn when some fail), one field at a time or all at once:
    the fields of four per obstacle, one at a time."""

    def fields(at_once: bool = False) -> list:
        generators = [np.random.default_rng(seed) for seed in range(30)]
        if at_once:
            layouts = active_scenarios.goal_field_layouts(generators, n_obstacles=6)
            fields = active_scenarios.goal_field_scenarios(layouts)
        else:
            fields = [active_scenarios.goal_field(rng, n_obstacles=6) for rng in generators]
        return [(field.obstacles, field.landmarks.tolist(), rng.random()) for field, rng in zip(fields, generators)]

    expected = fields()
    monkeypatch.setattr(active_scenarios, "OBSTACLE_ATTEMPTS_AHEAD", 1)
    assert fields() == expected
    assert fields(at_once=True) == expected


def test_reaching_the_goal_terminates_with_the_bonus():
    env = gym.make(ENV_ID, goal_radius_m=40.0, goal_bonus=7.0)
    env.reset(seed=0)
    _, reward, terminated, truncated, info = env.step(TO_GOAL)
    assert terminated is True and truncated is False
    assert info["goal_reached"] is True and info["failed"] is False
    assert reward_terms_of(info)["goal_bonus"] == 7.0 and reward_terms_of(info)["failure_penalty"] == 0.0
    assert reward == pytest.approx(sum(reward_terms_of(info).values()))


def test_crossing_the_uncertainty_bound_terminates_with_the_penalty():
    env = gym.make(ENV_ID, max_position_std_m=0.3, failure_penalty=5.0)
    _, info = env.reset(seed=1)
    for _ in range(30):
        before = info["position_std_m"]
        _, reward, terminated, _, info = env.step(TO_GOAL)  # never observe: the uncertainty only grows
        assert info["position_std_m"] > before
        if terminated:
            break
    assert terminated, "the position std never crossed 0.3 m while driving blind"
    assert info["failed"] is True and info["goal_reached"] is False
    assert before <= 0.3 < info["position_std_m"]
    assert reward_terms_of(info)["failure_penalty"] == -5.0
    assert reward < -4.0


def test_the_sensing_budget_is_enforced_through_the_mask():
    env = gym.make(ENV_ID, max_observations=2).unwrapped
    _, info = env.reset(seed=0)
    for used in (1, 2):
        info = first_visible_step(env, info)
        landmark = int(np.flatnonzero(info["action_mask"][N_PRIMITIVES:])[0]) // N_PRIMITIVES
        info = env.step(observe(landmark))[4]
        assert info["observations_left"] == 2 - used
    assert info["observations_left"] == 0
    assert not info["action_mask"][N_PRIMITIVES:].any(), "observations stay valid once the budget is spent"
    assert info["action_mask"][:N_PRIMITIVES].all()
    model = env.planning_model()
    assert model.plan_decision(model.belief())[0][0, N_PRIMITIVES:].sum() == 0
    # A visible landmark with no budget left is a masked no-op: no update, no cost, the robot stays put.
    _, reward, _, _, after = env.step(observe(0))
    assert after["invalid_action"] is True and after["observations_left"] == 0
    assert reward_terms_of(after)["mutual_information"] == 0.0 and reward == 0.0
    assert np.array_equal(after["true_pose"][:2], info["true_pose"][:2])


def test_costs_appear_in_the_reward_terms():
    env = gym.make(ENV_ID, observation_cost_nats=0.3, motion_cost_per_step=0.2).unwrapped
    _, info = env.reset(seed=0)
    info = first_visible_step(env, info)
    action = int(np.argmax(info["action_information_gain"]))
    _, reward, _, _, observed = env.step(action)
    terms = reward_terms_of(observed)
    assert tuple(terms) == REWARD_TERMS
    assert terms["sensing_cost"] == -0.3 and terms["motion_cost"] == -0.2
    assert terms["mutual_information"] == pytest.approx(info["action_information_gain"][action], rel=1e-9)
    assert reward == sum(terms.values())
    moved = reward_terms_of(env.step(TO_GOAL)[4])
    assert moved["sensing_cost"] == 0.0 and moved["mutual_information"] == 0.0 and moved["motion_cost"] == -0.2
    assert moved["progress"] > 0.0  # the to_goal primitive brings the robot closer


def test_each_valid_observations_gain_equals_its_realized_mi_and_the_models_gain():
    env = gym.make(ENV_ID).unwrapped
    model = env.planning_model()
    _, info = env.reset(seed=3)
    checked = 0
    for _ in range(40):
        valid = np.flatnonzero(info["action_mask"])
        model_mask, model_gain = model.plan_decision(model.belief())
        assert np.array_equal(model_mask[0], info["action_mask"])
        np.testing.assert_allclose(model_gain[0], info["action_information_gain"], rtol=1e-12, atol=0)
        for action in valid[valid >= N_PRIMITIVES]:
            realized = reward_terms_of(pickle.loads(pickle.dumps(env)).step(int(action))[4])["mutual_information"]
            assert realized == pytest.approx(info["action_information_gain"][action], rel=1e-9, abs=0)
            _, predicted_reward = model.plan_step(model.belief(), [action])
            _, predicted_idle = model.plan_step(model.belief(), [action % N_PRIMITIVES])
            model_mi = predicted_reward[0] - predicted_idle[0] + env.config["observation_cost_nats"]
            assert model_mi == pytest.approx(realized, rel=1e-6), "the model's MI differs from the env's"
            checked += 1
        _, _, terminated, _, info = env.step(TO_GOAL)
        if terminated:
            break
    assert checked >= 10


@pytest.mark.parametrize(
    "key, value",
    [
        ("n_candidates", 3),
        ("field_size_m", 20.0),
        ("max_position_std_m", 0.05),
        ("max_observations", -1),
        ("goal_bonus", -1.0),
        ("observation_cost_nats", -0.1),
        ("goal_radius_m", 0.0),
        ("motion_cost_per_step", "cheap"),
    ],
)
def test_bad_config_raises_naming_the_key(key, value):
    with pytest.raises(ValueError, match=f"'{key}'"):
        gym.make(ENV_ID, **{key: value})


def test_planner_rejects_an_env_without_a_planning_model_and_bad_arguments():
    with pytest.raises(ValueError, match="plan_step"):
        PlannerAgent(gym.make("infonav/LandmarkSelection-v0"))
    with pytest.raises(ValueError, match="depth"):
        PlannerAgent(gym.make(ENV_ID), depth=0)


def test_planner_is_deterministic_and_works_through_wrappers():
    env = gym.make(ENV_ID)  # wrapped: PassiveEnvChecker, OrderEnforcing
    planner = PlannerAgent(env, depth=1)
    observation, info = env.reset(seed=2)
    actions = []
    for _ in range(5):
        actions.append(planner.act(observation, info))
        observation, _, _, _, info = env.step(actions[-1])
    observation, info = env.reset(seed=2)
    replayed = []
    for _ in range(5):
        replayed.append(planner.act(observation, info))
        observation, _, _, _, info = env.step(replayed[-1])
    assert actions == replayed


def test_planner_beats_greedy_and_greedy_beats_random_on_a_few_seeds():
    env = gym.make(ENV_ID)
    seeds = range(6)
    planner = [run_episode(env, PlannerAgent(env, depth=1), seed) for seed in seeds]
    greedy = [run_episode(env, GreedyEntropyAgent(), seed) for seed in seeds]
    random = [run_episode(env, RandomAgent(env.action_space.n, seed=0), seed) for seed in seeds]

    def mean(results, key):
        return float(np.mean([r[key] for r in results]))

    assert mean(planner, "success") > mean(greedy, "success")
    assert mean(planner, "entropy") < mean(greedy, "entropy")
    assert mean(greedy, "entropy") < mean(random, "entropy")
    assert mean(planner, "return") > mean(greedy, "return")
