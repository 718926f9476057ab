"""The hooks of ``InfoNavEnv``: declared, called as their contracts say; the planning model."""

import pickle

import gymnasium as gym
import numpy as np
import pytest
from conftest import assert_identical
from gymnasium import spaces

import infonav_gym  # noqa: F401  (registers the envs)
from agents.planner import PlannerAgent, planning_model
from infonav_gym.envs.base import Decision, InfoNavEnv
from infonav_gym.multi import cooperative_exploration_v0, cooperative_localization_v0
from infonav_gym.registry import env_entry

REQUIRED_HOOKS = {"_reset_episode", "_next_decision", "_apply_action", "_observation", "_scene_frame"}
SINGLE_AGENT_IDS = sorted(
    env_id
    for env_id, spec in gym.registry.items()
    if isinstance(spec.entry_point, str) and spec.entry_point.startswith("infonav_gym.")
)
HOOKED_IDS = [env_id for env_id in SINGLE_AGENT_IDS if issubclass(env_entry(env_id).load(), InfoNavEnv)]
WALL_CLOCK_INFO_KEYS = {"icp_time_s"}


class AlternatingEnv(InfoNavEnv):
    """Action 0 is always valid, action 1 on even steps only; the reward is the chosen action's gain."""

    def __init__(self, **config):
        super().__init__(**config)
        self.action_space = spaces.Discrete(2)
        self.observation_space = spaces.Box(0.0, 1.0, (1,), dtype=np.float32)
        self.applied = []

    def _reset_episode(self):
        self.applied.clear()

    def _next_decision(self):
        even = self._elapsed_steps % 2 == 0
        return Decision(np.array([1, even], dtype=np.int8), np.array([0.0, 1.0 if even else 0.0]), self._elapsed_steps)

    def _apply_action(self, action, decision):
        self.applied.append((action, decision))
        return {"gain": 0.0 if action is None else float(decision.action_information_gain[action])}

    def _observation(self):
        return np.array([self._elapsed_steps % 2], dtype=np.float32)

    def _scene_frame(self):
        raise NotImplementedError


def test_the_required_hooks_are_abstract():
    assert InfoNavEnv.__abstractmethods__ == REQUIRED_HOOKS


@pytest.mark.parametrize("missing", sorted(REQUIRED_HOOKS))
def test_an_env_missing_a_hook_cannot_be_instantiated(missing):
    hooks = {name: getattr(AlternatingEnv, name) for name in REQUIRED_HOOKS - {missing}}
    incomplete = type("IncompleteEnv", (InfoNavEnv,), hooks)
    with pytest.raises(TypeError, match=f"abstract .*{missing}"):
        incomplete()


def test_the_base_hands_apply_action_the_decision_the_agent_saw_and_fills_the_optional_hooks():
    env = AlternatingEnv(horizon=4)
    _, info = env.reset(seed=0)
    seen, rewards = [info["action_mask"]], []
    for action in (1, 1, 1, 0):  # the second 1 comes at an odd step, where it is masked: a no-op
        _, reward, terminated, truncated, info = env.step(action)
        seen.append(info["action_mask"])
        rewards.append(reward)
    assert [action for action, _ in env.applied] == [1, None, 1, 0]
    assert [decision.payload for _, decision in env.applied] == [0, 1, 2, 3]  # each step's own decision
    for (_, decision), mask in zip(env.applied, seen):
        np.testing.assert_array_equal(decision.action_mask, mask)
    assert rewards == [1.0, 0.0, 1.0, 0.0]
    assert set(info) == {"action_mask", "action_information_gain", "reward_terms", "chosen_action", "invalid_action"}
    assert not terminated and truncated


def test_a_decision_is_frozen_and_its_arrays_read_only():
    env = AlternatingEnv()
    env.reset(seed=0)
    decision = env._decision
    with pytest.raises(AttributeError):
        decision.payload = 1
    with pytest.raises(ValueError, match="read-only"):
        decision.action_mask[0] = 0
    with pytest.raises(ValueError, match="read-only"):
        decision.action_information_gain[1] = 2.0


def _without_wall_clock(transition):
    return [
        {k: v for k, v in part.items() if k not in WALL_CLOCK_INFO_KEYS} if isinstance(part, dict) else part
        for part in transition
    ]


@pytest.mark.parametrize("env_id", HOOKED_IDS)  # an env written once has no single-env decision hook
def test_next_decision_changes_nothing(env_id):
    env = gym.make(env_id).unwrapped
    _, info = env.reset(seed=3)
    twin = pickle.loads(pickle.dumps(env))
    again = env._next_decision()
    np.testing.assert_array_equal(again.action_mask, info["action_mask"])
    np.testing.assert_array_equal(again.action_information_gain, info["action_information_gain"])
    action = int(np.flatnonzero(info["action_mask"])[-1]) if info["action_mask"].any() else 0
    assert_identical(_without_wall_clock(env.step(action)), _without_wall_clock(twin.step(action)))


def test_the_team_decision_changes_nothing():
    env = cooperative_localization_v0.parallel_env()
    _, infos = env.reset(seed=3)
    twin = pickle.loads(pickle.dumps(env))
    env.vector._decide()
    again = env.vector.decision
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

    env = AlternatingEnv()
    env.planning_model = Incomplete
    with pytest.raises(ValueError, match="lacks plan_decision, plan_step, position_std"):
        PlannerAgent(env)
