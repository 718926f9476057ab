"""Tests for infonav_gym.rendering and infonav_gym.scene (what a frame shows, the bounded paths)."""

import os
import subprocess
import sys

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import pickle
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from infonav_gym.rendering import (
    LANDMARK_LABEL_COLOUR,
    MIN_ELLIPSE_RADIUS_PX,
    ROBOT_COLOURS,
    LegendEntry,
    Renderer,
    legend_entries,
)
from infonav_gym.scene import N_SIGMA, PathHistory, RobotDrawing, SceneFrame, covariance_ellipse

pytest.importorskip("pygame")


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
    col, row = renderer.world_to_screen(frame, point)
    return tuple(int(channel) for channel in image[row, col])


def test_ellipse_of_axis_aligned_covariance_reaches_three_sigma_on_each_axis():
    outline = covariance_ellipse(np.diag([4.0, 1.0]), n_points=48)
    assert outline.shape == (48, 2)
    assert N_SIGMA == 3.0
    assert np.max(np.abs(outline[:, 0])) == pytest.approx(3.0 * 2.0, abs=1e-12)
    assert np.max(np.abs(outline[:, 1])) == pytest.approx(3.0 * 1.0, abs=1e-12)


def test_ellipse_of_rotated_covariance_lies_on_the_n_sigma_contour():
    angle = 0.7
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    covariance = rotation @ np.diag([3.0, 0.5]) @ rotation.T
    outline = covariance_ellipse(covariance, n_sigma=2.0)
    mahalanobis = np.einsum("ni,ij,nj->n", outline, np.linalg.inv(covariance), outline)
    np.testing.assert_allclose(mahalanobis, 2.0**2, rtol=0, atol=1e-9)


def test_ellipse_of_singular_covariance_collapses_to_a_segment():
    outline = covariance_ellipse(np.array([[1.0, 0.0], [0.0, -1e-15]]))
    np.testing.assert_allclose(outline[:, 1], 0.0, atol=1e-12)
    assert np.max(outline[:, 0]) == pytest.approx(3.0)


def test_ellipse_semi_axes_are_at_least_min_radius():
    outline = covariance_ellipse(np.diag([1e-10, 4.0]), min_radius=0.5, n_points=48)
    assert np.max(np.abs(outline[:, 0])) == pytest.approx(0.5)
    assert np.max(np.abs(outline[:, 1])) == pytest.approx(6.0), "an axis longer than min_radius is kept"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"covariance_2x2": np.eye(3)}, "2x2"),
        ({"covariance_2x2": np.array([[1.0, np.nan], [np.nan, 1.0]])}, "NaN"),
        ({"covariance_2x2": np.eye(2), "n_sigma": 0.0}, "n_sigma must be positive and finite, got 0.0"),
        ({"covariance_2x2": np.eye(2), "n_sigma": np.inf}, "n_sigma must be positive and finite, got inf"),
        ({"covariance_2x2": np.eye(2), "min_radius": -1.0}, "min_radius must be >= 0, got -1.0"),
        ({"covariance_2x2": np.eye(2), "n_points": 2}, "n_points must be at least 3, got 2"),
    ],
)
def test_ellipse_rejects_bad_input(kwargs, message):
    with pytest.raises(ValueError, match=message):
        covariance_ellipse(**kwargs)


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
    frame = SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0))
    margin = Renderer.MARGIN_PX
    assert renderer.world_to_screen(frame, (0.0, 10.0)) == (margin, margin)
    assert renderer.world_to_screen(frame, (20.0, 0.0)) == (220 - margin, 120 - margin)
    assert renderer.world_to_screen(frame, (10.0, 2.0)) == (110, 90)


def test_chosen_landmark_changes_pixels_and_is_red():
    renderer = Renderer("rgb_array", 300)
    frame = full_frame()
    plain = renderer.draw(frame)
    chosen = renderer.draw(full_frame(chosen_landmark=0))
    assert not np.array_equal(plain, chosen)
    col, row = renderer.world_to_screen(frame, frame.landmarks[0])
    red, green, blue = (int(channel) for channel in chosen[row, col])
    assert red > 180 and green < 80 and blue < 80
    red, green, blue = (int(channel) for channel in plain[row, col])
    assert green > red


def test_full_frame_draws_robot_in_black_and_invisible_landmark_in_grey():
    renderer = Renderer("rgb_array", 300)
    frame = full_frame(robots=[full_robot(estimated_pose=None, pose_covariance=None)], landmark_estimates=None)
    image = renderer.draw(frame)
    col, row = renderer.world_to_screen(frame, frame.robots[0].true_pose[:2])
    assert np.all(image[row, col] == 0)
    col, row = renderer.world_to_screen(frame, frame.landmarks[1])
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


def test_a_landmark_observation_is_a_line_from_the_observer_to_the_landmark_marked_red():
    renderer = Renderer("rgb_array", 300)
    robots = [RobotDrawing(true_pose=np.array([3.0, 5.0, 0.0])), RobotDrawing(true_pose=np.array([3.0, 2.0, 0.0]))]
    landmarks = np.array([[17.0, 5.0]])
    frame = SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0), robots=robots, landmarks=landmarks)
    observed = SceneFrame(bounds=frame.bounds, robots=robots, landmarks=landmarks, landmark_observations=[(1, 0)])
    midpoint = (10.0, 3.5)
    assert pixel(renderer.draw(frame), renderer, frame, midpoint) == (255, 255, 255)
    image = renderer.draw(observed)
    assert pixel(image, renderer, frame, midpoint) == ROBOT_COLOURS[1], "in the observer's colour"
    assert pixel(image, renderer, frame, (17.0, 5.0)) == (220, 30, 30), "the observed landmark is red"
    texts = [entry.text for entry in legend_entries(observed)]
    assert "landmark observation (observer's colour)" in texts and "landmark observed now" in texts


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
    col, row = renderer.world_to_screen(SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0), robots=[robot]), (10.0, 5.0))
    assert changed_rows.size and np.all(changed_cols > col + MIN_ELLIPSE_RADIUS_PX), "right of the robot's ellipse"
    assert changed_cols.min() < col + 3 * MIN_ELLIPSE_RADIUS_PX and abs(changed_rows.mean() - row) < 5, "beside it"


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


# ----------------------------------------------------------------------------- pictures for people


def fonts_or_skip():
    pygame = pytest.importorskip("pygame")
    pygame.font.init()
    if not pygame.font.get_init():
        pytest.skip("pygame has no fonts here")


def farthest_pixel_of_colour(image, start, step, colour) -> int:
    """How many pixels from ``start`` (col, row) along ``step`` the last pixel of ``colour`` lies."""
    col, row = start
    farthest = 0
    for distance in range(1, max(image.shape[:2])):
        col_, row_ = col + distance * step[0], row + distance * step[1]
        if not (0 <= row_ < image.shape[0] and 0 <= col_ < image.shape[1]):
            break
        if tuple(int(channel) for channel in image[row_, col_]) == colour:
            farthest = distance
    return farthest


@pytest.mark.parametrize(("std_x_m", "std_y_m"), [(1.0, 0.5), (0.4, 1.2)])
def test_pose_ellipse_reaches_three_sigma_of_the_covariance_on_screen(std_x_m, std_y_m):
    renderer = Renderer("rgb_array", 400)
    robot = RobotDrawing(
        estimated_pose=np.array([10.0, 5.0, np.pi / 4]), pose_covariance=np.diag([std_x_m, std_y_m, 1.0]) ** 2
    )
    frame = SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0), robots=[robot])
    image = renderer.draw(frame)
    scale = renderer.layout(frame).scale
    center = renderer.world_to_screen(frame, (10.0, 5.0))
    right = farthest_pixel_of_colour(image, center, (1, 0), ROBOT_COLOURS[0])
    down = farthest_pixel_of_colour(image, center, (0, 1), ROBOT_COLOURS[0])
    assert right == pytest.approx(3.0 * std_x_m * scale, abs=2.0)
    assert down == pytest.approx(3.0 * std_y_m * scale, abs=2.0)


def test_a_tiny_covariance_is_drawn_at_the_minimum_size_outside_the_robot_marker():
    renderer = Renderer("rgb_array", 400)
    robot = RobotDrawing(estimated_pose=np.array([10.0, 5.0, np.pi / 2]), pose_covariance=np.eye(3) * 1e-12)
    frame = SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0), robots=[robot])
    image = renderer.draw(frame)
    center = renderer.world_to_screen(frame, (10.0, 5.0))
    for step in ((1, 0), (-1, 0), (0, 1)):  # the heading tick points up
        assert farthest_pixel_of_colour(image, center, step, ROBOT_COLOURS[0]) == pytest.approx(
            MIN_ELLIPSE_RADIUS_PX, abs=1
        )
    assert MIN_ELLIPSE_RADIUS_PX > 7 + 2, "larger than the estimate's ring, so it stays visible"


def test_the_team_frame_draws_every_robots_ellipse_around_its_estimate():
    renderer = Renderer("rgb_array", 400)
    positions = [(4.0, 3.0), (10.0, 7.0), (16.0, 3.0)]
    robots = [
        RobotDrawing(estimated_pose=np.array([x, y, np.pi / 2]), pose_covariance=np.eye(2) * 1e-6) for x, y in positions
    ]
    frame = SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0), robots=robots)
    image = renderer.draw(frame)
    for index, position in enumerate(positions):
        center = renderer.world_to_screen(frame, position)
        assert farthest_pixel_of_colour(image, center, (1, 0), ROBOT_COLOURS[index]) >= MIN_ELLIPSE_RADIUS_PX - 1


def test_the_legend_names_the_sigma_and_draws_each_kind_below_the_scene():
    renderer = Renderer("rgb_array", 600)
    frame = full_frame(chosen_landmark=0)
    texts = [entry.text for entry in legend_entries(frame)]
    assert "3\u03c3 position ellipse (min 12 px)" in texts
    assert {"true pose", "estimated pose", "landmark in sight, numbered #1-#3", "landmark out of sight"} <= set(texts)
    assert "landmark observed now" in texts and "obstacle" in texts
    assert "relative observation (observer's colour)" not in texts, "only what the frame draws"
    image = renderer.draw(frame)
    layout = renderer.layout(frame)
    assert layout.legend_rows and layout.legend_top >= layout.scene_clip[1] + layout.scene_clip[3]
    legend = image[layout.legend_top :]
    for colour in (ROBOT_COLOURS[0], (40, 160, 70), (205, 205, 205), (220, 30, 30), (0, 0, 0)):
        assert np.any(np.all(legend == colour, axis=2)), f"legend has no pixel of colour {colour}"


def test_an_unknown_legend_symbol_is_rejected():
    with pytest.raises(ValueError, match="legend symbol 'star' is not one of disc, ring"):
        LegendEntry("star", (0, 0, 0), "x")


def test_landmarks_are_numbered_from_one_next_to_each_landmark(monkeypatch):
    fonts_or_skip()
    drawn = []
    original = Renderer._draw_text

    def recording(self, pygame, surface, text, colour, corner, background=None):
        drawn.append((text, colour, tuple(corner)))
        original(self, pygame, surface, text, colour, corner, background)

    monkeypatch.setattr(Renderer, "_draw_text", recording)
    renderer = Renderer("rgb_array", 600)
    frame = full_frame()
    image = renderer.draw(frame)
    labels = {text: corner for text, colour, corner in drawn if colour == LANDMARK_LABEL_COLOUR}
    assert set(labels) == {"#1", "#2", "#3"}
    for index, landmark in enumerate(frame.landmarks):
        col, row = renderer.world_to_screen(frame, landmark)
        label_col, label_row = labels[f"#{index + 1}"]
        assert 0 < label_col - col < 15 and abs(label_row + renderer.layout(frame).line_px / 2 - row) <= 2
        patch = image[label_row : label_row + 12, label_col : label_col + 20]
        assert np.any(np.all(patch == LANDMARK_LABEL_COLOUR, axis=2)), f"label #{index + 1} is drawn"


def test_the_caption_sits_in_its_own_band_above_the_scene_and_wraps():
    fonts_or_skip()
    renderer = Renderer("rgb_array", 300)
    walls = [((0.0, 10.0), (20.0, 10.0))]
    caption = "t = 12.0 s   a caption long enough that it has to wrap onto a second line of the frame"
    frame = SceneFrame(bounds=(0.0, 0.0, 20.0, 10.0), walls=walls, caption=caption)
    image = renderer.draw(frame)
    layout = renderer.layout(frame)
    assert len(layout.caption_lines) == 2 and " ".join(layout.caption_lines) == caption
    band = image[: layout.scene_clip[1]]
    assert np.any(np.all(band == 0, axis=2)), "the caption is drawn in black in the band"
    top_wall_row = renderer.world_to_screen(frame, (10.0, 10.0))[1]
    assert top_wall_row - 1 > layout.scene_clip[1]
    assert np.all(image[top_wall_row, 40:260] == (70, 70, 70)), "the wall is not hidden by the caption"


@pytest.mark.parametrize("bounds", [(0.0, 0.0, 20.0, 20.0), (-3.0, -4.0, 41.0, 4.0), (0.0, 0.0, 2.0, 30.0)])
@pytest.mark.parametrize("size_px", [64, 240])
def test_a_frame_with_caption_and_legend_has_its_longer_side_at_size_px(bounds, size_px):
    renderer = Renderer("rgb_array", size_px)
    inset = np.zeros((32, 180), dtype=np.uint8)
    image = renderer.draw(full_frame(bounds=bounds, inset_image=inset, inset_title="frame"))
    assert image.dtype == np.uint8 and image.shape[2] == 3
    assert max(image.shape[:2]) == size_px
    assert image.shape[1] == size_px, "a caption or legend spans the whole width"


def test_a_small_frame_leaves_out_the_legend_that_does_not_fit():
    frame = full_frame(inset_image=np.zeros((32, 180), dtype=np.uint8))
    assert Renderer("rgb_array", 600).layout(frame).legend_rows
    small = Renderer("rgb_array", 64).layout(frame)
    assert small.legend_rows == () and small.height <= 64


def test_without_fonts_the_frame_keeps_its_layout_and_draws_no_text(monkeypatch):
    pygame = pytest.importorskip("pygame")

    def no_font(*args, **kwargs):
        raise pygame.error("font not initialized")

    monkeypatch.setattr(pygame.font, "Font", no_font)
    renderer = Renderer("rgb_array", 300)
    frame = full_frame(chosen_landmark=0)
    image = renderer.draw(frame)
    assert max(image.shape[:2]) == 300 and renderer.layout(frame).legend_rows
    assert not np.any(np.all(image == LANDMARK_LABEL_COLOUR, axis=2)), "no landmark numbers without fonts"
    assert pixel(image, renderer, frame, frame.landmarks[0]) == (220, 30, 30)


def test_the_inset_is_under_the_scene_and_outlines_the_highlighted_cells_in_red():
    renderer = Renderer("rgb_array", 600)
    image_32x180 = np.full((32, 180), 128, dtype=np.uint8)
    frame = full_frame(inset_image=image_32x180, inset_title="range image", inset_grid=(4, 9), inset_highlights=[10])
    image = renderer.draw(frame)
    layout = renderer.layout(frame)
    left, top, width, height = layout.inset
    assert top >= layout.scene_clip[1] + layout.scene_clip[3], "below the scene, hiding nothing of it"
    assert abs(width - (600 - 2 * Renderer.MARGIN_PX)) <= 1, "as wide as the frame"
    assert width / height == pytest.approx(180 / 32, rel=0.01), "the image's aspect ratio"
    cell_w, cell_h = width / 9, height / 4
    row, col = divmod(10, 9)
    highlighted_left = left + round(col * cell_w)
    middle_row = top + round((row + 0.5) * cell_h)
    assert tuple(int(channel) for channel in image[middle_row, highlighted_left + 1]) == (220, 30, 30)
    plain_left = left + round(5 * cell_w)
    assert tuple(int(channel) for channel in image[middle_row, plain_left + 2]) == (128, 128, 128)
    assert layout.legend_top >= top + height


def test_a_long_inset_title_wraps_above_the_inset():
    renderer = Renderer("rgb_array", 300)
    title = "newest LADAR range image (dark = near, white = no return); red: patches picked for ICP"
    frame = full_frame(inset_image=np.zeros((32, 180), dtype=np.uint8), inset_title=title)
    layout = renderer.layout(frame)
    assert len(layout.inset_title_lines) >= 2 and " ".join(layout.inset_title_lines) == title
    title_top = layout.inset[1] - len(layout.inset_title_lines) * layout.line_px
    assert title_top >= layout.scene_clip[1] + layout.scene_clip[3], "below the scene"


def test_pygame_is_imported_only_when_an_env_renders():
    code = (
        "import sys, gymnasium as gym, infonav_gym\n"
        "env = gym.make('infonav/LandmarkSelection-v0', render_mode='rgb_array')\n"
        "env.reset(seed=0)\n"
        "for _ in range(5): env.step(0)\n"
        "assert 'pygame' not in sys.modules, 'pygame imported before render'\n"
        "assert 'infonav_gym.rendering' not in sys.modules\n"
        "env.render()\n"
        "assert 'pygame' in sys.modules\n"
    )
    environment = {**os.environ, "SDL_VIDEODRIVER": "dummy", "PYTHONPATH": os.pathsep.join(sys.path)}
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=environment)
    assert result.returncode == 0, result.stderr


# ----------------------------------------------------------------------------- bounded paths


def test_a_path_history_keeps_every_point_until_it_is_full():
    path = PathHistory([0.0, 0.0], max_points=8)
    for step in range(1, 8):
        path.append([step, -step])
    np.testing.assert_array_equal(path.points(), np.stack([np.arange(8), -np.arange(8)], axis=1))
    assert len(path) == 8


def test_a_path_history_stays_bounded_and_keeps_the_whole_path_shape():
    path = PathHistory([0.0, 0.0], max_points=8)
    for step in range(1, 10_001):
        path.append([float(step), 0.0])
        assert len(path) <= 9
    points = path.points()
    assert len(points) == len(path)
    assert points[0, 0] == 0.0 and points[-1, 0] == 10_000.0, "the first and the latest point are kept"
    gaps = np.diff(points[:-1, 0])
    assert np.all(gaps == gaps[0]) and gaps[0] >= 10_000 / 8 / 2, "evenly spaced over the whole path"


def test_a_path_history_copies_the_points_it_is_given():
    pose = np.array([1.0, 2.0])
    path = PathHistory(pose, max_points=4)
    pose[0] = 99.0
    path.append(pose)
    pose[0] = -1.0
    np.testing.assert_array_equal(path.points(), [[1.0, 2.0], [99.0, 2.0]])


@pytest.mark.parametrize("max_points", [1, 2.5, "8"])
def test_a_path_history_rejects_a_bad_bound(max_points):
    with pytest.raises(ValueError, match="PathHistory max_points must be an int >= 2"):
        PathHistory([0.0, 0.0], max_points=max_points)


SINGLE_AGENT_IDS = (
    "infonav/LandmarkSelection-v0",
    "infonav/ActiveLocalization-v0",
    "infonav/SensorSelection-v0",
    "infonav/RangeRegistration-v0",
)


def drawn_paths(env) -> list:
    """Copy 0's drawn paths, the true one first: in a scenario's state, or (not yet a scenario) the env's own."""
    state = getattr(env, "state", None)
    if state is not None:
        return list(state.paths)
    return [env._true_path] + ([env._estimated_path] if hasattr(env, "_estimated_path") else [])


@pytest.mark.parametrize("env_id", SINGLE_AGENT_IDS)
def test_an_env_keeps_its_drawn_paths_bounded_over_many_more_steps_than_the_bound(env_id, monkeypatch):
    import gymnasium as gym

    import infonav_gym  # noqa: F401

    monkeypatch.setattr(PathHistory, "MAX_POINTS", 4)
    single = gym.make(env_id, horizon=40, render_mode="rgb_array").unwrapped
    env = getattr(single, "vector", single)  # an env written once keeps its paths in its one copy
    _, info = single.reset(seed=0)
    start = drawn_paths(env)[0].points()[0].copy()
    steps = 0
    for _ in range(40):
        action = int(np.argmax(info["action_mask"]))  # the first valid action, else 0 (a no-op)
        _, _, terminated, truncated, info = single.step(action)
        steps += 1
        assert all(len(path) <= 5 for path in drawn_paths(env))
        if terminated or truncated:
            break
    assert steps > 10, "many more steps than the bound"
    np.testing.assert_array_equal(drawn_paths(env)[0].points()[0], start)
    frame = single.render()
    assert frame.dtype == np.uint8
    single.close()


def test_the_team_env_keeps_every_robots_paths_bounded(monkeypatch):
    from infonav_gym.multi import cooperative_localization_v0

    monkeypatch.setattr(PathHistory, "MAX_POINTS", 4)
    env = cooperative_localization_v0.parallel_env(max_cycles=40, render_mode="rgb_array")
    env.reset(seed=0)
    while env.agents:
        env.step({name: 0 for name in env.agents})
        paths = env.vector.state.paths
        assert all(len(path) <= 5 for path in paths.true_paths + paths.estimated_paths)
    np.testing.assert_array_equal(paths.true_paths[0].points()[-1], env.vector.true_poses[0, 0, :2])
    assert env.render().dtype == np.uint8
    env.close()


def test_the_frames_script_writes_a_png_and_a_gif_of_every_registered_env(tmp_path):
    from PIL import Image

    from infonav_gym.experiments.render_episode import frame_stem
    from infonav_gym.registry import registered_envs

    script = Path(__file__).resolve().parents[1] / "scripts" / "render_frames.py"
    environment = {**os.environ, "SDL_VIDEODRIVER": "dummy", "PYTHONPATH": os.pathsep.join(sys.path)}
    result = subprocess.run(
        [sys.executable, str(script), "--output-dir", str(tmp_path)], capture_output=True, text=True, env=environment
    )
    assert result.returncode == 0, result.stderr
    stems = sorted(frame_stem(entry.id) for entry in registered_envs())
    assert sorted(path.name for path in tmp_path.iterdir()) == sorted(
        f"{s}{x}" for s in stems for x in (".gif", ".png")
    )
    with Image.open(tmp_path / "LandmarkSelection.png") as corridor:
        assert corridor.size[0] == 900 and corridor.mode == "RGB"
    with Image.open(tmp_path / "cooperative_localization_v0.png") as team:
        assert max(team.size) == 600
    with Image.open(tmp_path / "cooperative_exploration_v0.gif") as episode:  # the reset and every 2nd of 40 steps
        assert episode.n_frames == 21 and max(episode.size) == 400
