"""Batched visibility against its references: Pymunk's segment queries (``World.line_of_sight``) and
``RangeBearingSensor.in_coverage``, bit for bit (booleans equal, no tolerance)."""

import math
from dataclasses import replace

import numpy as np
import pymunk
import pytest

from infonav_gym.estimation.models import range_bearing
from infonav_gym.sensors.range_bearing import RangeBearingSensor
from infonav_gym.world import CircleObstacle, Route, Scenario, StaticGeometry, World
from infonav_gym.world.scenarios import build_scenario
from infonav_gym.world.visibility import in_coverage, segments_clear, visible
from infonav_gym.world.visibility_kernels import DISC, WALL, shape_hits

OFFSETS_M = np.array([0.0, 1e-15, -1e-15, 1e-12, -1e-12, 1e-9, -1e-9])  # how far off a surface a point lies [m]
PARKED = (Route((0.0, 0.0, 0.0), np.zeros((0, 2))),)  # one robot that stays put


def pymunk_line_of_sight(world: World, origins: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """``World.line_of_sight`` of one query per row: origins (M, 2), targets (M, 2) -> (M,)."""
    return np.array([world.line_of_sight(origin, target[None])[0] for origin, target in zip(origins, targets)])


def geometry_of(world: World) -> StaticGeometry:
    """The geometry (one copy) of ``world``'s static shapes as of its last reset."""
    return StaticGeometry.from_scenario(world.scenario, world.wall_thickness_m)


def line_of_sight(geometry: StaticGeometry, origins: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Whether each copy's origin (N, 2) sees each of its targets (N, K, 2): ``segments_clear`` of every pair (N, K)."""
    n_copies, n_targets = targets.shape[:2]
    copies = np.repeat(np.arange(n_copies), n_targets)
    clear = segments_clear(geometry, copies, origins[copies], targets.reshape(-1, 2))
    return clear.reshape(n_copies, n_targets)


def unculled_hits(geometry: StaticGeometry, origins: np.ndarray, targets: np.ndarray, kind: int) -> np.ndarray:
    """(N, K, S) bool: each query against each wall (``WALL``) or disc (``DISC``), no bounding-box culling."""
    if kind == WALL:
        shapes = (geometry.wall_points, geometry.wall_radii, geometry.wall_boxes)
    else:
        shapes = (geometry.disc_centers, geometry.disc_radii, geometry.disc_boxes)
    n_copies, n_targets = targets.shape[:2]
    copies = np.repeat(np.arange(n_copies), n_targets)
    usable, culled = np.ones(shapes[1].shape, dtype=bool), np.zeros(n_copies, dtype=bool)
    hits = shape_hits(copies, origins[copies], targets.reshape(-1, 2), *shapes, usable, culled, kind)
    return hits.reshape(n_copies, n_targets, -1)


def unit(angles: np.ndarray) -> np.ndarray:
    return np.stack([np.cos(angles), np.sin(angles)], axis=-1)


def near_surfaces(world: World, count: int, rng: np.random.Generator) -> np.ndarray:
    """Points on, just inside and just outside every disc and wall of ``world`` (M, 2) [m]."""
    scenario, radius = world.scenario, world.wall_thickness_m / 2
    points = []
    for obstacle in scenario.obstacles:
        distance = obstacle.radius + rng.choice(OFFSETS_M, count)
        points.append(np.array(obstacle.center) + distance[:, None] * unit(rng.uniform(0, 2 * math.pi, count)))
    for start, end in scenario.walls:
        start, end = np.array(start), np.array(end)
        along = end - start
        if not np.any(along):
            continue  # a zero-length wall is a disc: its points are those of tangent_queries
        normal = np.array([along[1], -along[0]]) / np.linalg.norm(along)
        side = rng.choice([-1.0, 1.0], count) * radius + rng.choice(OFFSETS_M, count)
        points.append(start + rng.uniform(-0.01, 1.01, count)[:, None] * along + side[:, None] * normal)
    return np.concatenate(points)


def tangent_queries(world: World, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Queries (origins, targets) (M, 2) grazing every disc, wall face and wall end, some axis-aligned."""
    scenario, radius = world.scenario, world.wall_thickness_m / 2
    circles = [(np.array(o.center), o.radius) for o in scenario.obstacles]
    circles += [(np.array(end, dtype=float), radius) for wall in scenario.walls for end in wall]
    origins, targets = [], []
    for center, circle_radius in circles:
        outward = unit(rng.uniform(0, 2 * math.pi, count))
        outward[: count // 4] = unit(rng.integers(4, size=count // 4) * math.pi / 2)  # at the bounding box's sides
        touch = center + (circle_radius + rng.choice(OFFSETS_M, count))[:, None] * outward
        tangent = outward[:, ::-1] * [-1.0, 1.0]
        origins.append(touch - rng.uniform(0.1, 10.0, count)[:, None] * tangent)
        targets.append(touch + rng.uniform(-0.5, 10.0, count)[:, None] * tangent)
    for start, end in scenario.walls:
        start, end = np.array(start), np.array(end)
        if not np.any(end - start):
            continue
        direction = (end - start) / np.linalg.norm(end - start)
        normal = np.array([direction[1], -direction[0]])
        side = (rng.choice([-1.0, 1.0], count) * (radius + rng.choice(OFFSETS_M, count)))[:, None] * normal
        length = np.linalg.norm(end - start)
        origins.append(start + side + rng.uniform(-2.0, length + 2.0, count)[:, None] * direction)
        targets.append(start + side + rng.uniform(-2.0, length + 2.0, count)[:, None] * direction)
    return np.concatenate(origins), np.concatenate(targets)


def random_world(name: str, seed: int) -> World:
    parameters = {"field": {"n_obstacles": seed % 9}, "team_field": {"n_obstacles": seed % 7, "n_robots": 3}}
    world = World(wall_thickness_m=0.1 + 0.1 * (seed % 5))
    world.reset(build_scenario(name, np.random.default_rng(seed), **parameters.get(name, {})))
    return world


@pytest.mark.parametrize("name", ["field", "team_field", "corridor"])
def test_line_of_sight_equals_pymunk_over_copies_of_different_worlds(name):
    """N copies, each its own random world (obstacle counts differ: padding), poses and targets."""
    rng = np.random.default_rng(7)
    worlds = [random_world(name, seed) for seed in range(12)]
    geometry = StaticGeometry.stack([geometry_of(world) for world in worlds])
    if name != "corridor":
        assert not np.all(geometry.disc_valid)  # the copies' obstacle counts differ: some discs are padding
    targets, origins = [], []
    for world in worlds:
        low, high = np.array(world.scenario.bounds[:2]) - 1.0, np.array(world.scenario.bounds[2:]) + 1.0
        near = near_surfaces(world, 10, rng)
        targets.append(np.concatenate([near, rng.uniform(low, high, (400 - len(near), 2))]))
        robots = world.poses[:, :2]
        origins.append([robots[0], rng.uniform(low, high), near[rng.integers(len(near))]])
    targets, origins = np.array(targets), np.array(origins)
    checked = blocked = 0
    for column in range(origins.shape[1]):
        got = line_of_sight(geometry, origins[:, column], targets)
        for copy, world in enumerate(worlds):
            expected = world.line_of_sight(origins[copy, column], targets[copy])
            np.testing.assert_array_equal(got[copy], expected, err_msg=f"{name} copy {copy} origin {column}")
            checked, blocked = checked + expected.size, blocked + np.sum(~expected)
    assert 0.05 * checked < blocked < 0.95 * checked  # both answers occur often


def test_segments_clear_equals_pymunk_for_lines_of_any_copies_in_any_order():
    """Lines of copies in a shuffled order, each from its own start (as a team's robots see their own targets)."""
    rng = np.random.default_rng(3)
    worlds = [random_world("team_field", seed) for seed in range(6)]
    geometry = StaticGeometry.stack([geometry_of(world) for world in worlds])
    copies = rng.integers(len(worlds), size=600)
    starts, ends = rng.uniform(-1.0, 41.0, (600, 2)), rng.uniform(-1.0, 41.0, (600, 2))
    got = segments_clear(geometry, copies, starts, ends)
    expected = [worlds[copy].line_of_sight(start, end[None])[0] for copy, start, end in zip(copies, starts, ends)]
    np.testing.assert_array_equal(got, expected)
    assert 0.05 < np.mean(got) < 0.95
    assert segments_clear(geometry, np.zeros(0, dtype=int), np.zeros((0, 2)), np.zeros((0, 2))).shape == (0,)


@pytest.mark.parametrize("name", ["field", "team_field", "corridor"])
def test_tangent_queries_equal_pymunk_and_need_its_bounding_box_culling(name):
    """Lines grazing discs, wall faces and wall ends agree with Pymunk exactly; on some of them only
    Chipmunk's bounding-box culling decides (without it they would count as blocked)."""
    rng = np.random.default_rng(11)
    culling_decides = 0
    for seed in range(6):
        world = random_world(name, seed)
        geometry = geometry_of(world)
        origins, targets = tangent_queries(world, 40, rng)
        stacked = StaticGeometry.stack([geometry] * len(origins))
        got = line_of_sight(stacked, origins, targets[:, None])[:, 0]
        expected = pymunk_line_of_sight(world, origins, targets)
        np.testing.assert_array_equal(got, expected, err_msg=f"{name} seed {seed}")
        unculled = unculled_hits(stacked, origins, targets[:, None], WALL).any(axis=2)
        unculled |= unculled_hits(stacked, origins, targets[:, None], DISC).any(axis=2)
        culling_decides += np.sum(~unculled[:, 0] != expected)
    assert culling_decides > 0


def test_a_world_of_one_static_shape_is_not_culled_as_pymunk_does():
    """A horizontal line one ulp above a disc's top hits it by the circle test but misses its bounding box:
    Pymunk blocks it when the disc is the only static shape (its tree is one leaf) and not otherwise."""
    disc = CircleObstacle((5.0, 5.0), 1.3)
    y = np.nextafter(5.0 + 1.3, math.inf)
    origins, targets = np.array([[0.5, y]]), np.array([[[9.5, y]]])
    far_wall = (((20.0, 20.0), (21.0, 20.0)),)
    for walls, expected in (((), False), (far_wall, True)):
        world = World()
        world.reset(Scenario("disc", (0.0, 0.0, 30.0, 30.0), PARKED, walls=walls, obstacles=(disc,)))
        geometry = geometry_of(world)
        assert geometry.culled[0] == bool(walls)
        assert world.line_of_sight(origins[0], targets[0])[0] == expected
        assert line_of_sight(geometry, origins, targets)[0, 0] == expected


DEGENERATE_POINTS = np.array(  # ends and exact surface points (binary fractions) of the shapes below [m]
    [(5, 6.25), (5, 3.75), (6.25, 5), (4, 4), (4.25, 4), (4, 4.25), (1, 1), (5, 5), (2, 3), (7, 6.5), (2, 1.25)]
)


@pytest.mark.parametrize(
    "walls, obstacles",
    [
        ((((4.0, 4.0), (4.0, 4.0)), ((1.0, 1.0), (1.0, 1.0))), ()),  # zero-length walls
        ((((4.0, 4.0), (4.0, 4.0)),), (CircleObstacle((5.0, 5.0), 0.0),)),  # and a disc of radius 0
        ((((2.0, 3.0), (7.0, 6.5)),), ()),  # one slanted wall
        ((((1.0, 1.0), (4.0, 1.0)),), ()),  # one wall, (2, 1.25) on its surface
        ((), (CircleObstacle((5.0, 5.0), 1.25),)),  # one disc, (5, 6.25) etc. on its surface
    ],
)
def test_degenerate_shapes_and_queries_equal_pymunk(walls, obstacles):
    """Queries through and along degenerate shapes, from inside or on them, of zero length, ending on edges."""
    rng = np.random.default_rng(3)
    world = World(wall_thickness_m=0.5)
    world.reset(Scenario("degenerate", (0.0, 0.0, 10.0, 10.0), PARKED, walls=walls, obstacles=obstacles))
    count = 60 * len(DEGENERATE_POINTS)
    offsets = rng.choice(OFFSETS_M, (count, 1)) * unit(rng.integers(8, size=count) * math.pi / 4)
    near = np.repeat(DEGENERATE_POINTS, 60, axis=0) + offsets
    directions = unit(rng.choice([0.0, math.pi / 2, 1.0, 2.5], count))
    origins = np.where(rng.random((count, 1)) < 0.2, near, near + rng.uniform(-3, 3, (count, 1)) * directions)
    targets = np.where(rng.random((count, 1)) < 0.9, near + rng.uniform(-3, 3, (count, 1)) * directions, origins)
    geometry = StaticGeometry.stack([geometry_of(world)] * count)
    got = line_of_sight(geometry, origins, targets[:, None])[:, 0]
    expected = pymunk_line_of_sight(world, origins, targets)
    np.testing.assert_array_equal(got, expected)
    assert 0 < np.sum(~expected) < len(expected)


def slanted_world(seed: int) -> World:
    """Walls at random angles and lengths (zero among them) and discs, at random."""
    rng = np.random.default_rng(seed)
    starts = rng.uniform(0, 20, (8, 2))
    ends = starts + rng.uniform(0, 8, (8, 1)) * unit(rng.uniform(0, 2 * math.pi, 8))
    ends[0] = starts[0]
    walls = tuple((tuple(start), tuple(end)) for start, end in zip(starts, ends))
    discs = tuple(CircleObstacle(tuple(rng.uniform(0, 20, 2)), float(rng.uniform(0.1, 2.0))) for _ in range(5))
    world = World(wall_thickness_m=float(rng.uniform(0.05, 1.0)))
    world.reset(Scenario("slanted", (0.0, 0.0, 20.0, 20.0), PARKED, walls=walls, obstacles=discs))
    return world


def test_slanted_walls_equal_pymunk_on_near_faces_and_tangents():
    """Walls at any angle (so their face tests round) and zero-length walls, hit from near, on and off their faces."""
    rng = np.random.default_rng(13)
    for seed in range(8):
        world = slanted_world(seed)
        origins, targets = tangent_queries(world, 30, rng)
        near = near_surfaces(world, 30, rng)
        origins = np.concatenate([origins, rng.uniform(-1, 21, (len(near), 2))])
        targets = np.concatenate([targets, near])
        geometry = StaticGeometry.stack([geometry_of(world)] * len(origins))
        got = line_of_sight(geometry, origins, targets[:, None])[:, 0]
        np.testing.assert_array_equal(got, pymunk_line_of_sight(world, origins, targets), err_msg=f"seed {seed}")


def test_in_coverage_and_visible_equal_the_single_env_rule():
    """``in_coverage`` equals ``sensor.in_coverage(range_bearing(...))``; ``visible`` equals that coverage and
    Pymunk's segment queries (``World.line_of_sight``) from each copy's pose."""
    rng = np.random.default_rng(5)
    sensor = RangeBearingSensor(max_range_m=12.0, fov_rad=2.0)
    copies = 16
    poses = np.concatenate([rng.uniform(0, 40, (copies, 2)), rng.uniform(-4, 4, (copies, 1))], axis=1)
    landmarks = rng.uniform(0, 40, (copies, 60, 2))
    bearings = poses[:, 2:] + rng.choice([-1.0, 1.0, 0.3], (copies, 20))  # on the field of view's edges
    ranges = rng.choice([12.0, 11.0, 12.0 + 1e-14], (copies, 20, 1))  # on the range's edge
    landmarks[:, :20] = poses[:, None, :2] + ranges * unit(bearings)
    worlds = []
    for copy in range(copies):
        worlds.append(World())
        worlds[copy].reset(replace(random_world("field", copy).scenario, landmarks=landmarks[copy]))
    geometry = StaticGeometry.stack([geometry_of(world) for world in worlds])
    covered, seen = in_coverage(sensor, poses, landmarks), visible(geometry, sensor, poses, landmarks)
    for copy, world in enumerate(worlds):
        expected = sensor.in_coverage(range_bearing(poses[copy], landmarks[copy]))
        np.testing.assert_array_equal(covered[copy], expected)
        expected_seen = np.zeros(60, dtype=bool)
        indices = np.flatnonzero(expected)
        expected_seen[indices] = world.line_of_sight(poses[copy], landmarks[copy, indices])
        np.testing.assert_array_equal(seen[copy], expected_seen)
    assert 0 < np.sum(seen) < np.sum(covered) < covered.size


def test_stack_pads_with_invalid_shapes():
    corridor = StaticGeometry.from_scenario(build_scenario("corridor", np.random.default_rng(0)), 0.3)
    field = StaticGeometry.from_scenario(build_scenario("field", np.random.default_rng(0), n_obstacles=3), 0.3)
    stacked = StaticGeometry.stack([corridor, field, corridor])
    assert stacked.n_copies == 3
    assert stacked.disc_centers.shape == (3, 3, 2) and stacked.wall_starts.shape == (3, 4, 2)
    np.testing.assert_array_equal(stacked.disc_valid, [[False] * 3, [True] * 3, [False] * 3])
    np.testing.assert_array_equal(stacked.wall_radii[:, 0], 0.15)
    assert not stacked.disc_centers.flags.writeable


def test_with_copies_equals_stacking_the_replaced_list_up_to_padding():
    rng = np.random.default_rng(4)
    geometries = [StaticGeometry.from_scenario(build_scenario("field", rng, n_obstacles=n), 0.3) for n in (2, 4, 3)]
    corridor = StaticGeometry.from_scenario(build_scenario("corridor", rng), 0.3)
    bigger = StaticGeometry.from_scenario(build_scenario("field", rng, n_obstacles=6), 0.3)
    replaced = StaticGeometry.stack(geometries).with_copies([2, 0], StaticGeometry.stack([bigger, corridor]))
    expected = StaticGeometry.stack([corridor, geometries[1], bigger])
    for name in ("wall_starts", "wall_ends", "wall_radii", "wall_valid", "disc_centers", "disc_radii", "disc_valid"):
        np.testing.assert_array_equal(getattr(replaced, name), getattr(expected, name), err_msg=name)
    assert not replaced.disc_valid.flags.writeable
    with pytest.raises(ValueError, match="2 copies to replace, but the replacement holds 1"):
        replaced.with_copies([0, 1], corridor)


def test_from_scenarios_equals_stacking_each_scenarios_geometry_and_names_a_bad_one():
    rng = np.random.default_rng(5)
    scenarios = [build_scenario("field", rng, n_obstacles=n) for n in (2, 0, 5)] + [build_scenario("corridor", rng)]
    built = StaticGeometry.from_scenarios(scenarios, 0.3)
    expected = StaticGeometry.stack([StaticGeometry.from_scenario(scenario, 0.3) for scenario in scenarios])
    for name in built.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(built, name), getattr(expected, name), err_msg=name)
        assert getattr(built, name).flags.c_contiguous and not getattr(built, name).flags.writeable, name
        assert getattr(built.single(2), name).shape == (1, *getattr(built, name).shape[1:]), name
        np.testing.assert_array_equal(getattr(built.single(2), name)[0], getattr(built, name)[2], err_msg=name)
    bad = replace(scenarios[1], name="bad", obstacles=(CircleObstacle((1.0, 2.0), -1.0),))
    with pytest.raises(ValueError, match="scenario 'bad': obstacles need a finite centre"):
        StaticGeometry.from_scenarios([scenarios[0], bad, scenarios[2]], 0.3)
    bad = replace(scenarios[1], name="open", walls=(((0.0, 0.0), (math.nan, 1.0)),))
    with pytest.raises(ValueError, match="scenario 'open': walls must be pairs"):
        StaticGeometry.from_scenarios([scenarios[0], bad], 0.3)


CORRIDOR = build_scenario("corridor", np.random.default_rng(0))
GEOMETRY = StaticGeometry.from_scenario(CORRIDOR, 0.3)
ORIGIN, TARGETS = np.zeros((1, 2)), np.ones((1, 1, 2))
BAD_CALLS = {  # what is wrong: (the call, words its message must contain)
    "lines without a copy each": (lambda: segments_clear(GEOMETRY, [0, 0], ORIGIN, ORIGIN), "copies must be 1 ints"),
    "a line of no copy": (lambda: segments_clear(GEOMETRY, [1], ORIGIN, ORIGIN), r"copies must be in \[0, 0\]"),
    "line ends of another shape": (lambda: segments_clear(GEOMETRY, [0], ORIGIN, np.ones((2, 2))), "ends"),
    "poses not (N, 3)": (lambda: in_coverage(RangeBearingSensor(), ORIGIN, TARGETS), "poses"),
    "an empty stack": (lambda: StaticGeometry.stack([]), "one or more"),
    "a thickness of 0": (lambda: StaticGeometry.from_scenario(CORRIDOR, 0.0), "wall_thickness_m"),
    "a wall of one point": (
        lambda: StaticGeometry.from_scenario(Scenario("bad", (0, 0, 1, 1), PARKED, walls=((0.0, 1.0),)), 0.3),
        "'bad'",
    ),
    "a disc of radius NaN": (
        lambda: StaticGeometry.from_scenario(
            Scenario("nan", (0, 0, 1, 1), PARKED, obstacles=(CircleObstacle((0.0, 0.0), math.nan),)), 0.3
        ),
        "'nan'",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_CALLS))
def test_bad_input_raises_value_error_naming_it(case):
    call, words = BAD_CALLS[case]
    with pytest.raises(ValueError, match=words):
        call()


def test_bare_segments_of_radius_zero_equal_pymunk():
    """Bare segments (radius 0, allowed by Pymunk though World's walls are thick), one per space: queries nearly
    along them, by their ends; ``culled=False`` as Pymunk's tree of one leaf."""
    rng = np.random.default_rng(17)
    count = 2000
    starts = rng.uniform(0, 10, (count, 2))
    ends = starts + rng.uniform(-5, 5, (count, 2))
    direction = (ends - starts) / np.linalg.norm(ends - starts, axis=1, keepdims=True)
    off_line = rng.choice([0.0, 1e-16, -1e-16, 1e-15, -1e-15], (count, 1)) * direction[:, ::-1] * [-1.0, 1.0]
    end = np.where(rng.random((count, 1)) < 0.5, starts, ends) + off_line
    origins = end - rng.uniform(0.5, 3, (count, 1)) * rng.choice([-1.0, 1.0], (count, 1)) * direction
    targets = end + rng.uniform(-1, 3, (count, 1)) * direction
    expected = []
    for start, stop, origin, target in zip(starts, ends, origins, targets):
        space = pymunk.Space()
        space.add(pymunk.Segment(space.static_body, tuple(start), tuple(stop), 0.0))
        expected.append(space.segment_query_first(tuple(origin), tuple(target), 0.0, pymunk.ShapeFilter()) is not None)
    no_discs = np.zeros((count, 0, 2))
    segments = StaticGeometry(
        starts[:, None],
        ends[:, None],
        np.zeros((count, 1)),
        np.ones((count, 1), dtype=bool),
        no_discs,
        no_discs[..., 0],
        no_discs[..., 0] > 0,
    )
    got = unculled_hits(segments, origins, targets[:, None], WALL)
    np.testing.assert_array_equal(got[:, 0, 0], expected)
    assert 0 < np.sum(expected) < count


def test_tiled_copies_answer_as_stacked_ones_and_grown_shapes_are_swept_discs():
    world = random_world("field", 5)
    geometry = geometry_of(world)
    rng = np.random.default_rng(5)
    origins, targets = rng.uniform(0.0, 40.0, (6, 2)), rng.uniform(0.0, 40.0, (6, 9, 2))
    stacked = StaticGeometry.stack([geometry] * 6)
    np.testing.assert_array_equal(
        line_of_sight(geometry.tiled(6), origins, targets), line_of_sight(stacked, origins, targets)
    )
    np.testing.assert_array_equal(geometry.grown(0.3).disc_radii, geometry.disc_radii + 0.3)
    np.testing.assert_array_equal(geometry.grown(0.0).wall_radii, geometry.wall_radii)
