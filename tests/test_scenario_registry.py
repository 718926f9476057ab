"""Open scenarios: ``register_scenario`` makes a builder usable as the envs' ``scenario`` config key."""

import gymnasium as gym
import numpy as np
import pytest

import infonav_gym  # noqa: F401  (registers the envs)
from infonav_gym.multi import cooperative_localization_v0
from infonav_gym.world import SCENARIOS, Route, Scenario, build_scenario, register_scenario, scenario_names
from infonav_gym.world.scenarios import TEAM_SCENARIOS


def ring(np_random: np.random.Generator, n_landmarks: int = 3, speed_mps: float = 1.0) -> Scenario:
    """One robot driving east past ``n_landmarks`` landmarks on a line 2 m to its left."""
    xs = np.sort(np_random.uniform(2.0, 18.0, n_landmarks))
    landmarks = np.column_stack([xs, np.full(n_landmarks, 2.0)])
    route = Route((0.0, 0.0, 0.0), np.array([[20.0, 0.0]]), speed_mps=speed_mps)
    return Scenario(name="ring", bounds=(-1.0, -3.0, 21.0, 3.0), routes=(route,), landmarks=landmarks)


def lanes(np_random: np.random.Generator, **parameters) -> Scenario:
    """One straight lane per robot, 4 m apart; takes every parameter the env offers."""
    del np_random
    routes = tuple(
        Route((0.0, -4.0 * k, 0.0), np.array([[30.0, -4.0 * k]]), speed_mps=parameters["speed_mps"])
        for k in range(parameters["n_robots"])
    )
    return Scenario(name="lanes", bounds=(-1.0, -4.0 * len(routes), 31.0, 1.0), routes=routes)


@pytest.fixture
def registered():
    """``ring`` and the team scenario ``lanes`` registered for one test, removed after it."""
    register_scenario("ring", ring)
    register_scenario("lanes", lanes, team=True)
    yield
    for name in ("ring", "lanes"):
        SCENARIOS.pop(name)
        TEAM_SCENARIOS.discard(name)


def test_a_registered_builder_gets_the_parameters_it_names_and_the_env_runs_on_it(registered):
    assert "ring" in scenario_names(team=False) and "ring" not in scenario_names(team=True)
    env = gym.make("infonav/LandmarkSelection-v0", scenario="ring", n_candidates=5, speed_mps=2.0)
    _, info = env.reset(seed=4)
    scenario = env.unwrapped.vector.scenario(0)
    assert len(scenario.landmarks) == 5, "n_landmarks comes from n_candidates"
    assert scenario.routes[0].speed_mps == 2.0
    np.testing.assert_array_equal(scenario.landmarks, ring(np.random.default_rng(4), 5).landmarks)
    total = 0.0
    for _ in range(10):
        _, reward, _, _, info = env.step(int(np.argmax(info["action_information_gain"])))
        total += reward
    assert total > 0, "the landmarks beside the road bring information"


def test_a_registered_team_scenario_builds_one_route_per_robot(registered):
    env = cooperative_localization_v0.parallel_env(scenario="lanes", n_robots=3, max_cycles=5)
    observations, _ = env.reset(seed=0)
    assert len(observations) == 3 and env.vector.scenario(0).name == "lanes"
    assert [route.start_pose[1] for route in env.vector.scenario(0).routes] == [0.0, -4.0, -8.0]


def test_unknown_or_mismatched_scenarios_are_clear_errors(registered, monkeypatch):
    with pytest.raises(ValueError, match=r"config key 'scenario' .* must be one of \['corridor', 'field', 'ring'\]"):
        gym.make("infonav/LandmarkSelection-v0", scenario="lanes")
    with pytest.raises(ValueError, match=r"unknown scenario 'moon'; registered: convoy, corridor, field, lanes, ring"):
        build_scenario("moon", np.random.default_rng(0))
    monkeypatch.setitem(SCENARIOS, "crowd", lambda np_random: ring(np_random, n_landmarks=6))
    too_many = r"scenario 'crowd' has 1 route\(s\) and 6 landmarks: \w+ needs 1 route\(s\) and at most 4 landmarks"
    with pytest.raises(ValueError, match=too_many):
        gym.make("infonav/LandmarkSelection-v0", scenario="crowd", n_candidates=4).reset(seed=0)
    with pytest.raises(ValueError, match=r"scenario 'lanes' has 2 route\(s\) and 0 landmarks: \w+ needs 3 route\(s\)$"):
        monkeypatch.setitem(SCENARIOS, "lanes", lambda np_random: lanes(np_random, n_robots=2, speed_mps=1.0))
        cooperative_localization_v0.parallel_env(scenario="lanes", n_robots=3).reset(seed=0)
    with pytest.raises(ValueError, match="scenario 'field' is already registered"):
        register_scenario("field", ring)
    with pytest.raises(ValueError, match="must be callable"):
        register_scenario("nothing", None)


def test_a_builder_that_returns_no_scenario_is_refused(registered):
    SCENARIOS["ring"] = lambda np_random: {"routes": []}
    with pytest.raises(ValueError, match="the builder of scenario 'ring' returned a dict, not a Scenario"):
        build_scenario("ring", np.random.default_rng(0))
