"""World (Pymunk) and scenario builders."""

import math

import numpy as np
import pytest

from infonav_gym.estimation.models import unicycle_motion
from infonav_gym.world import SCENARIOS, CircleObstacle, Scenario, World
from infonav_gym.world.scenarios import CORRIDOR_LANDMARK_COUNT, corridor, field


def open_scenario(**overrides) -> Scenario:
    spec = {
        "name": "test",
        "bounds": (-10.0, -10.0, 10.0, 10.0),
        "waypoints": np.array([[8.0, 0.0]]),
        "start_pose": (0.0, 0.0, 0.0),
    }
    spec.update(overrides)
    return Scenario(**spec)


def test_space_is_rebuilt_on_every_reset():
    world = World()
    world.reset(open_scenario())
    first_space = world.space
    world.step(0.5)
    world.reset(open_scenario())
    assert world.space is not first_space
    np.testing.assert_allclose(world.pose, [0.0, 0.0, 0.0])


def test_line_of_sight_is_blocked_by_obstacles_and_walls_only():
    scenario = open_scenario(obstacles=(CircleObstacle((5.0, 0.0), 1.0),), walls=(((0.0, 5.0), (10.0, 5.0)),))
    world = World()
    world.reset(scenario)
    targets = np.array([[9.0, 0.0], [9.0, 3.0], [5.0, 8.0], [-6.0, 0.0], [5.0, 0.0]])
    np.testing.assert_array_equal(world.line_of_sight((0.0, 0.0), targets), [False, True, False, True, False])


def test_executed_control_reproduces_the_motion_exactly_without_collisions():
    world = World()
    world.reset(open_scenario(waypoints=np.array([[5.0, 5.0], [-5.0, 5.0]])))
    for _ in range(20):
        before = world.pose
        control = world.step(0.5)
        np.testing.assert_allclose(unicycle_motion(before, control, 0.5), world.pose, atol=1e-12)


def test_robot_follows_waypoints_and_stops_at_the_end_of_an_open_route():
    world = World()
    world.reset(open_scenario(waypoints=np.array([[4.0, 0.0], [4.0, 4.0]]), speed_mps=1.0))
    for _ in range(60):
        world.step(0.5)
    assert world.route_finished
    assert math.dist(world.pose[:2], (4.0, 4.0)) <= world.waypoint_tolerance_m
    before = world.pose
    np.testing.assert_allclose(world.step(0.5), [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(world.pose, before, atol=1e-12)


def test_a_looping_route_never_finishes():
    world = World()
    square = np.array([[3.0, 0.0], [3.0, 3.0], [0.0, 3.0], [0.0, 0.0]])
    world.reset(open_scenario(waypoints=square, loop_route=True))
    visited = set()
    for _ in range(200):
        world.step(0.5)
        visited.add(world.waypoint_index)
    assert not world.route_finished and visited == {0, 1, 2, 3}


def test_walls_stop_the_robot():
    wall_x = 3.0
    world = World()
    world.reset(open_scenario(walls=(((wall_x, -5.0), (wall_x, 5.0)),), waypoints=np.array([[8.0, 0.0]])))
    for _ in range(40):
        world.step(0.25)
    assert world.pose[0] < wall_x - world.robot_radius_m + 0.1


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_scenarios_are_deterministic_given_np_random(name):
    first = SCENARIOS[name](np.random.default_rng(7))
    second = SCENARIOS[name](np.random.default_rng(7))
    np.testing.assert_array_equal(first.landmarks, second.landmarks)
    np.testing.assert_array_equal(first.waypoints, second.waypoints)
    assert first.obstacles == second.obstacles and first.start_pose == second.start_pose


def test_field_layouts_vary_with_the_seed_and_keep_clear_of_route_and_obstacles():
    layouts = [field(np.random.default_rng(seed), n_landmarks=8, n_obstacles=6, size_m=30.0) for seed in range(10)]
    assert len({layout.landmarks.tobytes() for layout in layouts}) == 10
    for layout in layouts:
        assert layout.landmarks.shape == (8, 2) and len(layout.obstacles) == 6
        assert np.all((layout.landmarks > 0) & (layout.landmarks < 30.0))
        for obstacle in layout.obstacles:
            assert np.all(np.linalg.norm(layout.landmarks - obstacle.center, axis=1) > obstacle.radius)
            assert np.all(np.linalg.norm(layout.waypoints - obstacle.center, axis=1) > obstacle.radius + 2.0)


def test_a_robot_driving_the_field_never_collides():
    world = World()
    world.reset(field(np.random.default_rng(3), size_m=30.0))
    for _ in range(300):
        before = world.pose
        control = world.step(0.5)
        np.testing.assert_allclose(unicycle_motion(before, control, 0.5), world.pose, atol=1e-9)


def test_an_overcrowded_field_is_a_clear_error():
    with pytest.raises(ValueError, match="too crowded"):
        field(np.random.default_rng(0), n_obstacles=200, size_m=10.0)


def test_corridor_is_the_papers_figure_1():
    scenario = corridor(np.random.default_rng(0))
    assert len(scenario.landmarks) == CORRIDOR_LANDMARK_COUNT == 4
    assert scenario.start_pose == (0.0, 0.0, 0.0)
    assert np.all(np.abs(scenario.landmarks[:, 1]) < 3.0), "landmarks lie inside the corridor"
    distances = np.linalg.norm(scenario.landmarks, axis=1)
    assert int(np.argmin(distances)) == 2, "landmark #3 is the closest to the vehicle"
