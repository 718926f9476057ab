"""The vehicle's loop through a terrain: one set of obstacles for Pymunk and for the sensors."""

import math

import numpy as np
import pytest
from conftest import distance_to_loop

from infonav_gym.world import World
from infonav_gym.world.terrain_generation import make_terrain
from infonav_gym.world.terrain_scenario import ROUTE_CLEARANCE_M, terrain_loop


@pytest.mark.parametrize("seed", range(5))
def test_obstacles_keep_clear_of_the_route_and_the_world_has_the_terrains_obstacles(seed):
    scene = terrain_loop(np.random.default_rng(seed))
    route = scene.scenario.routes[0].waypoints
    terrain = scene.terrain
    for cylinder in terrain.cylinders:
        assert distance_to_loop(cylinder.center_m, route) > ROUTE_CLEARANCE_M + cylinder.radius_m
    for box in terrain.boxes:
        corners = np.array(box.min_corner_m[:2]), np.array(box.max_corner_m[:2])
        half_diagonal = np.linalg.norm(corners[1] - corners[0]) / 2
        assert distance_to_loop((corners[0] + corners[1]) / 2, route) > ROUTE_CLEARANCE_M + half_diagonal
    assert [(o.center, o.radius) for o in scene.scenario.obstacles] == [
        (c.center_m, c.radius_m) for c in terrain.cylinders
    ]
    assert len(scene.scenario.walls) == 4 * len(terrain.boxes)
    assert scene.scenario.bounds == terrain.bounds_m


@pytest.mark.parametrize("seed", range(3))
def test_the_vehicle_drives_the_whole_loop_without_touching_an_obstacle(seed):
    scene = terrain_loop(np.random.default_rng(seed))
    world = World()
    world.reset(scene.scenario)
    route = scene.scenario.routes[0].waypoints
    travelled, previous = 0.0, world.pose[:2]
    perimeter = sum(math.dist(a, b) for a, b in zip(route, np.roll(route, -1, axis=0)))
    speed = scene.scenario.routes[0].speed_mps
    for _ in range(math.ceil(1.5 * perimeter / (speed * 0.5))):  # stuck, it would not get round in time
        if travelled >= perimeter:
            break
        world.step(0.5)
        travelled += math.dist(previous, world.pose[:2])
        previous = world.pose[:2]
        for cylinder in scene.terrain.cylinders:
            assert math.dist(previous, cylinder.center_m) > cylinder.radius_m + world.robot_radius_m
        assert distance_to_loop(previous, route) < ROUTE_CLEARANCE_M - world.robot_radius_m
    assert travelled >= perimeter


def test_make_terrain_keeps_obstacles_clear_of_a_path_and_defaults_to_the_centre():
    path = np.array([[-10.0, -10.0], [10.0, -10.0], [10.0, 10.0], [-10.0, 10.0]])
    terrain = make_terrain(np.random.default_rng(1), n_trees=40, clear_radius_m=4.0, clear_path_m=path)
    assert all(distance_to_loop(c.center_m, path) > 4.0 + c.radius_m for c in terrain.cylinders)
    centred = make_terrain(np.random.default_rng(1), n_trees=40, clear_radius_m=4.0)
    assert all(math.hypot(*c.center_m) > 4.0 + c.radius_m for c in centred.cylinders)
    assert any(distance_to_loop(c.center_m, path) < 4.0 + c.radius_m for c in centred.cylinders)
    with pytest.raises(ValueError, match="clear_path_m"):
        make_terrain(np.random.default_rng(1), clear_path_m=[[0.0, np.nan]])


def test_distance_to_loop_matches_the_closed_form_on_a_square_and_a_point():
    square = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]
    assert distance_to_loop([1.0, 1.0], square) == pytest.approx(1.0)
    assert distance_to_loop([3.0, 1.0], square) == pytest.approx(1.0)
    assert distance_to_loop([3.0, 3.0], square) == pytest.approx(math.sqrt(2))
    assert distance_to_loop([3.0, 4.0], [[0.0, 0.0]]) == pytest.approx(5.0)


def test_terrain_loop_rejects_too_few_waypoints():
    with pytest.raises(ValueError, match="n_waypoints"):
        terrain_loop(np.random.default_rng(0), n_waypoints=2)
