"""Camera images against closed-form radiometry and geometry (issue 4, item 3)."""

import math

import numpy as np
import pytest
from skimage.measure import shannon_entropy

from infonav_gym.information import histogram_entropy
from infonav_gym.sensors import Camera, ground_texture
from infonav_gym.sensors import camera as camera_module
from infonav_gym.world.terrain import Box, Cylinder
from infonav_gym.world.terrain_generation import flat_terrain, make_terrain

CLEAN = {"noise_std": 0.0, "ground_texture_contrast": 0.0}  # noise-free, uniform ground


def lambert(camera: Camera, albedo: float, normal) -> float:
    """The documented closed form: ``exposure * albedo * (ambient + (1 - ambient) * max(0, n . sun))``."""
    cosine = max(0.0, float(np.dot(normal, camera.sun_direction)))
    return camera.exposure * albedo * (camera.ambient + (1 - camera.ambient) * cosine)


def test_image_shape_dtype_and_field_of_view_follow_config():
    camera = Camera(rows=30, columns=40, horizontal_fov_rad=math.radians(90.0))
    image = camera.capture(flat_terrain(), [0.0, 0.0, 0.0], np.random.default_rng(0))
    assert image.shape == (30, 40) and image.dtype == np.uint8
    assert camera.vertical_fov_rad == pytest.approx(2 * math.atan(math.tan(math.radians(45.0)) * 30 / 40))
    azimuth, elevation = camera.pixel_angles()
    assert azimuth[0] - azimuth[-1] == pytest.approx(math.radians(90.0) * 39 / 40)
    assert elevation[0] - elevation[-1] == pytest.approx(camera.vertical_fov_rad * 29 / 30)
    assert Camera(vertical_fov_rad=0.3).vertical_fov_rad == 0.3
    assert Camera().capture(flat_terrain(), [0.0, 0.0, 0.0], np.random.default_rng(0)).shape == (120, 160)


def test_same_seed_gives_the_same_image_and_another_seed_differs():
    terrain = make_terrain(np.random.default_rng(3))
    camera = Camera()
    first = camera.capture(terrain, [1.0, -2.0, 0.4], np.random.default_rng(7))
    again = camera.capture(terrain, [1.0, -2.0, 0.4], np.random.default_rng(7))
    other = camera.capture(terrain, [1.0, -2.0, 0.4], np.random.default_rng(8))
    np.testing.assert_array_equal(first, again)
    assert np.any(first != other)


def test_pan_and_tilt_overrides_match_a_camera_configured_with_them():
    terrain = make_terrain(np.random.default_rng(4))
    pose = [0.0, 0.0, 0.2]
    overridden = Camera().capture(terrain, pose, np.random.default_rng(0), pan_rad=0.5, tilt_rad=0.1)
    configured = Camera(pan_rad=0.5, tilt_rad=0.1).capture(terrain, pose, np.random.default_rng(0))
    np.testing.assert_array_equal(overridden, configured)
    # panning left by 0.5 rad equals turning the vehicle left by 0.5 rad
    turned = Camera(tilt_rad=0.1).capture(terrain, [0.0, 0.0, 0.7], np.random.default_rng(0))
    np.testing.assert_array_equal(overridden, turned)


def test_flat_ground_has_the_closed_form_brightness_and_rows_above_the_horizon_are_sky():
    camera = Camera(tilt_rad=math.radians(5.0), sun_elevation_rad=math.radians(35.0), **CLEAN)
    image = camera.capture(flat_terrain(size_m=400.0, cell_m=2.0), [3.0, -2.0, 0.7], np.random.default_rng(0))
    _, elevation = camera.pixel_angles()
    sky_rows = elevation > 0
    far_plane_depression = math.atan(camera.mount_height_m / camera.max_range_m)
    ground_rows = elevation < -far_plane_depression - 1e-3
    assert sky_rows.sum() > 10 and ground_rows.sum() > 50
    expected_ground = (
        camera.exposure
        * camera.ground_albedo
        * (camera.ambient + (1 - camera.ambient) * math.sin(camera.sun_elevation_rad))
    )
    assert np.all(image[ground_rows] == round(expected_ground))
    assert np.all(image[sky_rows] == round(camera.sky_level))
    assert round(camera.sky_level) != round(expected_ground)


def test_ground_texture_varies_with_world_position_within_the_configured_contrast():
    camera = Camera(noise_std=0.0, ground_texture_contrast=0.5, sun_elevation_rad=math.pi / 2)
    image = camera.capture(flat_terrain(), [0.0, 0.0, 0.0], np.random.default_rng(0))
    ground = image[camera.pixel_angles()[1] < -0.1].astype(float)
    uniform = camera.exposure * camera.ground_albedo  # sun overhead: shading 1
    assert ground.std() > 3.0
    assert ground.min() >= math.floor(uniform * 0.5) and ground.max() <= math.ceil(uniform * 1.5)
    texture = ground_texture(np.random.default_rng(1).uniform(-300, 300, size=(20000, 2)))
    assert np.all(np.abs(texture) <= 1) and abs(texture.mean()) < 0.05
    np.testing.assert_array_equal(texture, ground_texture(np.random.default_rng(1).uniform(-300, 300, (20000, 2))))


def test_ground_texture_at_lattice_points_is_the_weighted_mean_of_the_octaves_table_values():
    """At multiples of the coarsest cell (8 m) every octave sits on a lattice point: no interpolation, the documented
    table entry ``[(j % 256) * 256 + i % 256]`` of each octave, mapped to [-1, 1] and weighted."""
    table, cells, weights = camera_module._TEXTURE
    lattice = np.random.default_rng(2).integers(-600, 600, size=(300, 2))
    expected = np.zeros(300)
    for octave in range(len(cells)):
        i, j = (lattice * (8.0 / cells[octave])).astype(int).T % 256
        expected += weights[octave] * (2 * table[octave, j * 256 + i] - 1)
    np.testing.assert_allclose(ground_texture(8.0 * lattice), expected / weights.sum(), rtol=1e-12, atol=1e-15)
    offsets = np.random.default_rng(3).uniform(-1e-7, 1e-7, size=(300, 2))  # continuous across cell borders
    np.testing.assert_allclose(ground_texture(8.0 * lattice + offsets), expected / weights.sum(), atol=1e-12)


def test_a_wall_straight_ahead_fills_the_columns_that_see_it_with_building_shading():
    sun_azimuth = math.radians(150.0)
    camera = Camera(tilt_rad=0.0, sun_azimuth_rad=sun_azimuth, **CLEAN)
    wall = Box((10.0, -2.0, 0.0), (11.0, 2.0, 4.0))
    image = camera.capture(flat_terrain().with_obstacles(boxes=[wall]), [0.0, 0.0, 0.0], np.random.default_rng(0))
    azimuth, _ = camera.pixel_angles()
    row = camera.rows // 2  # just below the horizon, sees ground only beyond max range
    edge = math.atan2(2.0, 10.0)
    inside, outside = np.abs(azimuth) < edge - 0.01, np.abs(azimuth) > edge + 0.01
    assert inside.sum() > 50 and outside.sum() > 90
    expected = lambert(camera, camera.building_albedo, (-1.0, 0.0, 0.0))
    assert expected == pytest.approx(
        camera.exposure
        * camera.building_albedo
        * (camera.ambient + (1 - camera.ambient) * -math.cos(camera.sun_elevation_rad) * math.cos(sun_azimuth))
    )
    assert np.all(image[row, inside] == round(expected))
    assert np.all(image[row, outside] == round(camera.sky_level))


def test_a_low_box_shows_its_front_face_and_its_top_with_their_own_normals():
    camera = Camera(tilt_rad=math.radians(12.0), sun_azimuth_rad=math.radians(200.0), **CLEAN)
    block = Box((5.0, -3.0, 0.0), (8.0, 3.0, 1.0), material="rock")
    image = camera.capture(flat_terrain().with_obstacles(boxes=[block]), [0.0, 0.0, 0.0], np.random.default_rng(0))
    azimuth, elevation = camera.pixel_angles()
    column = np.argmin(np.abs(azimuth))
    slope = np.tan(elevation)  # from 2 m up: front face x = 5 for slope in [-0.4, -0.2], top for (-0.2, -0.125]
    front, top = (slope > -0.39) & (slope < -0.21), (slope > -0.19) & (slope < -0.135)
    assert front.sum() >= 5 and top.sum() >= 3
    assert np.all(image[front, column] == round(lambert(camera, camera.rock_albedo, (-1.0, 0.0, 0.0))))
    assert np.all(image[top, column] == round(lambert(camera, camera.rock_albedo, (0.0, 0.0, 1.0))))


def test_a_tree_trunk_is_shaded_with_its_radial_normal():
    center, radius = np.array([10.0, 0.0]), 1.0
    camera = Camera(tilt_rad=0.0, sun_azimuth_rad=math.radians(160.0), **CLEAN)
    tree = Cylinder(tuple(center), radius, 0.0, 6.0)
    image = camera.capture(flat_terrain().with_obstacles(cylinders=[tree]), [0.0, 0.0, 0.0], np.random.default_rng(0))
    azimuth, _ = camera.pixel_angles()
    seen = np.abs(np.sin(azimuth)) * 10.0 < radius - 0.05
    assert seen.sum() >= 6
    for column in np.flatnonzero(seen):
        direction = np.array([math.cos(azimuth[column]), math.sin(azimuth[column])])
        along = direction @ center
        hit = direction * (along - math.sqrt(radius**2 - (center @ center - along**2)))
        normal = np.append((hit - center) / radius, 0.0)
        expected = lambert(camera, camera.vegetation_albedo, normal)
        assert image[camera.rows // 2, column] == round(expected), column


def test_large_exposure_saturates_at_255_and_dark_noise_clips_at_0_without_wrapping():
    terrain = make_terrain(np.random.default_rng(5))
    bright = Camera(exposure=1e5, noise_std=0.0).capture(terrain, [0.0, 0.0, 0.0], np.random.default_rng(0))
    _, elevation = Camera().pixel_angles()
    assert np.all(bright == 255)  # every material has albedo * ambient > 0
    near_white = Camera(exposure=250.0, sky_luminance=1.0, noise_std=20.0)
    sky = near_white.capture(flat_terrain(), [0.0, 0.0, 0.0], np.random.default_rng(1))[elevation > 0]
    assert sky.min() > 150 and np.mean(sky == 255) == pytest.approx(0.40, abs=0.05)  # P(N(0,1) > 0.25)
    black = Camera(exposure=0.0, noise_std=10.0).capture(terrain, [0.0, 0.0, 0.0], np.random.default_rng(2))
    assert black.max() < 80 and np.mean(black == 0) == pytest.approx(0.52, abs=0.03)  # P(N(0,10) < 0.5)


def test_noise_standard_deviation_on_the_uniform_sky_matches_config():
    noise_std = 4.0
    camera = Camera(noise_std=noise_std, tilt_rad=-math.radians(15.0))
    image = camera.capture(flat_terrain(), [0.0, 0.0, 0.0], np.random.default_rng(3))
    sky = image[camera.pixel_angles()[1] > 0].astype(float)
    assert sky.size > 10000
    assert sky.mean() == pytest.approx(camera.sky_level, abs=0.2)
    assert sky.std() == pytest.approx(math.sqrt(noise_std**2 + 1 / 12), rel=0.03)  # rounding adds 1/12


@pytest.mark.parametrize("seed", [0, 1])
def test_histogram_entropy_of_camera_images_matches_scikit_image(seed):
    image = Camera().capture(make_terrain(np.random.default_rng(seed)), [0.0, 0.0, 0.3], np.random.default_rng(seed))
    assert histogram_entropy(image) == pytest.approx(shannon_entropy(image, base=np.e), rel=1e-12)
    assert histogram_entropy(image) > 2.0  # a textured, shaded scene, not a flat image


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("rows", 0),
        ("columns", 0),
        ("columns", 2.5),
        ("horizontal_fov_rad", 0.0),
        ("horizontal_fov_rad", math.pi),
        ("vertical_fov_rad", -0.1),
        ("mount_height_m", 0.0),
        ("max_range_m", math.inf),
        ("sun_elevation_rad", 0.0),
        ("ground_albedo", 1.5),
        ("building_albedo", -0.1),
        ("ambient", 1.2),
        ("ground_texture_contrast", 1.0),
        ("exposure", -1.0),
        ("noise_std", -0.5),
        ("sky_luminance", math.nan),
        ("tilt_rad", 1.4),
        ("pan_rad", math.inf),
    ],
)
def test_bad_config_raises_value_error_naming_the_key(key, value):
    with pytest.raises(ValueError, match=key):
        Camera(**{key: value})


def test_bad_capture_arguments_raise_value_error():
    camera = Camera()
    with pytest.raises(ValueError, match="vehicle_pose"):
        camera.capture(flat_terrain(), [0.0, 0.0], np.random.default_rng(0))
    with pytest.raises(ValueError, match="tilt_rad"):
        camera.capture(flat_terrain(), [0.0, 0.0, 0.0], np.random.default_rng(0), tilt_rad=1.5)
