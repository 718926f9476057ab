"""The scenario protocol and its one driver: what a scenario must implement, and that every built-in env is one."""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import textwrap
from typing import NamedTuple

import gymnasium as gym
import numpy as np
import pytest

import infonav_gym
from infonav_gym.envs.driver import Driver
from infonav_gym.envs.protocol import EnvScenario, State
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.registry import registered_envs

BUILT_IN_IDS = {env_id for env_id, *_ in infonav_gym.BUILTIN_ENVS}
HOOKS = ("allocate", "initial", "decision", "transition", "reward", "observation", "info")


class HooklessScenario(EnvScenario):
    """A scenario that implements no function of the protocol."""

    traits = EnvTraits()


class HooklessVectorEnv(Driver, scenario=HooklessScenario):
    pass


def test_a_scenario_missing_its_functions_is_refused_naming_them():
    with pytest.raises(TypeError, match="HooklessScenario") as error:
        HooklessVectorEnv(num_envs=2)
    assert all(hook in str(error.value) for hook in HOOKS)


class CoinState(State):
    pass


class CoinDecision(NamedTuple):
    action_mask: np.ndarray
    action_information_gain: np.ndarray


class Coin(EnvScenario):
    """The smallest scenario: two actions, the second masked; reward 1 for the first; it never renders."""

    traits = EnvTraits()

    def __init__(self, config, copies, owner, render_mode):
        super().__init__(config, copies, owner, render_mode)
        self.observation_space, self.action_space = gym.spaces.Box(0, 1, (1,)), gym.spaces.Discrete(2)

    def allocate(self, copies):
        return CoinState(np.zeros(copies, dtype=int))

    def initial(self, state, rows, rngs):
        return state

    def decision(self, state, rows):
        mask = np.tile(np.array([1, 0], dtype=np.int8), (len(state.elapsed[rows]), 1))
        return CoinDecision(mask, mask * 0.5)

    def transition(self, state, decision, action, acting):
        state.last = action[:, 0].copy()
        return state

    def reward(self, decision, action, state):
        return (action[:, 0] == 0).astype(float)

    def observation(self, state, decision, rows):
        return np.zeros((len(state.elapsed[rows]), 1), dtype=np.float32)

    def info(self, state, decision, rows, stepped):
        return {}


class CoinVectorEnv(Driver, scenario=Coin):
    pass


def test_the_driver_counts_steps_checks_actions_and_truncates_at_the_horizon():
    env = CoinVectorEnv(num_envs=3, horizon=2, invalid_action="raise", autoreset_mode="next_step")
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(np.zeros(3, dtype=int))
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action 1 of sub-env 0 is not valid now"):
        env.step(np.array([1, 0, 0]))
    with pytest.raises(ValueError, match=r"action 2 of sub-env 1 is not in the action space"):
        env.step(np.array([0, 2, 0]))
    _, rewards, terminated, truncated, _ = env.step(np.zeros(3, dtype=int))
    np.testing.assert_array_equal(rewards, 1.0)
    assert not truncated.any() and not terminated.any()
    _, _, _, truncated, _ = env.step(np.zeros(3, dtype=int))
    assert truncated.all()
    _, rewards, _, truncated, _ = env.step(np.zeros(3, dtype=int))  # NEXT_STEP: the copies start again
    np.testing.assert_array_equal(rewards, 0.0)
    np.testing.assert_array_equal(env.state.elapsed, 0)
    with pytest.raises(NotImplementedError, match="does not render"):
        env.env_scenario.frame(env.state, env.decision)


def env_folder_classes() -> list[type]:
    """Every class defined in a module of an env folder (``infonav_gym/envs/<name>/``)."""
    envs = importlib.import_module("infonav_gym.envs")
    classes = []
    for folder in pkgutil.iter_modules(envs.__path__):
        if not folder.ispkg:
            continue
        package = importlib.import_module(f"infonav_gym.envs.{folder.name}")
        modules = [package] + [
            importlib.import_module(f"{package.__name__}.{module.name}")
            for module in pkgutil.iter_modules(package.__path__)
        ]
        for module in modules:
            classes += [
                value
                for value in vars(module).values()
                if inspect.isclass(value) and value.__module__ == module.__name__
            ]
    return classes


def test_every_built_in_env_is_a_scenario_on_the_one_driver():
    built_in = [entry for entry in registered_envs() if entry.load_vector().__module__.startswith("infonav_gym.")]
    assert len(built_in) == len(infonav_gym.BUILTIN_ENVS)
    for entry in built_in:
        vector = entry.load_vector()
        assert issubclass(vector, Driver) and issubclass(vector.scenario_class, EnvScenario), entry.id
        assert not inspect.isabstract(vector.scenario_class), entry.id


def test_no_env_class_defines_reset_or_step():
    classes = env_folder_classes()
    assert len(classes) >= 18
    found = [
        f"{cls.__module__}.{cls.__name__}.{name}" for cls in classes for name in ("reset", "step") if name in vars(cls)
    ]
    assert found == []


def self_assignments(function) -> list[str]:
    """The ``self.attribute`` names ``function``'s source assigns to (``self.x = ...``, ``self.x += ...``)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(function)))
    targets = [
        target
        for node in ast.walk(tree)
        if isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign))
        for target in (node.targets if isinstance(node, ast.Assign) else [node.target])
    ]
    return [
        node.attr
        for target in targets
        for node in ast.walk(target)
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "self"
    ]


def test_a_scenarios_functions_keep_nothing_on_the_scenario():
    """The named functions read their arguments and the scenario's constants: what changes lives in the state."""
    scenarios = {entry.load_vector().scenario_class for entry in registered_envs() if entry.id in BUILT_IN_IDS}
    found = [
        f"{scenario.__name__}.{hook} sets self.{attribute}"
        for scenario in scenarios
        for hook in (*HOOKS, "terminal", "frame")
        for attribute in self_assignments(getattr(scenario, hook))
    ]
    assert len(scenarios) == len(BUILT_IN_IDS) and found == []
    assert self_assignments(Coin.transition) == [] and self_assignments(Coin.__init__) == [
        "observation_space",
        "action_space",
    ]
