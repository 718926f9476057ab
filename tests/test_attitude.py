"""Vehicle attitude on terrain, rigid transforms, pitched LADAR frames and frame pairs."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from infonav_gym.geometry import (
    invert_transform,
    rigid_transform,
    rotation_angle,
    rotation_matrix,
    transform_error,
    transform_points,
)
from infonav_gym.registration import frame_pairs
from infonav_gym.sensors.ladar import Ladar, point_cloud, sensor_points
from infonav_gym.world.attitude import terrain_attitude
from infonav_gym.world.terrain import Terrain
from infonav_gym.world.terrain_generation import make_terrain


def plane(slope_x: float, slope_y: float, size_m: float = 400.0, cell_m: float = 2.0) -> Terrain:
    """The plane ``z = slope_x x + slope_y y`` sampled on a grid centred on the origin."""
    points = int(size_m / cell_m) + 1
    axis = -size_m / 2 + cell_m * np.arange(points)
    heights = slope_x * axis[None, :] + slope_y * axis[:, None]
    return Terrain(heights, (-size_m / 2, -size_m / 2), cell_m)


@pytest.mark.parametrize("roll, pitch, yaw", [(0.1, -0.2, 0.3), (-0.5, 0.4, -2.0), (0.0, 0.0, 1.0)])
def test_rotation_matrix_is_scipys_intrinsic_zyx_euler_rotation(roll, pitch, yaw):
    expected = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
    assert rotation_matrix(roll, pitch, yaw) == pytest.approx(expected, abs=1e-12)
    assert rotation_angle(rotation_matrix(roll, pitch, yaw)) == pytest.approx(
        Rotation.from_euler("ZYX", [yaw, pitch, roll]).magnitude(), abs=1e-9
    )


def test_rigid_transforms_invert_compose_and_measure_errors_in_closed_form():
    rng = np.random.default_rng(0)
    transform = rigid_transform(Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix(), [1.0, -2.0, 0.5])
    points = rng.normal(size=(20, 3))
    assert transform_points(invert_transform(transform), transform_points(transform, points)) == pytest.approx(points)
    assert invert_transform(transform) @ transform == pytest.approx(np.eye(4), abs=1e-12)
    shifted = rigid_transform(transform[:3, :3] @ Rotation.from_rotvec([0, 0, 0.05]).as_matrix(), [1.0, -2.0, 0.8])
    translation, rotation = transform_error(shifted, transform)
    assert translation == pytest.approx(0.3) and rotation == pytest.approx(0.05)


@pytest.mark.parametrize("heading", [0.0, math.pi / 2, 2.5])
def test_attitude_on_a_tilted_plane_follows_its_slope_along_and_across_the_heading(heading):
    slope = np.array([0.2, -0.1])
    forward = np.array([math.cos(heading), math.sin(heading)])
    left = np.array([-forward[1], forward[0]])
    roll, pitch = terrain_attitude(plane(*slope), [3.0, -4.0, heading])
    assert pitch == pytest.approx(-math.atan(slope @ forward))
    assert roll == pytest.approx(math.atan(slope @ left))
    # The body axes lie in the plane along the heading (forward) and across it.
    rotation = rotation_matrix(roll, pitch, heading)
    assert rotation[2, 0] == pytest.approx(rotation[:2, 0] @ slope)
    assert rotation[2, 1] == pytest.approx(rotation[:2, 1] @ slope, abs=0.02)  # exact for small slopes only


def test_a_vehicle_aligned_with_a_tilted_plane_sees_what_a_level_one_sees_on_level_ground():
    ladar = Ladar(range_std_m=0.0, max_range_m=100.0)
    slope_x = 0.15  # pure pitch: the body frame is exactly the plane's
    tilted = ladar.scan(
        plane(slope_x, 0.0), [0.0, 0.0, 0.0], np.random.default_rng(0), attitude_rad=(0.0, -math.atan(slope_x))
    )
    level = ladar.scan(plane(0.0, 0.0), [0.0, 0.0, 0.0], np.random.default_rng(0))
    hit = ~level.no_return
    assert np.array_equal(tilted.no_return, level.no_return)
    assert tilted.ranges_m[hit] == pytest.approx(level.ranges_m[hit], rel=1e-4)


def test_pitched_and_rolled_frames_land_on_the_ground_and_world_from_sensor_places_them():
    terrain = make_terrain(np.random.default_rng(3), roughness=0.7, n_trees=0, n_rocks=0, n_buildings=0)
    pose = [2.0, -1.0, 0.7]
    attitude = terrain_attitude(terrain, pose)
    assert max(abs(a) for a in attitude) > math.radians(1.0), "the test needs a tilted vehicle"
    scan = Ladar(range_std_m=0.0).scan(terrain, pose, np.random.default_rng(0), attitude_rad=attitude)
    world = point_cloud(scan)
    assert world == pytest.approx(transform_points(scan.world_from_sensor, sensor_points(scan)), abs=1e-9)
    assert np.abs(world[:, 2] - terrain.height_at(world[:, :2])).max() < 0.02
    up = scan.world_from_sensor[:3, 2]
    ground = np.array([*pose[:2], terrain.height_at(np.array(pose[:2]))])
    assert scan.sensor_position_m == pytest.approx(ground + 2.0 * up)


@pytest.mark.parametrize("attitude", [(math.nan, 0.0), (0.0, 2.0)])
def test_bad_attitude_raises(attitude):
    with pytest.raises(ValueError, match="attitude_rad"):
        Ladar().scan(
            make_terrain(np.random.default_rng(0)), [0.0, 0.0, 0.0], np.random.default_rng(0), attitude_rad=attitude
        )


def test_frame_pair_true_motion_maps_current_points_onto_the_previous_frame():
    terrain = make_terrain(np.random.default_rng(4), roughness=0.7)
    ladar = Ladar(range_std_m=0.0)
    previous = frame_pairs.scan_on_terrain(ladar, terrain, [0.0, 0.0, 0.3], np.random.default_rng(1))
    current = frame_pairs.scan_on_terrain(ladar, terrain, [0.9, 0.4, 0.35], np.random.default_rng(2))
    pair = frame_pairs.frame_pair(previous, current, np.random.default_rng(3))
    mapped = transform_points(previous.world_from_sensor @ pair.true_motion, sensor_points(current))
    assert mapped == pytest.approx(point_cloud(current), abs=1e-9)
    assert pair.motion_covariance == pytest.approx(np.diag(np.square(frame_pairs.DEFAULT_ODOMETRY_STD)))


def test_odometry_errors_have_the_configured_spread_and_the_error_metric_weighs_rotation_by_the_lever_arm():
    std = np.array([0.1, 0.2, 0.05, 0.01, 0.02, 0.03])
    rng = np.random.default_rng(5)
    truth = rigid_transform(rotation_matrix(0.1, 0.0, 0.2), [1.0, 0.0, 0.1])
    errors = np.array([frame_pairs.perturbed_motion(truth, std * rng.standard_normal(6)) for _ in range(4000)])
    relative = np.array([invert_transform(truth) @ e for e in errors])
    assert relative[:, :3, 3].std(axis=0) == pytest.approx(std[:3], rel=0.05)
    rotvecs = Rotation.from_matrix(relative[:, :3, :3]).as_rotvec()
    assert rotvecs.std(axis=0) == pytest.approx(std[3:], rel=0.05)
    estimate = rigid_transform(truth[:3, :3] @ rotation_matrix(0.0, 0.0, 0.004), truth[:3, 3] + [0.03, 0.0, 0.0])
    assert frame_pairs.registration_error(estimate, truth) == pytest.approx(math.hypot(0.03, 10 * 0.004))
    with pytest.raises(ValueError, match="odometry_std"):
        frame_pairs.frame_pair(None, None, rng, odometry_std=(0.1, -0.1, 0.1, 0.1, 0.1, 0.1))
