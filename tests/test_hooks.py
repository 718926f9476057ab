"""The team decision and the planning model (the protocol's own checks: ``test_protocol.py``)."""

import pickle

import gymnasium as gym
import numpy as np
import pytest
from conftest import assert_identical

import infonav_gym  # noqa: F401  (registers the envs)
from agents.planner import PlannerAgent, planning_model
from infonav_gym.multi import cooperative_exploration_v0, cooperative_localization_v0


def test_the_team_decision_changes_nothing():
    env = cooperative_localization_v0.parallel_env()
    _, infos = env.reset(seed=3)
    twin = pickle.loads(pickle.dumps(env))
    again = env.vector.env_scenario.decision(env.vector.state, slice(None))
    np.testing.assert_array_equal(again.action_mask[0], [infos[agent]["action_mask"] for agent in env.agents])
    actions = {agent: int(np.flatnonzero(infos[agent]["action_mask"])[-1]) for agent in env.agents}
    assert_identical(env.step(actions), twin.step(actions))


def test_the_planner_finds_the_planning_model_through_wrappers():
    env = gym.make("infonav/ActiveLocalization-v0")  # TimeLimit, OrderEnforcing, PassiveEnvChecker
    assert planning_model(env) is env.unwrapped.planning_model()
    assert PlannerAgent(env).model is planning_model(env)


def test_a_team_view_has_its_copys_planning_model_when_its_vector_env_has_one():
    env = cooperative_exploration_v0.parallel_env()
    assert planning_model(env) is env.vector.planning_model(0) is env.planning_model()
    assert not hasattr(cooperative_localization_v0.parallel_env(), "planning_model")


def test_an_env_without_a_planning_model_is_a_clear_error():
    with pytest.raises(ValueError, match=r"planning_model\(\) method .*LandmarkSelectionEnv.* has none"):
        PlannerAgent(gym.make("infonav/LandmarkSelection-v0"))


def test_a_planning_model_missing_a_method_is_a_clear_error():
    class Incomplete:
        n_primitives, max_position_std_m = 5, 1.0

        def belief(self):
            raise NotImplementedError

    env = gym.make("infonav/LandmarkSelection-v0").unwrapped
    env.planning_model = Incomplete
    with pytest.raises(ValueError, match="lacks plan_decision, plan_step, position_std"):
        PlannerAgent(env)
