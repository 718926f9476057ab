"""Pygame drawing of a :class:`~infonav_gym.scene.SceneFrame` for the ``rgb_array`` and ``human`` render modes.

Ellipses are drawn at ``N_SIGMA`` standard deviations, at least ``MIN_ELLIPSE_RADIUS_PX``. pygame (an optional
extra) is imported only when a ``Renderer`` is built.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from infonav_gym.scene import N_SIGMA, SceneFrame, covariance_ellipse

RENDER_MODES = ("rgb_array", "human")
MIN_ELLIPSE_RADIUS_PX = 12  # no ellipse semi-axis is drawn shorter, so small covariances stay visible


def require_extra(module: str, purpose: str) -> None:
    """Import ``module`` or raise an ``ImportError`` that says how to install the ``[render]`` extra."""
    try:
        __import__(module)
    except ImportError as error:
        raise ImportError(f"{purpose} needs {module}: pip install 'infonav-gym[render]'") from error


def matplotlib_figure(purpose: str, **kwargs):
    """A matplotlib ``Figure(**kwargs)`` for ``purpose``: no pyplot, so it renders with Agg and leaves the caller's
    backend alone; without matplotlib, ``require_extra``'s ``ImportError``."""
    require_extra("matplotlib", purpose)
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def save_figure(figure, path, dpi: int, **savefig_kwargs) -> Path:
    """Write ``figure`` (``savefig``) to ``path``, its directory created if missing; return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=dpi, **savefig_kwargs)
    return path


_WHITE = (255, 255, 255)
_DARK_GREY = (70, 70, 70)
_LIGHT_GREY = (205, 205, 205)
_PATH_GREY = (160, 160, 160)
_GREEN = (40, 160, 70)
_RED = (220, 30, 30)
_BLACK = (0, 0, 0)
_BLUE = (30, 90, 220)
_ORANGE = (240, 140, 0)
_CANOPY_GREEN = (222, 238, 214)
ROBOT_COLOURS = (_BLUE, (200, 40, 160), (0, 150, 160), (140, 90, 30), (110, 60, 200))  # robot i: ROBOT_COLOURS[i % 5]
LANDMARK_LABEL_COLOUR = (20, 90, 40)  # the "#k" next to landmark k (index k - 1), as in the paper's Fig. 1
_LANDMARK_PX = 5
_ROBOT_PX = 7
_TICK_PX = 14
_LABEL_GAP_PX = 8  # from a landmark's centre to its label
_ROBOT_CLEARANCE_PX = MIN_ELLIPSE_RADIUS_PX + 2  # labels keep off this square around a robot and its ellipse
_LABEL_STEP_PX = 6  # a label that does not fit is tried this much farther away, up to _LABEL_REACH_PX
_LABEL_REACH_PX = 200
_LABEL_DIRECTIONS = ((1, 0), (1, -1), (1, 1), (-1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1))  # tried in this order
_SCALE_BAR_PX = 60  # the legend's scale bar is at most about this long
_FONT_SIZE = 20
_FALLBACK_LINE_PX = 15  # text line height when pygame has no fonts
_FALLBACK_CHAR_PX = 8  # ... and the width of one character
_PAD_PX = 4
_SYMBOL_PX = (24, 14)  # width, height of a legend symbol
_ENTRY_GAP_PX = 14  # between legend entries
_MAX_INSET_FRACTION = 0.25  # the inset image is at most this fraction of the frame's longer side tall
_MAX_PANEL_FRACTION = 0.5  # caption, inset and legend together take at most this fraction of it
LEGEND_SYMBOLS = ("disc", "ring", "ellipse", "line", "cross", "zone", "wedge", "target", "scale")


@dataclass(frozen=True)
class LegendEntry:
    """A legend item: a ``LEGEND_SYMBOLS`` symbol in ``colour``, ``symbol_px`` wide (``scale``: ``length_m``), text."""

    symbol: str
    colour: tuple[int, int, int]
    text: str
    symbol_px: int = _SYMBOL_PX[0]
    length_m: float = 0.0

    def __post_init__(self):
        if self.symbol not in LEGEND_SYMBOLS:
            raise ValueError(f"legend symbol {self.symbol!r} is not one of {', '.join(LEGEND_SYMBOLS)}")


@dataclass(frozen=True)
class FrameLayout:
    """Where the parts of a frame go, in pixels (column, row) from the top-left corner."""

    scale: float  # [px / m]
    width: int
    height: int
    scene_corner: tuple[int, int]  # the pixel of the bounds' top-left corner (x_min, y_max)
    field: tuple[int, int, int, int]  # left, top, width, height: the bounds, where discs are clipped
    scene_clip: tuple[int, int, int, int]  # left, top, width, height: the scene and its margin, where labels go
    caption_lines: tuple[str, ...]
    inset: tuple[int, int, int, int] | None  # left, top, width, height of the inset image
    inset_title_lines: tuple[str, ...]  # drawn right above the inset image
    legend_rows: tuple[tuple[LegendEntry, ...], ...]
    legend_top: int
    line_px: int


def _robot_colour(index: int) -> tuple[int, int, int]:
    return ROBOT_COLOURS[index % len(ROBOT_COLOURS)]


def legend_entries(frame: SceneFrame, *, possible: bool = False) -> list[LegendEntry]:
    """The legend of ``frame``: one entry per kind of thing it draws, in drawing order. With ``possible``, also the
    kinds that come and go in its scene (paths, observations, landmarks in and out of sight): the rows a frame
    reserves, so that every frame of an episode has the same size."""
    robots = list(frame.robots)
    estimated = [index for index, robot in enumerate(robots) if robot.estimated_pose is not None]
    colour = _robot_colour(estimated[0] if estimated else 0)
    per_robot = " (colour per robot)" if len(estimated) > 1 else ""
    visible = np.ones(len(frame.landmarks), bool) if frame.landmark_visible is None else frame.landmark_visible
    visible = np.asarray(visible, dtype=bool)
    has_landmarks, team = len(visible) > 0, len(robots) > 1
    numbers = "#1" if len(visible) == 1 else f"#1-#{len(visible)}"
    ellipse = f"{N_SIGMA:g}\u03c3 position ellipse (min {MIN_ELLIPSE_RADIUS_PX} px)"
    sight_varies = has_landmarks and frame.landmark_visible is not None  # landmarks may go out of sight
    observing = frame.chosen_landmark is not None or bool(frame.landmark_observations)
    candidates = [  # (drawn in this frame, may be drawn in its scene, symbol, colour, text)
        (any(robot.true_pose is not None for robot in robots), False, "disc", _BLACK, "true pose"),
        (bool(estimated), False, "ring", colour, "estimated pose" + per_robot),
        (any(robots[index].pose_covariance is not None for index in estimated), False, "ellipse", colour, ellipse),
        (any(_has_path(robot.true_path) for robot in robots), bool(robots), "line", _PATH_GREY, "true path"),
        (any(_has_path(robot.estimated_path) for robot in robots), bool(estimated), "line", colour, "estimated path"),
        (bool(visible.any()), has_landmarks, "disc", _GREEN, f"landmark in sight, numbered {numbers}"),
        (not visible.all(), sight_varies, "disc", _LIGHT_GREY, "landmark out of sight"),
        (observing, has_landmarks, "disc", _RED, "landmark observed now"),
        (
            frame.landmark_estimates is not None,
            False,
            "cross",
            _ORANGE,
            f"{frame.landmark_estimate_label}, {N_SIGMA:g}\u03c3",
        ),
        *(
            (bool(pairs), may_show, "line", _first_observer_colour(pairs), f"{kind} observation (observer's colour)")
            for kind, pairs, may_show in (
                ("relative", frame.observations, team),
                ("landmark", frame.landmark_observations, team and has_landmarks),
            )
        ),
        (bool(frame.walls), False, "line", _DARK_GREY, "wall"),
        (bool(frame.obstacles), False, "disc", _DARK_GREY, "obstacle"),
        (bool(frame.gps_denied_zones), False, "zone", _CANOPY_GREEN, "GPS denied"),
        (frame.sensor_wedge is not None, False, "wedge", _RED, "sensor field of view"),
        (frame.goal is not None, False, "target", _BLACK, "goal"),
    ]
    return [
        LegendEntry(symbol, colour, text)
        for shown, may_show, symbol, colour, text in candidates
        if shown or (possible and may_show)
    ]


def scale_bar_m(longest_m: float) -> float:
    """The longest of 1, 2 or 5 times a power of ten metres that is at most ``longest_m``."""
    power = 10.0 ** math.floor(math.log10(longest_m))
    return max(step * power for step in (1, 2, 5) if step * power <= longest_m)


def overlap(box, other) -> bool:
    """Whether two (left, top, width, height) boxes share an area (touching edges do not)."""
    (left, top, width, height), (other_left, other_top, other_width, other_height) = box, other
    horizontal = left < other_left + other_width and other_left < left + width
    return horizontal and top < other_top + other_height and other_top < top + height


def place_label(anchor, size, taken: list, area) -> tuple[int, int, int, int] | None:
    """The box (left, top, width, height) of a label of ``size`` (width, height) nearest ``anchor`` (col, row):
    ``_LABEL_DIRECTIONS`` tried at growing distances, the first inside ``area`` that overlaps no box of ``taken``;
    ``None`` if none does within ``_LABEL_REACH_PX``."""
    width, height = size
    for distance in range(_LABEL_GAP_PX, _LABEL_REACH_PX, _LABEL_STEP_PX):
        for dx, dy in _LABEL_DIRECTIONS:
            left = anchor[0] + dx * distance - (width if dx < 0 else width // 2 if dx == 0 else 0)
            top = anchor[1] + dy * distance - (height if dy < 0 else height // 2 if dy == 0 else 0)
            box = (int(left), int(top), width, height)
            inside = area[0] <= box[0] and box[0] + width <= area[0] + area[2] and area[1] <= box[1]
            if inside and box[1] + height <= area[1] + area[3] and not any(overlap(box, other) for other in taken):
                return box
    return None


def _first_observer_colour(pairs) -> tuple[int, int, int]:
    """The colour of the first ``(observer, ...)`` pair's observer (robot 0's if there is none)."""
    return _robot_colour(pairs[0][0] if pairs else 0)


def _has_path(path) -> bool:
    return path is not None and len(path) >= 2


def _draw_cross(pygame, surface, colour, center) -> None:
    """An X, 9 px across, at pixel ``center`` (col, row): a landmark estimate."""
    for slope in (-4, 4):
        pygame.draw.line(surface, colour, (center[0] - 4, center[1] - slope), (center[0] + 4, center[1] + slope), 2)


def _draw_target(pygame, surface, colour, center, radius_px: int) -> None:
    """A ring of ``radius_px`` around pixel ``center`` (col, row), crossed by its two diameters: the goal."""
    pygame.draw.circle(surface, colour, center, radius_px, 2)
    for dx, dy in ((radius_px, 0), (0, radius_px)):
        pygame.draw.line(surface, colour, (center[0] - dx, center[1] - dy), (center[0] + dx, center[1] + dy), 1)


class Renderer:
    """Draws :class:`SceneFrame` objects to an RGB array or a pygame window, the longer side ``size_px``: caption on
    top, the scene, then the inset and the legend (at most half of ``size_px`` with the caption, else no legend)."""

    MARGIN_PX = 10

    def __init__(self, render_mode: str, size_px: int = 600, fps: int = 10):
        if render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode {render_mode!r} is not supported; valid modes: {', '.join(RENDER_MODES)}")
        if size_px <= 2 * self.MARGIN_PX:
            raise ValueError(f"size_px must exceed {2 * self.MARGIN_PX}, got {size_px}")
        if fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        require_extra("pygame", "rendering")
        self.render_mode, self.size_px, self.fps = render_mode, int(size_px), int(fps)
        self._window = self._clock = self._font = None
        self.text_boxes: list[tuple[str, tuple[int, int, int, int]]] = []  # the last frame's texts and their boxes

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_window": None, "_clock": None, "_font": None}

    def layout(self, frame: SceneFrame) -> FrameLayout:
        """Where ``frame``'s caption, scene, inset and legend go; ``ValueError`` for bad bounds."""
        x_min, y_min, x_max, y_max = (float(value) for value in frame.bounds)
        if not (np.isfinite([x_min, y_min, x_max, y_max]).all() and x_max > x_min and y_max > y_min):
            raise ValueError(f"bounds must be finite (x_min, y_min, x_max, y_max) with max > min, got {frame.bounds}")
        margin, inner, line = self.MARGIN_PX, self.size_px - 2 * self.MARGIN_PX, self._line_px()
        budget = int(self.size_px * _MAX_PANEL_FRACTION)
        caption_lines = tuple(self._wrap(frame.caption, inner))[: max(0, (budget - _PAD_PX) // line)]
        caption_px = _PAD_PX + line * len(caption_lines) if caption_lines else 0
        inset_block, inset_size, title_lines = 0, None, ()
        if frame.inset_image is not None:
            title_lines = tuple(self._wrap(frame.inset_title, inner))
            available = budget - caption_px - line * len(title_lines) - _PAD_PX
            inset_size = self._inset_size(np.shape(frame.inset_image), inner, available)
            inset_block = line * len(title_lines) + inset_size[1] + _PAD_PX if inset_size else 0
        widest_scale = min(inner / (x_max - x_min), inner / (y_max - y_min))  # [px / m]
        bar_m = scale_bar_m(_SCALE_BAR_PX / widest_scale)
        bar_px = max(_SYMBOL_PX[0], math.ceil(bar_m * widest_scale))
        scale_bar = LegendEntry("scale", _BLACK, f"{bar_m:g} m", bar_px, bar_m)
        entries, reserved = legend_entries(frame), legend_entries(frame, possible=True)
        legend_rows = self._legend_rows([*entries, scale_bar] if entries else [], inner)  # an empty scene: no legend
        reserved_rows = self._legend_rows([*reserved, scale_bar] if reserved else [], inner)
        legend_px = max(len(legend_rows), len(reserved_rows)) * line + _PAD_PX if reserved_rows else 0
        if caption_px + inset_block + legend_px > budget:
            legend_rows, legend_px = (), 0
        scale = min(inner / (x_max - x_min), (inner - caption_px - inset_block - legend_px) / (y_max - y_min))
        scene_w, scene_h = max(1, round((x_max - x_min) * scale)), max(1, round((y_max - y_min) * scale))
        content_w = max(scene_w, inner) if caption_px or inset_block or legend_px else scene_w
        panel_top = caption_px + scene_h + 2 * margin
        inset = (margin, panel_top + line * len(title_lines), *inset_size) if inset_size else None
        scene_corner = (margin + (content_w - scene_w) // 2, caption_px + margin)
        return FrameLayout(
            scale=scale,
            width=content_w + 2 * margin,
            height=panel_top + inset_block + legend_px,
            scene_corner=scene_corner,
            field=(*scene_corner, scene_w, scene_h),
            scene_clip=(0, caption_px, content_w + 2 * margin, scene_h + 2 * margin),
            caption_lines=caption_lines,
            inset=inset,
            inset_title_lines=title_lines if inset else (),
            legend_rows=legend_rows,
            legend_top=panel_top + inset_block,
            line_px=line,
        )

    def _inset_size(self, image_shape, width_px: int, available_px: int) -> tuple[int, int] | None:
        """The drawn (width, height) of an image at most ``width_px`` wide and ``available_px`` tall, aspect kept."""
        rows, columns = image_shape
        height = min(round(width_px * rows / columns), int(self.size_px * _MAX_INSET_FRACTION), available_px)
        return (max(1, min(width_px, round(height * columns / rows))), height) if height >= 1 else None

    def world_to_screen(self, frame: SceneFrame, point) -> tuple[int, int]:
        """Return the (col, row) pixel of a world point of ``frame``; rows grow downwards."""
        col, row = self._to_screen(self.layout(frame), frame.bounds, point)[0]
        return int(col), int(row)

    @staticmethod
    def _to_screen(layout: FrameLayout, bounds, points) -> np.ndarray:
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        cols = layout.scene_corner[0] + (points[:, 0] - bounds[0]) * layout.scale
        rows = layout.scene_corner[1] + (bounds[3] - points[:, 1]) * layout.scale
        return np.rint(np.stack([cols, rows], axis=1)).astype(int)

    def draw(self, frame: SceneFrame) -> np.ndarray | None:
        """Draw ``frame``; return an (H, W, 3) uint8 array in rgb_array mode, else None."""
        import pygame

        layout = self.layout(frame)
        self.text_boxes = []
        surface = pygame.Surface((layout.width, layout.height))
        surface.fill(_WHITE)
        surface.set_clip(pygame.Rect(layout.scene_clip))
        self._draw_scene(pygame, surface, frame, layout)
        surface.set_clip(None)
        for index, text in enumerate(layout.caption_lines):
            self._draw_text(pygame, surface, text, _BLACK, (self.MARGIN_PX, _PAD_PX + index * layout.line_px))
        if layout.inset is not None:
            self._draw_inset(pygame, surface, frame, layout)
        self._draw_legend(pygame, surface, layout)
        if self.render_mode == "rgb_array":
            return np.ascontiguousarray(pygame.surfarray.array3d(surface).transpose(1, 0, 2))
        if self._window is None or self._window.get_size() != (layout.width, layout.height):
            pygame.display.init()
            self._window = pygame.display.set_mode((layout.width, layout.height))
            pygame.display.set_caption("infonav-gym")
            self._clock = pygame.time.Clock()
        self._window.blit(surface, (0, 0))
        pygame.event.pump()
        pygame.display.flip()
        self._clock.tick(self.fps)
        return None

    def close(self) -> None:
        """Close the window if one was opened; safe to call repeatedly."""
        if self._window is not None:
            import pygame

            pygame.display.quit()
        self._window = self._clock = None

    def _draw_scene(self, pygame, surface, frame: SceneFrame, layout: FrameLayout) -> None:
        scale = layout.scale

        def screen(points):
            return self._to_screen(layout, frame.bounds, points)

        def ellipse(center, covariance, colour):
            covariance = np.asarray(covariance, dtype=float)[:2, :2]
            offsets = covariance_ellipse(covariance, N_SIGMA, min_radius=MIN_ELLIPSE_RADIUS_PX / scale)
            pygame.draw.lines(surface, colour, True, screen(np.asarray(center, dtype=float)[:2] + offsets).tolist(), 2)

        def robot(pose, colour, filled):
            center = screen(pose[:2])[0]
            tip = center + _TICK_PX * np.array([np.cos(pose[2]), -np.sin(pose[2])])
            pygame.draw.circle(surface, colour, center.tolist(), _ROBOT_PX, 0 if filled else 2)
            pygame.draw.line(surface, colour, center.tolist(), np.rint(tip).tolist(), 2)

        surface.set_clip(pygame.Rect(layout.field))
        for circle, colour in [
            *((zone, _CANOPY_GREEN) for zone in frame.gps_denied_zones),
            *((obstacle, _DARK_GREY) for obstacle in frame.obstacles),
        ]:
            pygame.draw.circle(surface, colour, screen(circle.center)[0].tolist(), max(1, round(circle.radius * scale)))
        surface.set_clip(pygame.Rect(layout.scene_clip))
        for start, end in frame.walls:
            pygame.draw.line(surface, _DARK_GREY, *screen([start, end]).tolist(), 3)
        if frame.goal is not None:
            goal_px = max(_ROBOT_PX, round(frame.goal_radius_m * scale))
            _draw_target(pygame, surface, _BLACK, screen(frame.goal)[0].tolist(), goal_px)
        for index, drawing in enumerate(frame.robots):
            for path, colour in ((drawing.true_path, _PATH_GREY), (drawing.estimated_path, _robot_colour(index))):
                if _has_path(path):
                    pygame.draw.lines(surface, colour, False, screen(path).tolist(), 1)
        if frame.landmark_estimates is not None:
            for index, center in enumerate(screen(frame.landmark_estimates).tolist()):
                _draw_cross(pygame, surface, _ORANGE, center)
                if frame.landmark_covariances is not None:
                    ellipse(frame.landmark_estimates[index], frame.landmark_covariances[index], _ORANGE)
        landmarks = screen(frame.landmarks).tolist()
        for index, point in enumerate(landmarks):
            visible = frame.landmark_visible is None or bool(frame.landmark_visible[index])
            pygame.draw.circle(surface, _GREEN if visible else _LIGHT_GREY, point, _LANDMARK_PX)
        if frame.chosen_landmark is not None:
            chosen = landmarks[frame.chosen_landmark]
            if frame.robots and frame.robots[0].true_pose is not None:
                pygame.draw.line(surface, _RED, screen(frame.robots[0].true_pose[:2])[0].tolist(), chosen, 2)
            pygame.draw.circle(surface, _RED, chosen, _LANDMARK_PX + 2)
        for observer, landmark in frame.landmark_observations:
            observer_pose = frame.robots[observer].true_pose
            if observer_pose is not None:
                start = screen(observer_pose[:2])[0].tolist()
                pygame.draw.line(surface, _robot_colour(observer), start, landmarks[landmark], 1)
            pygame.draw.circle(surface, _RED, landmarks[landmark], _LANDMARK_PX + 2)
        for observer, target in frame.observations:
            ends = [frame.robots[observer].true_pose, frame.robots[target].true_pose]
            if ends[0] is not None and ends[1] is not None:
                pygame.draw.line(surface, _robot_colour(observer), *screen([end[:2] for end in ends]).tolist(), 1)
        for index, drawing in enumerate(frame.robots):
            if drawing.estimated_pose is not None:
                if drawing.pose_covariance is not None:
                    ellipse(drawing.estimated_pose, drawing.pose_covariance, _robot_colour(index))
                robot(drawing.estimated_pose, _robot_colour(index), filled=False)
        for drawing in frame.robots:
            if drawing.true_pose is not None:
                robot(drawing.true_pose, _BLACK, filled=True)
        if frame.sensor_wedge is not None and frame.robots and frame.robots[0].true_pose is not None:
            axis, width, length = frame.sensor_wedge
            angles = axis + np.linspace(-width / 2, width / 2, 16)
            apex = np.asarray(frame.robots[0].true_pose[:2], dtype=float)
            arc = apex + length * np.stack([np.cos(angles), np.sin(angles)], axis=1)
            pygame.draw.lines(surface, _RED, True, screen(np.vstack([apex, arc])).tolist(), 2)
        self._draw_labels(pygame, surface, frame, layout, landmarks, screen)

    def _draw_labels(self, pygame, surface, frame: SceneFrame, layout: FrameLayout, landmarks, screen) -> None:
        """Landmark numbers, then robot labels, each where ``place_label`` finds room beside the landmarks, the
        robots and the labels before it; a label pushed away from its anchor gets a leader line."""
        font = self._text_font()
        if font is None:
            return
        labels = [(point, f"#{index + 1}", LANDMARK_LABEL_COLOUR) for index, point in enumerate(landmarks)]
        taken = [(col - _LANDMARK_PX, row - _LANDMARK_PX, 2 * _LANDMARK_PX, 2 * _LANDMARK_PX) for col, row in landmarks]
        for index, drawing in enumerate(frame.robots):
            poses = [pose for pose in (drawing.true_pose, drawing.estimated_pose) if pose is not None]
            for col, row in screen([pose[:2] for pose in poses]).tolist() if poses else []:
                taken.append((col - _ROBOT_CLEARANCE_PX, row - _ROBOT_CLEARANCE_PX, *(2 * _ROBOT_CLEARANCE_PX,) * 2))
            if drawing.label and poses:
                labels.append((screen(poses[0][:2])[0].tolist(), drawing.label, _robot_colour(index)))
        for anchor, text, colour in labels:
            box = place_label(anchor, font.size(text), taken, layout.scene_clip)
            if box is None:
                continue  # no room: the legend and the colours still tell the robots apart
            taken.append(box)
            nearest = np.clip(anchor, box[:2], (box[0] + box[2], box[1] + box[3]))
            if np.hypot(*(nearest - anchor)) > 2 * _LABEL_GAP_PX:
                pygame.draw.line(surface, colour, anchor, nearest.tolist(), 1)
            self._draw_text(pygame, surface, text, colour, box[:2], background=_WHITE)

    def _draw_inset(self, pygame, surface, frame: SceneFrame, layout: FrameLayout) -> None:
        """Blit the gray inset image, framed, with its title above it, its grid and its highlighted cells."""
        left, top, width, height = layout.inset
        for index, text in enumerate(layout.inset_title_lines):
            title_top = top - (len(layout.inset_title_lines) - index) * layout.line_px
            self._draw_text(pygame, surface, text, _BLACK, (left, title_top))
        rgb = np.repeat(np.asarray(frame.inset_image, dtype=np.uint8).T[:, :, None], 3, axis=2)
        surface.blit(pygame.transform.scale(pygame.surfarray.make_surface(rgb), (width, height)), (left, top))
        if frame.inset_grid is not None:
            rows, columns = frame.inset_grid
            row_edges = top + np.rint(np.arange(rows + 1) * height / rows).astype(int)
            col_edges = left + np.rint(np.arange(columns + 1) * width / columns).astype(int)
            for row in row_edges[1:-1]:
                pygame.draw.line(surface, _BLUE, (left, row), (left + width - 1, row), 1)
            for col in col_edges[1:-1]:
                pygame.draw.line(surface, _BLUE, (col, top), (col, top + height - 1), 1)
            for cell in frame.inset_highlights:
                row, col = divmod(int(cell), columns)
                cell_rect = (col_edges[col], row_edges[row], col_edges[col + 1] - col_edges[col] + 1)
                pygame.draw.rect(surface, _RED, (*cell_rect, row_edges[row + 1] - row_edges[row] + 1), 3)
        pygame.draw.rect(surface, _BLACK, (left, top, width, height), 1)

    def _draw_legend(self, pygame, surface, layout: FrameLayout) -> None:
        for row_index, entries in enumerate(layout.legend_rows):
            top = layout.legend_top + row_index * layout.line_px
            col = self.MARGIN_PX
            for entry in entries:
                box = pygame.Rect(col, top + (layout.line_px - _SYMBOL_PX[1]) // 2, entry.symbol_px, _SYMBOL_PX[1])
                if entry.symbol == "scale":
                    box.width = max(1, round(entry.length_m * layout.scale))  # at most symbol_px
                self._draw_symbol(pygame, surface, entry, box)
                self._draw_text(pygame, surface, entry.text, _BLACK, (col + entry.symbol_px + _PAD_PX, top))
                col += self._entry_width(entry) + _ENTRY_GAP_PX

    @staticmethod
    def _draw_symbol(pygame, surface, entry: LegendEntry, box) -> None:
        center, radius = box.center, box.height // 2 - 1
        if entry.symbol == "disc":
            pygame.draw.circle(surface, entry.colour, center, _LANDMARK_PX)
        elif entry.symbol == "ring":
            pygame.draw.circle(surface, entry.colour, center, radius, 2)
        elif entry.symbol == "ellipse":
            pygame.draw.ellipse(surface, entry.colour, box, 2)
        elif entry.symbol in ("line", "scale"):
            pygame.draw.line(surface, entry.colour, box.midleft, box.midright, 2)
            for end in (box.left, box.right - 1) if entry.symbol == "scale" else ():
                pygame.draw.line(surface, entry.colour, (end, box.top + 2), (end, box.bottom - 2), 2)
        elif entry.symbol == "cross":
            _draw_cross(pygame, surface, entry.colour, center)
        elif entry.symbol == "zone":
            pygame.draw.rect(surface, entry.colour, box)
        elif entry.symbol == "wedge":
            pygame.draw.polygon(surface, entry.colour, [box.midleft, box.topright, box.bottomright], 2)
        else:
            _draw_target(pygame, surface, entry.colour, center, radius)

    def _legend_rows(self, entries: list[LegendEntry], width_px: int) -> tuple[tuple[LegendEntry, ...], ...]:
        """``entries`` flowed left to right into rows at most ``width_px`` wide."""
        rows, row, used = [], [], 0
        for entry in entries:
            needed = self._entry_width(entry) + (_ENTRY_GAP_PX if row else 0)
            if row and used + needed > width_px:
                rows.append(tuple(row))
                row, used, needed = [], 0, self._entry_width(entry)
            row.append(entry)
            used += needed
        return tuple(rows + [tuple(row)]) if row else ()

    def _entry_width(self, entry: LegendEntry) -> int:
        return entry.symbol_px + _PAD_PX + self._text_width(entry.text)

    def _wrap(self, text: str, width_px: int) -> list[str]:
        """``text`` broken at spaces into lines at most ``width_px`` wide (a longer word gets a line of its own)."""
        lines = []
        for word in text.split(" "):
            candidate = f"{lines[-1]} {word}" if lines else word
            if lines and self._text_width(candidate) <= width_px:
                lines[-1] = candidate
            else:
                lines.append(word)
        return [line.strip() for line in lines if line.strip()]

    def _text_font(self):
        """The pygame font, or ``None`` if pygame has no fonts here (text is then left out)."""
        if self._font is None:
            import pygame

            try:
                pygame.font.init()
                self._font = pygame.font.Font(None, _FONT_SIZE)
            except (ImportError, NotImplementedError, OSError, pygame.error):
                self._font = False
        return self._font or None

    def _line_px(self) -> int:
        font = self._text_font()
        return font.get_linesize() if font else _FALLBACK_LINE_PX

    def _text_width(self, text: str) -> int:
        font = self._text_font()
        return font.size(text)[0] if font else _FALLBACK_CHAR_PX * len(text)

    def _draw_text(self, pygame, surface, text: str, colour, corner, background=None) -> None:
        """Blit ``text`` (on ``background``, if given) at top-left pixel ``corner``; nothing without fonts."""
        font = self._text_font()
        if font:
            surface.blit(font.render(text, True, colour, background), corner)
            self.text_boxes.append((text, (int(corner[0]), int(corner[1]), *font.size(text))))
