"""Tests for infonav_gym.rendering."""

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import pickle
from dataclasses import dataclass

import numpy as np
import pytest
from scipy.stats import chi2

from infonav_gym.rendering import ROBOT_COLOURS, Renderer, RobotDrawing, SceneFrame, covariance_ellipse

pytest.importorskip("pygame")

CHI2_95 = chi2.ppf(0.95, 2)


@dataclass
class Disc:
    center: tuple[float, float]
    radius: float


def full_robot(**overrides) -> RobotDrawing:
    fields = {
        "true_pose": np.array([2.0, 8.0, 0.3]),
        "estimated_pose": np.array([2.2, 7.9, 0.25]),
        "pose_covariance": np.diag([0.2, 0.1, 0.01]),
        "true_path": np.array([[1.0, 9.0], [1.5, 8.5], [2.0, 8.0]]),
        "estimated_path": np.array([[1.1, 9.0], [1.6, 8.4], [2.2, 7.9]]),
    }
    fields.update(overrides)
    return RobotDrawing(**fields)


def full_frame(**overrides) -> SceneFrame:
    fields = {
        "bounds": (0.0, 0.0, 20.0, 10.0),
        "walls": [((0.0, 0.0), (20.0, 0.0)), ((20.0, 0.0), (20.0, 10.0))],
        "obstacles": [Disc((5.0, 5.0), 1.0)],
        "landmarks": np.array([[15.0, 8.0], [3.0, 2.0], [10.0, 1.0]]),
        "landmark_visible": np.array([True, False, True]),
        "robots": [full_robot()],
        "landmark_estimates": np.array([[15.2, 7.9], [3.1, 2.2], [9.8, 1.1]]),
        "landmark_covariances": np.stack([np.eye(2) * 0.1] * 3),
        "caption": "step 3",
    }
    fields.update(overrides)
    return SceneFrame(**fields)


def pixel(image, renderer, frame, point) -> tuple[int, int, int]:
    col, row = renderer.world_to_screen(frame.bounds, point)
    return tuple(int(channel) for channel in image[row, col])


def test_ellipse_of_axis_aligned_covariance_has_closed_form_extremes():
    outline = covariance_ellipse(np.diag([4.0, 1.0]), 0.95, n_points=48)
    assert outline.shape == (48, 2)
    assert np.max(np.abs(outline[:, 0])) == pytest.approx(2.0 * np.sqrt(CHI2_95), abs=1e-6)
    assert np.max(np.abs(outline[:, 1])) == pytest.approx(np.sqrt(CHI2_95), abs=1e-6)


def test_ellipse_of_rotated_covariance_lies_on_the_chi2_contour():
    angle = 0.7
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    covariance = rotation @ np.diag([3.0, 0.5]) @ rotation.T
    outline = covariance_ellipse(covariance)
    mahalanobis = np.einsum("ni,ij,nj->n", outline, np.linalg.inv(covariance), outline)
    np.testing.assert_allclose(mahalanobis, CHI2_95, rtol=0, atol=1e-9)


def test_ellipse_of_singular_covariance_collapses_to_a_segment():
    outline = covariance_ellipse(np.array([[1.0, 0.0], [0.0, -1e-15]]))
    np.testing.assert_allclose(outline[:, 1], 0.0, atol=1e-12)
    assert np.max(outline[:, 0]) == pytest.approx(np.sqrt(CHI2_95))


@pytest.mark.parametrize(
    ("covariance", "message"),
    [(np.eye(3), "2x2"), (np.array([[1.0, np.nan], [np.nan, 1.0]]), "NaN"), (np.eye(2), "confidence")],
)
def test_ellipse_rejects_bad_input(covariance, message):
    confidence = 1.5 if message == "confidence" else 0.95
    with pytest.raises(ValueError, match=message):
        covariance_ellipse(covariance, confidence)


def test_rgb_array_shape_dtype_and_aspect_ratio():
    renderer = Renderer("rgb_array", 300)
    image = renderer.draw(SceneFrame(bounds=(-20.0, 0.0, 20.0, 10.0)))
    assert image.dtype == np.uint8
    assert image.flags["C_CONTIGUOUS"]
    height, width, channels = image.shape
    assert channels == 3
    assert max(height, width) == 300 == width
    margin = 2 * Renderer.MARGIN_PX
    assert (width - margin) / (height - margin) == pytest.approx(4.0, rel=0.02)


def test_tall_world_keeps_longer_side_vertical():
    image = Renderer("rgb_array", 200).draw(SceneFrame(bounds=(0.0, 0.0, 1.0, 1000.0)))
    height, width, _ = image.shape
    assert height == 200
    assert width == 1 + 2 * Renderer.MARGIN_PX


def test_empty_frame_is_uniform_white():
    image = Renderer("rgb_array", 120).draw(SceneFrame(bounds=(0.0, 0.0, 5.0, 5.0)))
    assert np.all(image == 255)


def test_world_to_screen_maps_corners_and_flips_y():
    renderer = Renderer("rgb_array", 220)
    bounds = (0.0, 0.0, 20.0, 10.0)
    margin = Renderer.MARGIN_PX
    assert renderer.world_to_screen(bounds, (0.0, 10.0)) == (margin, margin)
    assert renderer.world_to_screen(bounds, (20.0, 0.0)) == (220 - margin, 120 - margin)
    assert renderer.world_to_screen(bounds, (10.0, 2.0)) == (110, 90)


def test_chosen_landmark_changes_pixels_and_is_red():
    renderer = Renderer("rgb_array", 300)
    frame = full_frame()
    plain = renderer.draw(frame)
    chosen = renderer.draw(full_frame(chosen_landmark=0))
    assert not np.array_equal(plain, chosen)
    col, row = renderer.world_to_screen(frame.bounds, frame.landmarks[0])
    red, green, blue = (int(channel) for channel in chosen[row, col])
    assert red > 180 and green < 80 and blue < 80
    red, green, blue = (int(channel) for channel in plain[row, col])
    assert green > red


def test_full_frame_draws_robot_in_black_and_invisible_landmark_in_grey():
    renderer = Renderer("rgb_array", 300)
    frame = full_frame(robots=[full_robot(estimated_pose=None, pose_covariance=None)], landmark_estimates=None)
    image = renderer.draw(frame)
    col, row = renderer.world_to_screen(frame.bounds, frame.robots[0].true_pose[:2])
    assert np.all(image[row, col] == 0)
    col, row = renderer.world_to_screen(frame.bounds, frame.landmarks[1])
    assert np.all(image[row, col] > 180) and np.all(image[row, col] < 255)


def test_chosen_landmark_line_starts_at_robot_0():
    renderer = Renderer("rgb_array", 300)
    robot_0 = full_robot(true_pose=np.array([3.0, 8.0, 0.0]), estimated_pose=None, true_path=None)
    robot_1 = full_robot(true_pose=np.array([17.0, 2.0, 0.0]), estimated_pose=None, true_path=None)
    frame = full_frame(robots=[robot_0, robot_1], chosen_landmark=0, landmark_estimates=None)
    image = renderer.draw(frame)
    assert pixel(image, renderer, frame, (9.0, 8.0)) == (220, 30, 30), "on the line from robot 0 to landmark 0"


def test_several_robots_are_each_drawn_in_their_colour():
    renderer = Renderer("rgb_array", 300)
    positions = [(3.0, 5.0), (8.0, 5.0), (13.0, 5.0), (18.0, 5.0)]
    robots = [RobotDrawing(estimated_pose=np.array([x, y, 0.5]), pose_covariance=np.eye(2) * 0.1) for x, y in positions]
    robots.append(RobotDrawing(true_pose=np.array([10.0, 8.0, 0.0])))
    frame = SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0), robots=robots)
    image = renderer.draw(frame)
    for index, position in enumerate(positions):
        assert pixel(image, renderer, frame, position) == ROBOT_COLOURS[index]
    assert pixel(image, renderer, frame, (10.0, 8.0)) == (0, 0, 0), "truth is black whatever the robot"
    assert len(set(ROBOT_COLOURS)) == len(ROBOT_COLOURS) and ROBOT_COLOURS[0] == (30, 90, 220)


def test_an_observation_is_a_line_between_the_two_robots_true_positions():
    renderer = Renderer("rgb_array", 300)
    robots = [RobotDrawing(true_pose=np.array([3.0, 5.0, 0.0])), RobotDrawing(true_pose=np.array([17.0, 5.0, 0.0]))]
    frame = SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0), robots=robots)
    observed = SceneFrame(bounds=frame.bounds, robots=robots, observations=[(1, 0)])
    midpoint = (10.0, 5.0)
    assert pixel(renderer.draw(frame), renderer, frame, midpoint) == (255, 255, 255)
    assert pixel(renderer.draw(observed), renderer, frame, midpoint) == ROBOT_COLOURS[1], "in the observer's colour"


def test_a_gps_denied_zone_is_filled_lightly_under_the_obstacles():
    renderer = Renderer("rgb_array", 300)
    frame = SceneFrame(
        bounds=(0.0, 0.0, 20.0, 10.0), obstacles=[Disc((10.0, 5.0), 0.5)], gps_denied_zones=[Disc((10.0, 5.0), 3.0)]
    )
    image = renderer.draw(frame)
    zone = pixel(image, renderer, frame, (12.0, 5.0))
    assert zone != (255, 255, 255) and min(zone) > 200, "a light fill"
    assert zone[1] >= max(zone[0], zone[2]), "green like a canopy"
    assert pixel(image, renderer, frame, (10.0, 5.0)) == (70, 70, 70), "the obstacle is drawn over the zone"
    assert pixel(image, renderer, frame, (14.0, 5.0)) == (255, 255, 255)


def test_a_robot_label_is_drawn_next_to_it():
    pygame = pytest.importorskip("pygame")
    pygame.font.init()
    if not pygame.font.get_init():
        pytest.skip("pygame has no fonts here")
    renderer = Renderer("rgb_array", 300)
    robot = RobotDrawing(true_pose=np.array([10.0, 5.0, 0.0]))
    plain = renderer.draw(SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0), robots=[robot]))
    labelled = renderer.draw(
        SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0), robots=[RobotDrawing(robot.true_pose, label="3")])
    )
    changed_rows, changed_cols = np.nonzero(np.any(plain != labelled, axis=2))
    col, row = renderer.world_to_screen((0.0, 0.0, 20.0, 10.0), (10.0, 5.0))
    assert changed_rows.size and np.all(changed_cols > col) and np.all(changed_rows < row)


def test_caption_draws_text_in_top_left():
    renderer = Renderer("rgb_array", 200)
    image = renderer.draw(SceneFrame(bounds=(0.0, 0.0, 5.0, 5.0), caption="hello"))
    assert np.any(image[:20, :60] < 128)
    assert np.all(image[100:] == 255)


def test_human_mode_returns_none_and_close_is_idempotent():
    renderer = Renderer("human", 200, fps=1000)
    assert renderer.draw(full_frame(chosen_landmark=2)) is None
    assert renderer.draw(full_frame()) is None
    renderer.close()
    renderer.close()


def test_close_without_drawing_and_pickle_round_trip():
    renderer = Renderer("rgb_array", 150)
    renderer.draw(full_frame())
    clone = pickle.loads(pickle.dumps(renderer))
    np.testing.assert_array_equal(clone.draw(full_frame()), renderer.draw(full_frame()))
    Renderer("human").close()


def test_invalid_mode_names_valid_modes():
    with pytest.raises(ValueError, match="'ansi'.*rgb_array, human"):
        Renderer("ansi")


def test_degenerate_bounds_rejected():
    with pytest.raises(ValueError, match="bounds"):
        Renderer("rgb_array").draw(SceneFrame(bounds=(0.0, 0.0, 0.0, 5.0)))


def test_a_missing_optional_extra_names_the_install_command(monkeypatch):
    import builtins

    from infonav_gym.rendering import require_extra

    real_import = builtins.__import__

    def without_pygame(name, *args, **kwargs):
        if name == "pygame":
            raise ImportError("No module named 'pygame'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", without_pygame)
    with pytest.raises(ImportError, match=r"rendering needs pygame: pip install 'infonav-gym\[render\]'"):
        require_extra("pygame", "rendering")
