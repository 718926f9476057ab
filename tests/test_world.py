"""World (Pymunk) and scenario builders."""

import math

import numpy as np
import pytest
from conftest import distance_to_loop

from infonav_gym.estimation.models import unicycle_motion
from infonav_gym.multi.team_sensing import gps_available
from infonav_gym.world import SCENARIOS, CircleObstacle, Scenario, World
from infonav_gym.world.scenarios import (
    CORRIDOR_LANDMARK_COUNT,
    DEFAULT_WAYPOINTS,
    MAX_ATTEMPTS_EACH,
    MAX_CANOPY_COVER,
    TEAM_ROUTE_GAP_M,
    Route,
    corridor,
    field,
    team_field,
)


def open_scenario(waypoints=((8.0, 0.0),), loop=False, speed_mps=1.0, routes=None, **overrides) -> Scenario:
    """An open 20 m square without walls; one robot at the origin unless ``routes`` says otherwise."""
    if routes is None:
        routes = (Route((0.0, 0.0, 0.0), np.array(waypoints), loop=loop, speed_mps=speed_mps),)
    return Scenario(name="test", bounds=(-10.0, -10.0, 10.0, 10.0), routes=routes, **overrides)


def route_finished(world: World, robot: int = 0) -> bool:
    """Whether robot ``robot``'s open route has had its last waypoint reached."""
    return world.waypoint_indices[robot] >= len(world.scenario.routes[robot].waypoints)


def team_field_route_polygons(scenario: Scenario) -> list[np.ndarray]:
    """Each robot's closed route as the polygon it loops around (start point first)."""
    return [np.roll(route.waypoints, 1, axis=0) for route in scenario.routes]


def test_space_is_rebuilt_on_every_reset():
    world = World()
    world.reset(open_scenario())
    first_space = world.space
    world.step(0.5)
    world.reset(open_scenario())
    assert world.space is not first_space
    np.testing.assert_allclose(world.pose, [0.0, 0.0, 0.0])


def test_line_of_sight_is_blocked_by_obstacles_and_walls_only():
    robots = (Route((0.0, 0.0, 0.0), np.zeros((0, 2))), Route((-3.0, 0.0, 0.0), np.zeros((0, 2))))
    scenario = open_scenario(
        routes=robots, obstacles=(CircleObstacle((5.0, 0.0), 1.0),), walls=(((0.0, 5.0), (10.0, 5.0)),)
    )
    world = World()
    world.reset(scenario)
    targets = np.array([[9.0, 0.0], [9.0, 3.0], [5.0, 8.0], [-6.0, 0.0], [5.0, 0.0]])
    np.testing.assert_array_equal(world.line_of_sight((0.0, 0.0), targets), [False, True, False, True, False])


def test_executed_control_reproduces_the_motion_exactly_without_collisions():
    world = World()
    world.reset(open_scenario(waypoints=[[5.0, 5.0], [-5.0, 5.0]]))
    for _ in range(20):
        before = world.pose
        control = world.step(0.5)
        assert control.shape == (1, 2)
        np.testing.assert_allclose(unicycle_motion(before, control[0], 0.5), world.pose, atol=1e-12)


def test_robot_follows_waypoints_and_stops_at_the_end_of_an_open_route():
    world = World()
    world.reset(open_scenario(waypoints=[[4.0, 0.0], [4.0, 4.0]], speed_mps=1.0))
    for _ in range(60):
        world.step(0.5)
    assert route_finished(world)
    assert math.dist(world.pose[:2], (4.0, 4.0)) <= world.waypoint_tolerance_m
    before = world.pose
    np.testing.assert_allclose(world.step(0.5), [[0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(world.pose, before, atol=1e-12)


def test_a_looping_route_never_finishes():
    world = World()
    square = np.array([[3.0, 0.0], [3.0, 3.0], [0.0, 3.0], [0.0, 0.0]])
    world.reset(open_scenario(waypoints=square, loop=True))
    visited = set()
    for _ in range(200):
        world.step(0.5)
        visited.add(world.waypoint_indices[0])
    assert not route_finished(world) and visited == {0, 1, 2, 3}


def test_each_robot_has_its_own_waypoint_index_and_route_end():
    routes = (
        Route((0.0, 0.0, 0.0), np.array([[3.0, 0.0]])),
        Route((0.0, -6.0, 0.0), np.array([[3.0, -6.0], [3.0, -3.0], [0.0, -6.0]]), loop=True),
    )
    world = World()
    world.reset(open_scenario(routes=routes))
    for _ in range(100):
        world.step(0.5)
    assert route_finished(world, 0) and not route_finished(world, 1)
    assert world.waypoint_indices[0] == 1 and 0 <= world.waypoint_indices[1] < 3


def test_walls_stop_the_robot():
    wall_x = 3.0
    world = World()
    world.reset(open_scenario(walls=(((wall_x, -5.0), (wall_x, 5.0)),), waypoints=[[8.0, 0.0]]))
    for _ in range(40):
        world.step(0.25)
    assert world.pose[0] < wall_x - world.robot_radius_m + 0.1


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_scenarios_are_deterministic_given_np_random(name):
    first = SCENARIOS[name](np.random.default_rng(7))
    second = SCENARIOS[name](np.random.default_rng(7))
    np.testing.assert_array_equal(first.landmarks, second.landmarks)
    assert len(first.routes) == len(second.routes) >= 1
    for route, twin in zip(first.routes, second.routes):
        np.testing.assert_array_equal(route.waypoints, twin.waypoints)
        assert (route.start_pose, route.loop, route.speed_mps) == (twin.start_pose, twin.loop, twin.speed_mps)
    assert first.obstacles == second.obstacles and first.gps_denied_zones == second.gps_denied_zones


def test_field_layouts_vary_with_the_seed_and_keep_clear_of_route_and_obstacles():
    layouts = [field(np.random.default_rng(seed), n_landmarks=8, n_obstacles=6, size_m=30.0) for seed in range(10)]
    assert len({layout.landmarks.tobytes() for layout in layouts}) == 10
    for layout in layouts:
        assert layout.landmarks.shape == (8, 2) and len(layout.obstacles) == 6
        assert np.all((layout.landmarks > 0) & (layout.landmarks < 30.0))
        for obstacle in layout.obstacles:
            assert np.all(np.linalg.norm(layout.landmarks - obstacle.center, axis=1) > obstacle.radius)
            waypoints = layout.routes[0].waypoints
            assert np.all(np.linalg.norm(waypoints - obstacle.center, axis=1) > obstacle.radius + 2.0)


def test_a_robot_driving_the_field_never_collides():
    world = World()
    world.reset(field(np.random.default_rng(3), size_m=30.0))
    for _ in range(300):
        before = world.pose
        control = world.step(0.5)[0]
        np.testing.assert_allclose(unicycle_motion(before, control, 0.5), world.pose, atol=1e-9)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize(
    "arguments",
    [{}, {"n_landmarks": 30, "n_obstacles": 20, "size_m": 50.0, "n_waypoints": 9}, {"n_landmarks": 0, "size_m": 20}],
)
def test_field_draws_one_row_per_attempt_and_keeps_exactly_the_clear_ones(seed, arguments):
    """Replayed from the seed: the route's 2 W numbers, then one row of uniform numbers per attempt, obstacle rows
    (x, y, radius) kept when clear of the route by radius + 2 m, then landmark rows (x, y) kept when > 1 m from the
    route and 0.5 m outside every obstacle; the generator ends right after the last kept row."""
    n_landmarks, n_obstacles = arguments.get("n_landmarks", 8), arguments.get("n_obstacles", 6)
    size_m, n_waypoints = arguments.get("size_m", 40.0), arguments.get("n_waypoints", DEFAULT_WAYPOINTS)
    np_random, replay = np.random.default_rng(seed), np.random.default_rng(seed)
    layout = field(np_random, **arguments)
    (route,) = team_field_route_polygons(layout)
    replay.random(2 * n_waypoints)
    low, high, obstacles = np.array([2.0, 2.0, 0.5]), np.array([size_m - 2.0, size_m - 2.0, 2.0]), []
    while len(obstacles) < n_obstacles:
        x, y, radius = (low + (high - low) * replay.random(3)).tolist()
        if distance_to_loop((x, y), route) > radius + 2.0:
            obstacles.append(CircleObstacle((x, y), radius))
    landmarks = []
    while len(landmarks) < n_landmarks:
        point = 1.0 + (size_m - 1.0 - 1.0) * replay.random(2)
        outside = all(math.hypot(*(point - obstacle.center)) > obstacle.radius + 0.5 for obstacle in obstacles)
        if outside and distance_to_loop(point, route) > 1.0:
            landmarks.append(point)
    assert layout.obstacles == tuple(obstacles) and len(obstacles) == n_obstacles
    np.testing.assert_array_equal(layout.landmarks, np.array(landmarks).reshape(-1, 2))
    assert layout.landmarks.shape == (n_landmarks, 2) and layout.landmarks.flags.c_contiguous
    assert np_random.bit_generator.state == replay.bit_generator.state


def test_an_overcrowded_field_is_a_clear_error_after_every_attempt():
    np_random, replay = np.random.default_rng(0), np.random.default_rng(0)
    with pytest.raises(ValueError, match="could not place 3 obstacles clear of the routes .* too crowded"):
        field(np_random, n_obstacles=3, size_m=10.0)
    replay.random(2 * DEFAULT_WAYPOINTS + 3 * 3 * MAX_ATTEMPTS_EACH)  # the route, then every obstacle attempt
    assert np_random.bit_generator.state == replay.bit_generator.state


def test_corridor_is_the_papers_figure_1():
    scenario = corridor(np.random.default_rng(0))
    assert len(scenario.landmarks) == CORRIDOR_LANDMARK_COUNT == 4
    assert len(scenario.routes) == 1 and scenario.routes[0].start_pose == (0.0, 0.0, 0.0)
    assert np.all(np.abs(scenario.landmarks[:, 1]) < 3.0), "landmarks lie inside the corridor"
    distances = np.linalg.norm(scenario.landmarks, axis=1)
    assert int(np.argmin(distances)) == 2, "landmark #3 is the closest to the vehicle"


def test_poses_hold_every_robot_and_pose_is_robot_0():
    world = World()
    world.reset(team_field(np.random.default_rng(0), n_robots=3))
    for _ in range(5):
        world.step(0.5)
        poses = world.poses
        assert world.n_robots == 3 and poses.shape == (3, 3)
        np.testing.assert_array_equal(poses[0], world.pose)
        assert np.all(np.abs(poses[:, 2]) <= math.pi)


def test_every_robots_executed_control_reproduces_its_motion_without_collisions():
    world = World()
    world.reset(team_field(np.random.default_rng(5)))
    for _ in range(300):
        before = world.poses
        controls = world.step(0.5)
        assert controls.shape == (4, 2)
        for robot, control in enumerate(controls):
            np.testing.assert_allclose(unicycle_motion(before[robot], control, 0.5), world.poses[robot], atol=1e-9)


def test_robots_on_crossing_routes_collide_and_push_each_other():
    east = Route((-5.0, 0.0, 0.0), np.array([[8.0, 0.0]]))
    north = Route((0.0, -5.0, math.pi / 2), np.array([[0.0, 8.0]]))
    world = World()
    world.reset(open_scenario(routes=(east, north)))
    slop_m = 0.05
    largest_detour_m = 0.0
    for _ in range(30):
        world.step(0.5)
        (east_x, east_y, _), (north_x, north_y, _) = world.poses
        assert math.hypot(east_x - north_x, east_y - north_y) >= 2 * world.robot_radius_m - slop_m
        largest_detour_m = max(largest_detour_m, abs(east_y), abs(north_x))  # off their free straight paths
    assert largest_detour_m > 1.0


def test_dgps_fixes_match_a_hand_computed_case():
    """``gps_available``: a robot has a fix when it carries DGPS, is in no outage span and in no GPS-denied zone."""
    centers = np.array([[[0.0, 0.0], [5.0, 0.0], [0.0, 0.0]]])  # two zones, then padding
    radii_sq = np.array([[4.0, 1.0, -1.0]])
    positions = np.array([[[1.0, 1.0], [5.0, 0.9], [3.0, 0.0], [5.0, 1.5], [-1.5, -1.5], [3.0, 3.0], [3.0, 3.0]]])
    has_gps = np.array([True] * 6 + [False])
    outages = np.zeros((7, 1, 2))
    outages[5, 0] = (10.0, 20.0)  # robot 5 loses its DGPS from 10 s to 20 s
    for time_s, robot_5 in ((5.0, True), (10.0, False), (20.0, True)):
        available = gps_available(np.array([0]), positions, centers, radii_sq, has_gps, outages, np.array([time_s]))
        assert available[0].tolist() == [False, False, True, True, True, robot_5, False]


@pytest.mark.parametrize("seed", range(8))
def test_team_field_routes_lie_in_separate_bands_and_obstacles_and_canopies_fit_them(seed):
    size_m = 40.0
    scenario = team_field(np.random.default_rng(seed), n_robots=4, n_obstacles=6, n_canopies=3, size_m=size_m)
    center = np.array([size_m / 2, size_m / 2])
    polygons = team_field_route_polygons(scenario)
    assert len(scenario.routes) == 4 and all(route.loop for route in scenario.routes)
    assert scenario.landmarks.shape == (0, 2)
    nearest = [distance_to_loop(center, polygon) for polygon in polygons]  # a polygon's closest point to the centre
    farthest = [np.max(np.linalg.norm(polygon - center, axis=1)) for polygon in polygons]
    order = np.argsort(nearest)
    for inner, outer in zip(order[:-1], order[1:]):
        assert nearest[outer] - farthest[inner] >= TEAM_ROUTE_GAP_M
    starts = np.array([route.start_pose[:2] for route in scenario.routes])
    np.testing.assert_allclose(starts, [polygon[0] for polygon in polygons])
    assert np.min(np.linalg.norm(starts[:, None] - starts[None], axis=-1) + 1e3 * np.eye(4)) > TEAM_ROUTE_GAP_M
    assert np.all(np.array(farthest) < size_m / 2 - 2.0)
    assert len(scenario.obstacles) == 6
    for obstacle in scenario.obstacles:
        assert all(distance_to_loop(np.array(obstacle.center), p) > obstacle.radius + 2.0 for p in polygons)
    assert len(scenario.gps_denied_zones) == 3
    for canopy in scenario.gps_denied_zones:
        assert 4.0 <= canopy.radius <= 8.0
        assert min(distance_to_loop(np.array(canopy.center), p) for p in polygons) < 1e-9
        assert np.all(np.linalg.norm(starts - canopy.center, axis=1) >= canopy.radius), "robots start in the open"
        for polygon in polygons:  # vertices and edge midpoints: no route lies (mostly) under one canopy
            points = np.concatenate([polygon, 0.5 * (polygon + np.roll(polygon, -1, axis=0))])
            assert np.mean(np.linalg.norm(points - canopy.center, axis=1) < canopy.radius) <= MAX_CANOPY_COVER + 0.1


def test_team_field_layouts_vary_with_the_seed():
    starts = {team_field(np.random.default_rng(seed)).routes[0].start_pose for seed in range(5)}
    assert len(starts) == 5


def test_team_field_robots_pass_under_the_canopies():
    world = World()
    world.reset(team_field(np.random.default_rng(2), n_canopies=2))
    denied_steps = 0
    for _ in range(200):
        world.step(0.5)
        offsets = world.poses[:, None, :2] - [zone.center for zone in world.scenario.gps_denied_zones]
        denied_steps += int(
            np.any(np.linalg.norm(offsets, axis=-1) <= [zone.radius for zone in world.scenario.gps_denied_zones])
        )
    assert denied_steps > 0


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"n_robots": 8}, "fewer robots, a larger size_m or more n_waypoints"),
        ({"n_robots": 3, "size_m": 20.0}, "fewer robots"),
        ({"n_robots": 1, "size_m": 10.0}, "too crowded"),
        ({"n_robots": 0}, r"n_robots must be an integer in \[1, 32\], got 0"),
    ],
)
def test_team_field_that_cannot_be_built_is_a_clear_error(params, message):
    with pytest.raises(ValueError, match=message):
        team_field(np.random.default_rng(0), **params)


def test_bad_routes_and_a_scenario_without_robots_are_clear_errors():
    with pytest.raises(ValueError, match=r"\(W, 2\)"):
        Route((0.0, 0.0, 0.0), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="speed_mps"):
        Route((0.0, 0.0, 0.0), np.zeros((1, 2)), speed_mps=0.0)
    with pytest.raises(ValueError, match="at least one route"):
        Scenario(name="empty", bounds=(0.0, 0.0, 1.0, 1.0), routes=())


@pytest.mark.parametrize("dt", [math.inf, math.nan, 0.0, -0.5, 61.0])
def test_world_step_refuses_a_time_step_outside_its_range(dt):
    world = World()
    world.reset(corridor(np.random.default_rng(0)))
    with pytest.raises(ValueError, match=r"World.step dt must be in \(0, 60\] s"):
        world.step(dt)


@pytest.mark.parametrize(
    ("argument", "value"),
    [
        ("robot_radius_m", 0.0),
        ("max_turn_rate_rps", math.inf),
        ("heading_gain", math.nan),
        ("max_physics_step_s", 1e-9),
    ],
)
def test_world_refuses_arguments_outside_their_range(argument, value):
    with pytest.raises(ValueError, match=f"World {argument} must be in"):
        World(**{argument: value})
