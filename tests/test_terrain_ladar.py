"""Terrain and LADAR geometry against closed forms (issue 4)."""

import math

import numpy as np
import pymunk
import pytest
from scipy.interpolate import RegularGridInterpolator
from skimage.measure import shannon_entropy

from infonav_gym.experiments.sensor_timing import footprint_space
from infonav_gym.information import histogram_entropy
from infonav_gym.sensors.ladar import Ladar, point_cloud, to_display_image
from infonav_gym.sensors.pixel_grid import unit_directions
from infonav_gym.world.terrain import MATERIALS, NO_HIT, Box, Cylinder, Terrain
from infonav_gym.world.terrain_generation import flat_terrain, make_terrain
from infonav_gym.world.terrain_kernels import ground_at


def ray_directions(ladar: Ladar, vehicle_pose) -> np.ndarray:
    """World-frame unit directions (rows, columns, 3) of ``ladar``'s pixels from ``vehicle_pose``."""
    azimuth, elevation = ladar.pixel_angles()
    return unit_directions(vehicle_pose[2] + azimuth, elevation)


def surface_normal_at(terrain: Terrain, xy) -> np.ndarray:
    """Upward unit normals (..., 3) of the terrain's bilinear ground at ``xy`` (..., 2), from its kernel."""
    points = np.asarray(xy, dtype=float)
    return ground_at(terrain.arrays[0], np.ascontiguousarray(points.reshape(-1, 2)))[1].reshape(*points.shape[:-1], 3)


EXACT = {"rtol": 1e-6, "atol": 1e-9}


def flat_ground_ranges(ladar: Ladar, elevation_rad: np.ndarray) -> np.ndarray:
    """Closed form on level ground: ``h / sin(depression)`` per row, ``inf`` at or above the horizon."""
    depression = -elevation_rad
    with np.errstate(divide="ignore"):
        ranges = np.where(depression > 0, ladar.mount_height_m / np.sin(depression), np.inf)
    return np.where(ranges <= ladar.max_range_m, ranges, np.inf)


def test_flat_ground_rows_range_is_mount_height_over_sine_of_depression():
    ladar = Ladar(range_std_m=0.0, tilt_rad=math.radians(5.0))
    scan = ladar.scan(flat_terrain(), [3.0, -2.0, 0.7], np.random.default_rng(0))
    expected = flat_ground_ranges(ladar, scan.elevation_rad)
    hits = np.isfinite(expected)
    assert scan.ranges_m.shape == (32, 180) and scan.ranges_m.dtype == np.float32
    assert (scan.elevation_rad >= 0).sum() == 8  # rows 0-7 look above the horizon
    assert 0 < hits.sum() < 32 - 8  # some rows below the horizon still reach past max range
    np.testing.assert_allclose(scan.ranges_m[hits], np.repeat(expected[hits, None], 180, axis=1), **EXACT)
    np.testing.assert_array_equal(scan.no_return, np.repeat(~hits[:, None], 180, axis=1))
    assert np.all(scan.ranges_m[~hits] == ladar.max_range_m)


def test_flat_ground_range_noise_has_the_configured_standard_deviation():
    range_std_m = 0.05
    ladar = Ladar(range_std_m=range_std_m)
    scan = ladar.scan(flat_terrain(), [0.0, 0.0, 0.0], np.random.default_rng(1))
    expected = flat_ground_ranges(ladar, scan.elevation_rad)[:, None] * np.ones(180)
    clear_of_clipping = expected < ladar.max_range_m - 6 * range_std_m
    errors = (scan.ranges_m - expected)[clear_of_clipping]
    assert errors.size > 4000
    assert abs(errors.mean()) < 4 * range_std_m / math.sqrt(errors.size)
    assert errors.std() == pytest.approx(range_std_m, rel=0.05)


def test_ground_on_a_tilted_plane_matches_the_ray_plane_intersection():
    slope_x, height_at_origin_m = 0.1, 3.0  # ground z = 3 + 0.1 x
    x = np.arange(-100.0, 100.5, 0.5)
    terrain = Terrain(np.tile(height_at_origin_m + slope_x * x, (x.size, 1)), (-100.0, -100.0), 0.5)
    ladar = Ladar(range_std_m=0.0)
    scan = ladar.scan(terrain, [0.0, 0.0, 0.0], np.random.default_rng(0))
    azimuth, elevation = np.meshgrid(scan.azimuth_rad, scan.elevation_rad)
    expected = ladar.mount_height_m / (slope_x * np.cos(elevation) * np.cos(azimuth) - np.sin(elevation))
    hits = (expected > 0) & (expected <= ladar.max_range_m)
    assert hits.sum() > 1000
    np.testing.assert_allclose(scan.ranges_m[hits], expected[hits], **EXACT)
    assert np.all(scan.no_return == ~hits)


@pytest.mark.parametrize("heading_rad, pan_rad", [(0.0, 0.0), (math.pi / 2, 0.0), (0.0, math.pi / 2), (math.pi, 0.0)])
def test_wall_straight_ahead_gives_distance_over_cos_azimuth_cos_elevation(heading_rad, pan_rad):
    distance_m, half_width_m, vehicle_xy = 10.0, 4.0, np.array([3.0, -2.0])
    look = np.array([math.cos(heading_rad + pan_rad), math.sin(heading_rad + pan_rad)]).round()
    across = np.array([-look[1], look[0]])
    near_face, far_face = vehicle_xy + distance_m * look, vehicle_xy + (distance_m + 0.5) * look
    corners = np.array([near_face + half_width_m * across, far_face - half_width_m * across])
    wall = Box((*corners.min(axis=0), -1.0), (*corners.max(axis=0), 20.0))
    terrain = flat_terrain().with_obstacles(boxes=[wall])
    ladar = Ladar(range_std_m=0.0, tilt_rad=0.0, pan_rad=pan_rad)
    scan = ladar.scan(terrain, [*vehicle_xy, heading_rad], np.random.default_rng(0))

    relative_azimuth = scan.azimuth_rad - pan_rad
    sees_wall = np.abs(distance_m * np.tan(relative_azimuth)) < half_width_m
    wall_range = distance_m / (np.cos(relative_azimuth)[None, :] * np.cos(scan.elevation_rad)[:, None])
    ground_range = flat_ground_ranges(ladar, scan.elevation_rad)[:, None] * np.ones(ladar.columns)
    expected = np.where(sees_wall[None, :], np.minimum(wall_range, ground_range), ground_range)
    assert 60 < sees_wall.sum() < ladar.columns - 60
    np.testing.assert_allclose(scan.ranges_m[~scan.no_return], expected[np.isfinite(expected)], **EXACT)
    np.testing.assert_array_equal(scan.no_return, ~np.isfinite(expected))
    assert not scan.no_return[:, sees_wall].any()  # every row of those columns hits the wall
    hits = terrain.cast_rays(scan.sensor_position_m, heading_rad + scan.azimuth_rad, scan.elevation_rad, 60.0)
    sees_it_first = wall_range < ground_range
    assert np.all(hits.material_index[:, sees_wall][sees_it_first[:, sees_wall]] == MATERIALS.index("building"))


def test_tree_at_known_position_center_pixel_reads_distance_minus_radius():
    distance_m, radius_m = 15.0, 0.4
    tree = Cylinder((distance_m, 0.0), radius_m, bottom_m=-1.0, top_m=8.0)
    terrain = flat_terrain().with_obstacles(cylinders=[tree])
    ladar = Ladar(rows=33, columns=181, range_std_m=0.0, tilt_rad=0.0)
    scan = ladar.scan(terrain, [0.0, 0.0, 0.0], np.random.default_rng(0))
    assert scan.azimuth_rad[90] == pytest.approx(0.0, abs=1e-12)
    assert scan.elevation_rad[16] == pytest.approx(0.0, abs=1e-12)
    assert scan.ranges_m[16, 90] == pytest.approx(distance_m - radius_m, rel=1e-6)
    azimuth, elevation = np.meshgrid(scan.azimuth_rad, scan.elevation_rad)
    lateral = distance_m * np.sin(azimuth)
    with np.errstate(invalid="ignore"):
        tree_range = (distance_m * np.cos(azimuth) - np.sqrt(radius_m**2 - lateral**2)) / np.cos(elevation)
    sees_tree = (np.abs(lateral) < radius_m) & (tree_range < flat_ground_ranges(ladar, elevation))
    assert sees_tree.sum() >= 33
    np.testing.assert_allclose(scan.ranges_m[sees_tree], tree_range[sees_tree], **EXACT)
    hits = terrain.cast_rays(scan.sensor_position_m, scan.azimuth_rad, scan.elevation_rad, 60.0)
    assert np.all(hits.material_index[sees_tree] == MATERIALS.index("vegetation"))
    assert np.all(hits.material_index[(elevation > 0) & ~sees_tree] == NO_HIT)


def test_horizontal_rays_meet_the_obstacles_where_the_pymunk_benchmark_reference_does():
    terrain = flat_terrain().with_obstacles(
        cylinders=[Cylinder((8.0, 3.0), 1.0, bottom_m=-1.0, top_m=5.0)],
        boxes=[Box((-9.0, -6.0, -1.0), (-5.0, 4.0, 5.0))],
    )
    origin, azimuth, max_range_m = np.array([0.3, -0.6, 1.0]), np.radians(np.arange(360.0)), 30.0
    ranges = terrain.cast_rays(origin, azimuth, np.zeros(1), max_range_m).range_m[0]
    space, start = footprint_space(terrain), tuple(origin[:2])
    expected = []
    for angle in azimuth:
        end = (start[0] + max_range_m * math.cos(angle), start[1] + max_range_m * math.sin(angle))
        query = space.segment_query_first(start, end, 0, pymunk.ShapeFilter())
        expected.append(math.inf if query is None else max_range_m * query.alpha)
    assert np.isfinite(ranges).sum() > 60  # both obstacles are seen
    np.testing.assert_allclose(ranges, expected, **EXACT)


@pytest.mark.parametrize(
    "rows, columns, vertical_fov_deg, horizontal_fov_deg, tilt_deg, pan_deg",
    [(8, 20, 30.0, 100.0, 0.0, 0.0), (32, 180, 20.0, 80.0, 10.0, -25.0), (1, 3, 5.0, 170.0, -20.0, 90.0)],
)
def test_image_shape_and_angular_spacing_follow_config(
    rows, columns, vertical_fov_deg, horizontal_fov_deg, tilt_deg, pan_deg
):
    ladar = Ladar(
        rows=rows,
        columns=columns,
        vertical_fov_rad=math.radians(vertical_fov_deg),
        horizontal_fov_rad=math.radians(horizontal_fov_deg),
        tilt_rad=math.radians(tilt_deg),
        pan_rad=math.radians(pan_deg),
    )
    heading_rad = 0.3
    directions = ray_directions(ladar, [1.0, 2.0, heading_rad])
    assert directions.shape == (rows, columns, 3)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0, rtol=1e-12)
    elevation = np.degrees(np.arcsin(directions[..., 2]))
    azimuth = np.degrees(np.unwrap(np.arctan2(directions[..., 1], directions[..., 0]), axis=1) - heading_rad)
    np.testing.assert_allclose(np.diff(elevation, axis=0), -vertical_fov_deg / rows, rtol=1e-9)
    np.testing.assert_allclose(np.diff(azimuth, axis=1), -horizontal_fov_deg / columns, rtol=1e-9)
    assert elevation[0, 0] == pytest.approx(vertical_fov_deg / 2 * (1 - 1 / rows) - tilt_deg)
    assert azimuth[0, 0] == pytest.approx(pan_deg + horizontal_fov_deg / 2 * (1 - 1 / columns))
    scan = ladar.scan(flat_terrain(), [1.0, 2.0, heading_rad], np.random.default_rng(0))
    assert scan.ranges_m.shape == scan.no_return.shape == (rows, columns)


def fine_march(terrain: Terrain, ladar: Ladar, vehicle_pose, step_m: float = 0.01):
    """Brute-force reference: points every ``step_m`` along each ray, ``solid`` where inside ground or obstacle.

    Returns the distances (T,), the ray points (rows, columns, T, 3) and ``solid`` (rows, columns, T).
    """
    origin = np.array([*vehicle_pose[:2], terrain.height_at(np.array(vehicle_pose[:2])) + ladar.mount_height_m])
    distances = np.arange(1, round(ladar.max_range_m / step_m) + 1) * step_m
    points = origin + distances[:, None] * ray_directions(ladar, vehicle_pose)[:, :, None, :]
    solid = points[..., 2] <= terrain.height_at(points[..., :2])
    for tree in terrain.cylinders:
        within = np.linalg.norm(points[..., :2] - tree.center_m, axis=-1) <= tree.radius_m
        solid |= within & (tree.bottom_m <= points[..., 2]) & (points[..., 2] <= tree.top_m)
    for box in terrain.boxes:
        solid |= np.all((box.min_corner_m <= points) & (points <= box.max_corner_m), axis=-1)
    return distances, points, solid


@pytest.mark.parametrize("seed", [1, 4])
def test_rugged_scene_ranges_agree_with_a_fine_brute_force_march(seed):
    terrain = make_terrain(np.random.default_rng(seed), roughness=1.0, n_trees=25, n_rocks=8, n_buildings=3)
    ladar = Ladar(rows=10, columns=40, max_range_m=25.0, range_std_m=0.0, tilt_rad=math.radians(5.0))
    pose = [0.0, 0.0, 1.3 * seed]
    scan = ladar.scan(terrain, pose, np.random.default_rng(0))
    distances, points, solid = fine_march(terrain, ladar, pose)
    reference = np.where(solid.any(axis=-1), distances[solid.argmax(axis=-1)], np.inf)
    measured = np.where(scan.no_return, np.inf, scan.ranges_m)
    assert np.mean(np.isfinite(reference) != np.isfinite(measured)) < 0.01
    both = np.isfinite(reference) & np.isfinite(measured)
    within_a_step = (measured > reference - 0.01 - 1e-4) & (measured < reference + 1e-4)
    assert both.sum() > 150 and np.mean(within_a_step[both]) > 0.98
    # the rest are rays grazing a crest: the ground is sampled once per cell along a ray, so a ray may
    # pass a few centimetres into the bilinear surface between samples, never deeper
    clearance = points[..., 2] - terrain.height_at(points[..., :2])
    before_hit = distances < np.where(np.isfinite(measured), measured, ladar.max_range_m)[..., None] - 0.02
    assert np.where(before_hit, clearance, np.inf).min() > -0.05


def test_scans_and_terrains_are_deterministic_given_the_seed():
    terrain = make_terrain(np.random.default_rng(7))
    again = make_terrain(np.random.default_rng(7))
    other = make_terrain(np.random.default_rng(8))
    np.testing.assert_array_equal(terrain.heights_m, again.heights_m)
    assert terrain.cylinders == again.cylinders and terrain.boxes == again.boxes
    assert not np.array_equal(terrain.heights_m, other.heights_m)
    ladar, pose = Ladar(), [0.0, 0.0, 1.0]
    first = ladar.scan(terrain, pose, np.random.default_rng(3))
    second = ladar.scan(terrain, pose, np.random.default_rng(3))
    np.testing.assert_array_equal(first.ranges_m, second.ranges_m)
    assert not np.array_equal(first.ranges_m, ladar.scan(terrain, pose, np.random.default_rng(4)).ranges_m)


def test_make_terrain_roughness_zero_is_flat_and_obstacles_stand_clear_of_the_center():
    flat = make_terrain(np.random.default_rng(5), roughness=0.0)
    rugged = make_terrain(np.random.default_rng(5), roughness=1.0)
    assert np.all(flat.heights_m == 0.0)
    assert rugged.heights_m.std() > 1.0
    assert flat.cylinders[0].center_m == rugged.cylinders[0].center_m  # layout does not depend on roughness
    assert (len(flat.cylinders), len(flat.boxes)) == (20, 2)
    assert flat.bounds_m == (-30.0, -30.0, 30.0, 30.0) and flat.heights_m.shape == (121, 121)
    for tree in rugged.cylinders:
        assert math.hypot(*tree.center_m) > 5.0 + tree.radius_m
        assert tree.bottom_m <= rugged.height_at(np.array(tree.center_m)) < tree.top_m


def test_height_and_normal_are_exact_on_a_plane_and_interpolate_between_grid_points():
    slope = np.array([0.2, -0.5])
    y, x = np.mgrid[0:11, 0:21] * 0.5
    terrain = Terrain(1.0 + slope[0] * x + slope[1] * y, (0.0, 0.0), 0.5)
    points = np.random.default_rng(0).uniform([0.0, 0.0], [10.0, 5.0], size=(50, 2))
    np.testing.assert_allclose(terrain.height_at(points), 1.0 + points @ slope, rtol=1e-12)
    normal = np.array([-slope[0], -slope[1], 1.0]) / np.linalg.norm([*slope, 1.0])
    np.testing.assert_allclose(surface_normal_at(terrain, points), np.tile(normal, (50, 1)), rtol=1e-12)
    bump = Terrain(np.array([[0.0, 0.0], [0.0, 4.0]]), (0.0, 0.0), 2.0)
    assert bump.height_at(np.array([1.0, 1.0])) == pytest.approx(1.0)  # bilinear: 4 * 0.5 * 0.5
    assert bump.height_at(np.array([[5.0, 5.0]]))[0] == pytest.approx(4.0)  # the edge extends beyond the grid


def test_height_is_scipys_bilinear_interpolation_and_the_normal_its_gradient_on_random_grids():
    rng = np.random.default_rng(3)
    terrain = Terrain(rng.normal(size=(9, 13)), (-2.0, 1.0), 0.7)
    x0, y0, x1, y1 = terrain.bounds_m
    inside = rng.uniform([x0, y0], [x1, y1], size=(400, 2))
    beyond = rng.uniform([x0 - 3, y0 - 3], [x1 + 3, y1 + 3], size=(400, 2))  # the edge heights extend
    x_grid, y_grid = x0 + 0.7 * np.arange(13), y0 + 0.7 * np.arange(9)
    interpolate = RegularGridInterpolator((y_grid, x_grid), terrain.heights_m, method="linear")
    for points in (inside, beyond):
        clamped = np.clip(points, [x0, y0], [x1, y1])
        np.testing.assert_allclose(terrain.height_at(points), interpolate(clamped[:, ::-1]), rtol=1e-12, atol=1e-12)
    step = 1e-6
    slope_x = (terrain.height_at(inside + [step, 0.0]) - terrain.height_at(inside - [step, 0.0])) / (2 * step)
    slope_y = (terrain.height_at(inside + [0.0, step]) - terrain.height_at(inside - [0.0, step])) / (2 * step)
    gradient_normal = np.stack([-slope_x, -slope_y, np.ones(400)], axis=1)
    gradient_normal /= np.linalg.norm(gradient_normal, axis=1, keepdims=True)
    on_grid_lines = np.any(np.abs(np.remainder(inside - [x0, y0] + step, 0.7)) < 2 * step, axis=1)
    np.testing.assert_allclose(
        surface_normal_at(terrain, inside)[~on_grid_lines], gradient_normal[~on_grid_lines], atol=1e-8
    )
    assert surface_normal_at(terrain, np.array([x0 - 1.0, y0 - 1.0])).tolist() == [0.0, 0.0, 1.0]  # level beyond


def test_ray_hits_name_the_obstacle_they_hit():
    trees = [Cylinder((10.0, 0.0), 1.0, -1.0, 6.0), Cylinder((10.0, 3.0), 0.5, -1.0, 6.0, material="rock")]
    wall = Box((-12.0, -5.0, -1.0), (-11.0, 5.0, 4.0))
    terrain = flat_terrain().with_obstacles(cylinders=trees, boxes=[wall])
    azimuth = np.array([0.0, math.atan2(3.0, 10.0), math.pi, math.pi / 2])
    hits = terrain.cast_rays([0.0, 0.0, 1.0], azimuth, np.array([0.0, -0.5]), 50.0)
    np.testing.assert_array_equal(hits.obstacle_index, [[0, 1, 2, -1], [-1, -1, -1, -1]])
    np.testing.assert_array_equal(hits.material_index, [[1, 2, 3, NO_HIT], [0, 0, 0, 0]])
    np.testing.assert_allclose(hits.range_m[0, :3], [9.0, math.hypot(10.0, 3.0) - 0.5, 11.0], rtol=1e-12)


def test_display_image_is_dark_near_light_far_and_white_without_return():
    ladar = Ladar()
    scan = ladar.scan(make_terrain(np.random.default_rng(2)), [0.0, 0.0, 0.0], np.random.default_rng(0))
    image = to_display_image(scan)
    assert image.dtype == np.uint8 and image.shape == (32, 180)
    assert scan.no_return.any() and np.all(image[scan.no_return] == 255)
    assert np.all(np.abs(image - 255.0 * scan.ranges_m / ladar.max_range_m) <= 0.5 + 1e-4)  # linear in range
    near, far = (
        np.unravel_index(scan.ranges_m.argmin(), image.shape),
        np.unravel_index(scan.ranges_m.argmax(), image.shape),
    )
    assert image[near] < image[far]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_histogram_entropy_of_display_image_agrees_with_scikit_image(seed):
    terrain = make_terrain(np.random.default_rng(seed), roughness=0.8)
    scan = Ladar().scan(terrain, [0.0, 0.0, seed], np.random.default_rng(seed))
    image = to_display_image(scan)
    assert histogram_entropy(image) == pytest.approx(shannon_entropy(image, base=np.e), rel=1e-12)
    assert histogram_entropy(image) > 2.0


def test_point_cloud_lies_on_the_ground_and_moves_with_the_pose():
    ladar = Ladar(range_std_m=0.0)
    scan = ladar.scan(flat_terrain(), [3.0, 4.0, 0.5], np.random.default_rng(0))
    points = point_cloud(scan)
    assert points.shape == ((~scan.no_return).sum(), 3)
    np.testing.assert_allclose(points[:, 2], 0.0, atol=1e-5)
    np.testing.assert_allclose(point_cloud(scan, [4.0, 2.0, 0.5]), points + [1.0, -2.0, 0.0], atol=1e-9)
    turned = point_cloud(scan, [3.0, 4.0, 0.5 + math.pi])
    np.testing.assert_allclose(turned[:, :2] - [3.0, 4.0], -(points[:, :2] - [3.0, 4.0]), atol=1e-9)


@pytest.mark.parametrize(
    "config, key",
    [
        ({"rows": 0}, "rows"),
        ({"columns": 2.5}, "columns"),
        ({"vertical_fov_rad": 0.0}, "vertical_fov_rad"),
        ({"horizontal_fov_rad": math.pi}, "horizontal_fov_rad"),
        ({"horizontal_fov_rad": -0.1}, "horizontal_fov_rad"),
        ({"range_std_m": -0.01}, "range_std_m"),
        ({"max_range_m": 0.0}, "max_range_m"),
        ({"mount_height_m": float("nan")}, "mount_height_m"),
        ({"tilt_rad": math.radians(85.0)}, "tilt_rad"),
    ],
)
def test_bad_ladar_config_raises_naming_the_key(config, key):
    with pytest.raises(ValueError, match=key):
        Ladar(**config)


def test_bad_scene_and_scan_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match="heights_m contains NaN"):
        Terrain(np.array([[0.0, np.nan], [0.0, 0.0]]))
    with pytest.raises(ValueError, match=r"at least 2 x 2 points, got shape \(5,\)"):
        Terrain(np.zeros(5))
    with pytest.raises(ValueError, match="cell_m must be positive"):
        Terrain(np.zeros((3, 3)), cell_m=0.0)
    with pytest.raises(ValueError, match="radius_m must be positive"):
        Cylinder((0.0, 0.0), 0.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="must be below max_corner_m"):
        Box((0.0, 0.0, 0.0), (1.0, -1.0, 1.0))
    with pytest.raises(ValueError, match="'lava'"):
        Box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), material="lava")
    with pytest.raises(ValueError, match="roughness must be"):
        make_terrain(np.random.default_rng(0), roughness=-1.0)
    with pytest.raises(ValueError, match="query points must be finite"):
        flat_terrain().height_at(np.zeros((4, 3)))
    ladar, rng = Ladar(), np.random.default_rng(0)
    with pytest.raises(ValueError, match=r"vehicle_pose must be finite \[x, y, heading\]"):
        ladar.scan(flat_terrain(), [0.0, 0.0], rng)
    with pytest.raises(ValueError, match="tilt_rad"):
        ladar.scan(flat_terrain(), [0.0, 0.0, 0.0], rng, tilt_rad=math.radians(89.0))
    with pytest.raises(ValueError, match="not above the ground"):
        flat_terrain().cast_rays([0.0, 0.0, -1.0], np.zeros(3), np.zeros(2), 10.0)
