"""``infonav_gym.registration.icp``: recovery of known motions, conventions, robustness, Open3D, errors.

Synthetic clouds (noise std 1% of the cloud's extent, on the source only):

* ``box_cloud``: uniform in a 4 m cube. Any three non-collinear points fix a rigid motion, and
  with 2,000 points about 0.25 m apart and 4 cm noise, the closest point is almost always the
  true counterpart, so point-to-point ICP is well posed. 4 m (not 10 m) because the accuracy bar
  is absolute: the least-squares floor of the translation is about ``sigma * sqrt(3 / N)``,
  1.5 mm here but 3.9 mm at 10 m, where "< 5 mm" would be a coin toss.
* ``face_cloud``: the six faces of a randomly rotated box with sides 2-4 m. Its plane normals
  span 3D and every rotation moves some face along its normal, so point-to-plane ICP is well
  posed. Point-to-plane sees only the normal part of the noise, one constraint per point, so it
  needs 20,000 points for the same 0.1 degree floor that 2,000 give point-to-point.
"""

import importlib
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from infonav_gym.registration import RegistrationResult, icp, range_image_to_points
from infonav_gym.registration.icp import rotation_angle
from infonav_gym.sensors import Ladar, point_cloud
from infonav_gym.world.terrain_generation import make_terrain

ICP_MODULE = importlib.import_module("infonav_gym.registration.icp")  # the package attribute is the function
EXTENT_M = 4.0
NOISE_STD_M = 0.01 * EXTENT_M


def box_cloud(rng, count=2000):
    return rng.uniform(-EXTENT_M / 2, EXTENT_M / 2, (count, 3))


def face_cloud(rng, count=20000):
    sides = rng.uniform(EXTENT_M / 2, EXTENT_M, 3)
    areas = np.array([sides[1] * sides[2], sides[0] * sides[2], sides[0] * sides[1]])
    face_axis = rng.choice(3, size=count, p=areas / areas.sum())
    points = rng.uniform(-0.5, 0.5, (count, 3))
    points[np.arange(count), face_axis] = rng.choice([-0.5, 0.5], size=count)
    return (points * sides) @ Rotation.random(random_state=rng).as_matrix().T


def rigid(rotation, translation):
    transform = np.eye(4)
    transform[:3, :3], transform[:3, 3] = rotation, translation
    return transform


def random_motion(rng, max_angle_deg=10.0, max_translation_m=0.5):
    axis = rng.standard_normal(3)
    rotation = Rotation.from_rotvec(math.radians(rng.uniform(0, max_angle_deg)) * axis / np.linalg.norm(axis))
    direction = rng.standard_normal(3)
    return rigid(rotation.as_matrix(), rng.uniform(0, max_translation_m) * direction / np.linalg.norm(direction))


def noisy_source(rng, target, motion):
    """Source points with ``target ~ motion @ source``, plus 1% Gaussian noise."""
    source = (target - motion[:3, 3]) @ motion[:3, :3]
    return source + rng.normal(scale=NOISE_STD_M, size=source.shape)


def errors(estimate, truth):
    """Rotation error [deg] and translation error [m]."""
    return math.degrees(rotation_angle(estimate[:3, :3].T @ truth[:3, :3])), np.linalg.norm(
        estimate[:3, 3] - truth[:3, 3]
    )


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize(
    "make_cloud, method",
    [(box_cloud, "point_to_point"), (face_cloud, "point_to_point"), (face_cloud, "point_to_plane")],
)
def test_icp_recovers_a_known_motion_to_a_tenth_of_a_degree_and_5_mm(seed, make_cloud, method):
    rng = np.random.default_rng(seed)
    target = make_cloud(rng, 2000) if make_cloud is box_cloud else make_cloud(rng)  # a surface needs more points
    truth = random_motion(rng)
    result = icp(noisy_source(rng, target, truth), target, method=method)
    rotation_error_deg, translation_error_m = errors(result.transform, truth)
    assert result.converged and result.fitness > 0.95
    assert result.rmse == pytest.approx(
        math.sqrt(3) * NOISE_STD_M, rel=0.3 if make_cloud is box_cloud else 0.7
    )  # on a dense surface closest points absorb the tangential noise
    assert rotation_error_deg < 0.1 and translation_error_m < 5e-3


@pytest.mark.parametrize("method", ["point_to_point", "point_to_plane", "gicp"])
def test_identical_clouds_give_the_identity_after_one_iteration(method):
    cloud = face_cloud(np.random.default_rng(0), 2000)
    assert len(cloud) >= ICP_MODULE.COARSE_STRIDE * ICP_MODULE.COARSE_MIN_POINTS  # its coarse phase must not count
    result = icp(cloud, cloud, method=method)
    assert isinstance(result, RegistrationResult)
    assert result.iterations == 1 and result.converged
    np.testing.assert_allclose(result.transform, np.eye(4), rtol=0, atol=1e-12)
    assert result.rmse < 1e-12 and result.fitness == 1.0


@pytest.mark.parametrize("method", ["point_to_point", "point_to_plane", "gicp"])
def test_coarse_phase_is_only_a_speed_up(method, monkeypatch):
    """With and without the coarse phase: transforms far closer than the accuracy bar, fitness and rmse within 0.1%."""
    rng = np.random.default_rng(8)
    target = face_cloud(rng)
    truth = random_motion(rng)
    source = noisy_source(rng, target, truth)
    coarse_to_fine = icp(source, target, method=method, max_correspondence_distance=0.5)
    monkeypatch.setattr(ICP_MODULE, "COARSE_MIN_POINTS", len(source))
    fine_only = icp(source, target, method=method, max_correspondence_distance=0.5)
    assert coarse_to_fine.converged and fine_only.converged
    rotation_difference_deg, translation_difference_m = errors(coarse_to_fine.transform, fine_only.transform)
    assert rotation_difference_deg < 0.02 and translation_difference_m < 1e-3
    assert coarse_to_fine.fitness == pytest.approx(fine_only.fitness, abs=1e-3)
    assert coarse_to_fine.rmse == pytest.approx(fine_only.rmse, rel=1e-3)


def test_transform_maps_source_onto_target():
    source = box_cloud(np.random.default_rng(1))
    target = source + [0.3, -0.2, 0.1]
    result = icp(source, target)
    np.testing.assert_allclose(result.transform[:3, 3], [0.3, -0.2, 0.1], atol=1e-9)
    np.testing.assert_allclose(source @ result.transform[:3, :3].T + result.transform[:3, 3], target, atol=1e-9)


def test_warm_start_is_used_and_composed():
    rng = np.random.default_rng(2)
    target = box_cloud(rng)
    truth = random_motion(rng)
    source = (target - truth[:3, 3]) @ truth[:3, :3]
    cold = icp(source, target)
    warm = icp(source, target, truth)
    np.testing.assert_allclose(warm.transform, truth, atol=1e-9)
    assert warm.iterations <= 2 < cold.iterations


@pytest.mark.parametrize("method", ["point_to_point", "point_to_plane"])
def test_a_fifth_of_junk_source_points_does_not_spoil_the_result(method):
    """The MAD test drops the junk: 20% of the source replaced by points uniform in a box twice as large."""
    rng = np.random.default_rng(3)
    target = face_cloud(rng)
    truth = random_motion(rng)
    source = noisy_source(rng, target, truth)
    junk = rng.random(source.shape[0]) < 0.2
    source[junk] = rng.uniform(-EXTENT_M, EXTENT_M, (junk.sum(), 3))
    result = icp(source, target, method=method)
    rotation_error_deg, translation_error_m = errors(result.transform, truth)
    assert rotation_error_deg < 0.1 and translation_error_m < 5e-3
    assert result.fitness < 0.85  # most junk is rejected: 80% of the points are real


def test_max_correspondence_distance_leaves_points_without_counterpart_out():
    rng = np.random.default_rng(4)
    target = box_cloud(rng)
    source = np.vstack([target + [0.01, 0.0, 0.0], target[:500] + [0.0, 0.0, 3 * EXTENT_M]])
    result = icp(source, target, max_correspondence_distance=0.5)
    assert result.fitness == pytest.approx(2000 / 2500)
    np.testing.assert_allclose(result.transform[:3, 3], [-0.01, 0.0, 0.0], atol=1e-9)
    assert result.rmse < 1e-9


def test_no_correspondence_within_the_limit_returns_the_start_unconverged():
    cloud = box_cloud(np.random.default_rng(5))
    result = icp(cloud, cloud + 100.0, max_correspondence_distance=1.0)
    assert not result.converged and result.iterations == 0 and result.fitness == 0.0 and result.rmse == math.inf
    np.testing.assert_array_equal(result.transform, np.eye(4))


def test_max_iterations_caps_the_iterations():
    rng = np.random.default_rng(6)
    target = box_cloud(rng)
    result = icp(noisy_source(rng, target, random_motion(rng)), target, max_iterations=2)
    assert result.iterations == 2 and not result.converged


@pytest.mark.parametrize("seed", range(3))
def test_point_to_point_agrees_with_open3d(seed):
    o3d = pytest.importorskip("open3d")
    rng = np.random.default_rng(seed)
    target = box_cloud(rng)
    truth = random_motion(rng, max_angle_deg=5.0, max_translation_m=0.2)
    source = noisy_source(rng, target, truth)
    ours = icp(source, target, max_correspondence_distance=0.5, max_iterations=100)
    clouds = [o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points)) for points in (source, target)]
    theirs = o3d.pipelines.registration.registration_icp(
        *clouds,
        0.5,
        np.eye(4),
        o3d.pipelines.registration.TransformationEstimationPointToPoint(),
        o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=100),
    )
    theirs_transform = np.asarray(theirs.transformation)
    close = np.abs(ours.transform - theirs_transform).max() < 1e-3
    assert close or errors(ours.transform, truth) <= errors(theirs_transform, truth)
    assert ours.fitness == pytest.approx(theirs.fitness, abs=0.02)
    assert ours.rmse == pytest.approx(theirs.inlier_rmse, rel=0.1)


def test_range_image_points_match_the_ladar_point_cloud():
    terrain = make_terrain(np.random.default_rng(0))
    scan = Ladar().scan(terrain, [0.0, 0.0, 0.0], np.random.default_rng(0))
    pose = rigid(np.eye(3), scan.sensor_position_m)
    points = range_image_to_points(scan.ranges_m, scan.azimuth_rad, scan.elevation_rad, scan.no_return, pose)
    np.testing.assert_allclose(points, point_cloud(scan), rtol=0, atol=1e-9)
    local = range_image_to_points(scan.ranges_m, scan.azimuth_rad, scan.elevation_rad, scan.no_return)
    np.testing.assert_allclose(np.linalg.norm(local, axis=1), scan.ranges_m[~scan.no_return], rtol=1e-12)


def test_range_image_points_axes_and_pose():
    ranges = np.array([[2.0, 3.0]])
    points = range_image_to_points(ranges, np.array([0.0, math.pi / 2]), np.array([0.0]))
    np.testing.assert_allclose(points, [[2.0, 0.0, 0.0], [0.0, 3.0, 0.0]], atol=1e-15)
    up = range_image_to_points([[1.0]], [0.0], [math.pi / 2], no_return=[[False]])
    np.testing.assert_allclose(up, [[0.0, 0.0, 1.0]], atol=1e-15)
    turned = rigid(Rotation.from_euler("z", 90, degrees=True).as_matrix(), [1.0, 0.0, 0.0])
    moved = range_image_to_points(ranges, [0.0, math.pi / 2], [0.0], sensor_pose=turned)
    np.testing.assert_allclose(moved, [[1.0, 2.0, 0.0], [-2.0, 0.0, 0.0]], atol=1e-12)
    assert range_image_to_points([[1.0, np.inf]], [0.0, 1.0], [0.0]).shape == (1, 3)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"source": np.zeros((5, 2))}, r"source must be an \(N, 3\) array"),
        ({"target": np.zeros(9)}, r"target must be an \(N, 3\) array"),
        ({"source": np.zeros((2, 3))}, "source needs at least 3 points"),
        ({"target": [[0.0, 0.0, np.nan]] * 4}, "target must be finite, but 4 of its 4 points"),
        ({"source": [[np.inf, 0.0, 0.0]] + [[0.0, 0.0, 0.0]] * 3}, "source must be finite, but 1"),
        ({"init": np.eye(3)}, r"init must be a \(4, 4\) rigid transform"),
        ({"init": np.diag([1.0, 1.0, -1.0, 1.0])}, "init must be rigid"),
        ({"init": 2 * np.eye(4)}, r"init must have last row \[0, 0, 0, 1\]"),
        ({"init": np.diag([2.0, 1.0, 1.0, 1.0])}, "init must be rigid"),
        ({"init": np.full((4, 4), np.nan)}, "init must be finite"),
        ({"method": "point_to_line"}, "unknown ICP method 'point_to_line'"),
        ({"max_correspondence_distance": 0.0}, "max_correspondence_distance must be positive"),
        ({"max_correspondence_distance": -1.0}, "max_correspondence_distance must be positive"),
        ({"max_correspondence_distance": float("nan")}, "max_correspondence_distance must be positive"),
        ({"tolerance": 0.0}, "tolerance must be a positive number"),
        ({"tolerance": -1e-6}, "tolerance must be a positive number"),
        ({"max_iterations": 0}, "max_iterations must be a positive integer"),
        ({"max_iterations": 2.5}, "max_iterations must be a positive integer"),
    ],
)
def test_bad_input_is_refused_with_a_clear_message(kwargs, message):
    cloud = box_cloud(np.random.default_rng(7), 10)
    arguments = {"source": cloud, "target": cloud, **kwargs}
    with pytest.raises(ValueError, match=message):
        icp(arguments.pop("source"), arguments.pop("target"), **arguments)


def test_range_image_bad_input_is_refused():
    with pytest.raises(ValueError, match=r"ranges_m must be \(rows, columns\)"):
        range_image_to_points(np.ones((2, 3)), np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError, match="no_return must have the shape"):
        range_image_to_points(np.ones((1, 2)), np.zeros(2), np.zeros(1), no_return=np.zeros((2, 1), bool))
    with pytest.raises(ValueError, match="sensor_pose must be rigid"):
        range_image_to_points(np.ones((1, 2)), np.zeros(2), np.zeros(1), sensor_pose=np.diag([1, 1, -1, 1]))
