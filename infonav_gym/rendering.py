"""Pygame drawing of a 2D world for the ``rgb_array`` and ``human`` render modes.

Envs describe what to draw in a :class:`SceneFrame`; :class:`Renderer` draws it.
pygame is an optional extra, so it is imported only when a ``Renderer`` is built.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

RENDER_MODES = ("rgb_array", "human")


def require_extra(module: str, purpose: str) -> None:
    """Import ``module`` or raise an ``ImportError`` that says how to install the ``[render]`` extra."""
    try:
        __import__(module)
    except ImportError as error:
        raise ImportError(f"{purpose} needs {module}: pip install 'infonav-gym[render]'") from error


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
_LANDMARK_PX = 5
_ROBOT_PX = 7
_TICK_PX = 14
_LABEL_OFFSET_PX = (9, -18)


@dataclass
class RobotDrawing:
    """One robot to draw: truth in black, its estimate in its own colour, positions in metres."""

    true_pose: np.ndarray | None = None
    estimated_pose: np.ndarray | None = None
    pose_covariance: np.ndarray | None = None  # (3, 3) or (2, 2); the x-y block is drawn as a 95% ellipse
    true_path: np.ndarray | None = None
    estimated_path: np.ndarray | None = None
    label: str = ""  # drawn next to the robot if fonts are available

    @classmethod
    def tracked(cls, true_pose, ekf, true_path, estimated_path) -> RobotDrawing:
        """A robot tracked by a ``PoseEKF``: its truth, the filter's pose and covariance, and both paths (lists)."""
        return cls(
            true_pose=true_pose,
            estimated_pose=ekf.pose,
            pose_covariance=ekf.pose_covariance,
            true_path=np.array(true_path),
            estimated_path=np.array(estimated_path),
        )


@dataclass
class SceneFrame:
    """Everything to draw for one frame; positions in metres, headings in radians.

    ``observations`` are ``(observer, target)`` pairs of robot indices, drawn as a line
    between their true positions; ``gps_denied_zones`` are circles (``center``,
    ``radius``) filled lightly under everything else. The chosen landmark's line starts
    at ``robots[0]``'s true pose. ``sensor_wedge`` is a field of view from ``robots[0]``'s
    true position: ``(world azimuth of its axis, full width [rad], length [m])``;
    ``inset_image`` a gray uint8 image (e.g. the frame a sensor just acquired) drawn in the
    bottom-left corner.
    """

    bounds: tuple[float, float, float, float]
    walls: Sequence[tuple[tuple[float, float], tuple[float, float]]] = ()
    obstacles: Sequence = ()
    landmarks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    landmark_visible: np.ndarray | None = None
    chosen_landmark: int | None = None
    robots: Sequence[RobotDrawing] = ()
    landmark_estimates: np.ndarray | None = None
    landmark_covariances: np.ndarray | None = None
    observations: Sequence[tuple[int, int]] = ()
    gps_denied_zones: Sequence = ()
    sensor_wedge: tuple[float, float, float] | None = None
    inset_image: np.ndarray | None = None
    caption: str = ""


def covariance_ellipse(covariance_2x2, confidence: float = 0.95, n_points: int = 48) -> np.ndarray:
    """Return the (n_points, 2) outline offsets of a covariance's confidence ellipse.

    The first point lies along the smallest principal axis (angle 0), so a
    multiple of 4 points hits both axis extremes.

    Raises:
        ValueError: for a non-finite or non-2x2 matrix, ``confidence`` outside
            (0, 1) or fewer than 3 points.
    """
    covariance = np.asarray(covariance_2x2, dtype=float)
    if covariance.shape != (2, 2):
        raise ValueError(f"covariance must be 2x2, got shape {covariance.shape}")
    if not np.all(np.isfinite(covariance)):
        raise ValueError("covariance contains NaN or infinite entries")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    if n_points < 3:
        raise ValueError(f"n_points must be at least 3, got {n_points}")
    eigenvalues, eigenvectors = np.linalg.eigh(0.5 * (covariance + covariance.T))
    radii = np.sqrt(np.clip(eigenvalues, 0.0, None) * chi2.ppf(confidence, 2))
    angles = np.linspace(0.0, 2.0 * np.pi, n_points, endpoint=False)
    circle = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    return (circle * radii) @ eigenvectors.T


class Renderer:
    """Draws :class:`SceneFrame` objects to an RGB array or a pygame window."""

    MARGIN_PX = 10

    def __init__(self, render_mode: str, size_px: int = 600, fps: int = 10):
        if render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode {render_mode!r} is not supported; valid modes: {', '.join(RENDER_MODES)}")
        if size_px <= 2 * self.MARGIN_PX:
            raise ValueError(f"size_px must exceed {2 * self.MARGIN_PX}, got {size_px}")
        if fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        require_extra("pygame", "rendering")
        self.render_mode = render_mode
        self.size_px = int(size_px)
        self.fps = int(fps)
        self._window = None
        self._clock = None
        self._font = None

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_window": None, "_clock": None, "_font": None}

    def _layout(self, bounds) -> tuple[float, int, int]:
        x_min, y_min, x_max, y_max = (float(value) for value in bounds)
        if not (np.isfinite([x_min, y_min, x_max, y_max]).all() and x_max > x_min and y_max > y_min):
            raise ValueError(f"bounds must be finite (x_min, y_min, x_max, y_max) with max > min, got {bounds}")
        scale = (self.size_px - 2 * self.MARGIN_PX) / max(x_max - x_min, y_max - y_min)
        width = max(1, round((x_max - x_min) * scale)) + 2 * self.MARGIN_PX
        height = max(1, round((y_max - y_min) * scale)) + 2 * self.MARGIN_PX
        return scale, width, height

    def _to_screen(self, bounds, points) -> np.ndarray:
        scale = self._layout(bounds)[0]
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        cols = self.MARGIN_PX + (points[:, 0] - bounds[0]) * scale
        rows = self.MARGIN_PX + (bounds[3] - points[:, 1]) * scale
        return np.rint(np.stack([cols, rows], axis=1)).astype(int)

    def world_to_screen(self, frame_bounds, point) -> tuple[int, int]:
        """Return the (col, row) pixel of a world point; rows grow downwards."""
        col, row = self._to_screen(frame_bounds, point)[0]
        return int(col), int(row)

    def draw(self, frame: SceneFrame) -> np.ndarray | None:
        """Draw ``frame``; return an (H, W, 3) uint8 array in rgb_array mode, else None."""
        import pygame

        scale, width, height = self._layout(frame.bounds)
        surface = pygame.Surface((width, height))
        surface.fill(_WHITE)
        self._draw_scene(pygame, surface, frame, scale)
        if self.render_mode == "rgb_array":
            return np.ascontiguousarray(pygame.surfarray.array3d(surface).transpose(1, 0, 2))
        if self._window is None or self._window.get_size() != (width, height):
            pygame.display.init()
            self._window = pygame.display.set_mode((width, height))
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
        self._window = None
        self._clock = None

    def _draw_scene(self, pygame, surface, frame: SceneFrame, scale: float) -> None:
        def screen(points):
            return self._to_screen(frame.bounds, points)

        def ellipse(center, covariance, colour):
            covariance = np.asarray(covariance, dtype=float)
            if covariance.shape == (3, 3):
                covariance = covariance[:2, :2]
            outline = np.asarray(center, dtype=float)[:2] + covariance_ellipse(covariance)
            pygame.draw.lines(surface, colour, True, screen(outline).tolist(), 1)

        def robot(pose, colour, filled):
            center = screen(pose[:2])[0]
            tip = center + _TICK_PX * np.array([np.cos(pose[2]), -np.sin(pose[2])])
            pygame.draw.circle(surface, colour, center.tolist(), _ROBOT_PX, 0 if filled else 2)
            pygame.draw.line(surface, colour, center.tolist(), np.rint(tip).tolist(), 2)

        def disc(circle, colour):
            pygame.draw.circle(surface, colour, screen(circle.center)[0].tolist(), max(1, round(circle.radius * scale)))

        def robot_colour(index):
            return ROBOT_COLOURS[index % len(ROBOT_COLOURS)]

        for zone in frame.gps_denied_zones:
            disc(zone, _CANOPY_GREEN)
        for start, end in frame.walls:
            pygame.draw.line(surface, _DARK_GREY, *screen([start, end]).tolist(), 3)
        for obstacle in frame.obstacles:
            disc(obstacle, _DARK_GREY)
        for index, drawing in enumerate(frame.robots):
            for path, colour in ((drawing.true_path, _PATH_GREY), (drawing.estimated_path, robot_colour(index))):
                if path is not None and len(path) >= 2:
                    pygame.draw.lines(surface, colour, False, screen(path).tolist(), 1)
        if frame.landmark_estimates is not None:
            for index, (col, row) in enumerate(screen(frame.landmark_estimates).tolist()):
                for slope in (-4, 4):
                    pygame.draw.line(surface, _ORANGE, (col - 4, row - slope), (col + 4, row + slope), 2)
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
        for observer, target in frame.observations:
            ends = [frame.robots[observer].true_pose, frame.robots[target].true_pose]
            if ends[0] is not None and ends[1] is not None:
                pygame.draw.line(surface, robot_colour(observer), *screen([end[:2] for end in ends]).tolist(), 1)
        for index, drawing in enumerate(frame.robots):
            if drawing.estimated_pose is not None:
                if drawing.pose_covariance is not None:
                    ellipse(drawing.estimated_pose, drawing.pose_covariance, robot_colour(index))
                robot(drawing.estimated_pose, robot_colour(index), filled=False)
        for drawing in frame.robots:
            if drawing.true_pose is not None:
                robot(drawing.true_pose, _BLACK, filled=True)
        for index, drawing in enumerate(frame.robots):
            anchor = drawing.true_pose if drawing.true_pose is not None else drawing.estimated_pose
            if drawing.label and anchor is not None:
                corner = screen(anchor[:2])[0] + _LABEL_OFFSET_PX
                self._draw_text(pygame, surface, drawing.label, robot_colour(index), corner.tolist())
        if frame.sensor_wedge is not None and frame.robots and frame.robots[0].true_pose is not None:
            axis, width, length = frame.sensor_wedge
            angles = axis + np.linspace(-width / 2, width / 2, 16)
            apex = np.asarray(frame.robots[0].true_pose[:2], dtype=float)
            arc = apex + length * np.stack([np.cos(angles), np.sin(angles)], axis=1)
            pygame.draw.lines(surface, _RED, True, screen(np.vstack([apex, arc])).tolist(), 2)
        if frame.inset_image is not None:
            self._draw_inset(pygame, surface, frame.inset_image)
        if frame.caption:
            self._draw_text(pygame, surface, frame.caption, _BLACK, (4, 2), background=_WHITE)

    def _draw_inset(self, pygame, surface, image: np.ndarray) -> None:
        """Blit the gray uint8 ``image``, framed, in the bottom-left corner at a third of the surface width."""
        rows, columns = image.shape
        width = max(1, surface.get_width() // 3)
        height = max(1, round(width * rows / columns))
        rgb = np.repeat(np.asarray(image, dtype=np.uint8).T[:, :, None], 3, axis=2)
        inset = pygame.transform.scale(pygame.surfarray.make_surface(rgb), (width, height))
        corner = (self.MARGIN_PX, surface.get_height() - height - self.MARGIN_PX)
        surface.blit(inset, corner)
        pygame.draw.rect(surface, _BLACK, (*corner, width, height), 1)

    def _draw_text(self, pygame, surface, text: str, colour, corner, background=None) -> None:
        """Blit ``text`` with its top-left at pixel ``corner``; nothing if pygame has no fonts."""
        if self._font is None:
            try:
                pygame.font.init()
                self._font = pygame.font.Font(None, 18)
            except (ImportError, NotImplementedError, OSError, pygame.error):
                self._font = False
        if self._font:
            surface.blit(self._font.render(text, True, colour, background), corner)
