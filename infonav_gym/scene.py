"""What a rendered frame shows, in metres and radians: :class:`SceneFrame` and what it holds.

Envs describe a frame here and ``infonav_gym.rendering`` draws it. Numpy only, so an env
keeps its :class:`PathHistory` on every step without importing pygame.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

N_SIGMA = 3.0  # pose and landmark ellipses: semi-axes of N_SIGMA standard deviations
SENSOR_WEDGE_LENGTH_M = 12.0  # drawn length of a sensor's field of view [m]


class PathHistory:
    """The points of a path in bounded memory: at most ``max_points`` evenly spaced ones (the stride doubles each
    time they fill), plus the first and the latest."""

    MAX_POINTS = 1024  # per path; an env's default horizon never reaches it

    def __init__(self, first_point, max_points: int | None = None):
        self.max_points = self.MAX_POINTS if max_points is None else max_points
        if not isinstance(self.max_points, int) or self.max_points < 2:
            raise ValueError(f"PathHistory max_points must be an int >= 2, got {self.max_points!r}")
        first = np.array(first_point, dtype=float)
        self._kept = np.empty((self.max_points + 1, first.size))  # a fixed buffer: appending allocates nothing
        self._kept[0] = first
        self._latest = first.copy()
        self._n_kept, self._stride, self._appended = 1, 1, 0  # _appended: points appended after the first

    def append(self, point) -> None:
        """Add the next point of the path (copied)."""
        self._appended += 1
        if self._appended % self._stride:
            self._latest[:] = point
            return
        self._kept[self._n_kept] = point
        self._n_kept += 1
        if self._n_kept > self.max_points:
            halved = self._kept[: self._n_kept : 2].copy()
            self._n_kept = len(halved)
            self._kept[: self._n_kept] = halved
            self._stride *= 2

    def __len__(self) -> int:
        return self._n_kept + (self._appended % self._stride != 0)

    def points(self) -> np.ndarray:
        """The kept points in order, ending with the latest: shape ``(len(self), dimensions)``."""
        kept = self._kept[: self._n_kept]
        if self._appended % self._stride == 0:
            return kept.copy()
        return np.vstack([kept, self._latest])


def extended_paths(paths, points, restarted: bool) -> tuple[PathHistory, ...]:
    """``paths`` with each of ``points`` appended, or new paths from them (``restarted``, or no paths yet)."""
    if restarted or paths is None:
        return tuple(PathHistory(point) for point in points)
    for path, point in zip(paths, points):
        path.append(point)
    return paths


@dataclass
class RobotDrawing:
    """One robot to draw: truth in black, its estimate in its own colour, positions in metres."""

    true_pose: np.ndarray | None = None
    estimated_pose: np.ndarray | None = None
    pose_covariance: np.ndarray | None = None  # (3, 3) or (2, 2); the x-y block is drawn as an N_SIGMA ellipse
    true_path: np.ndarray | None = None
    estimated_path: np.ndarray | None = None
    label: str = ""  # drawn next to the robot if fonts are available


@dataclass
class SceneFrame:
    """Everything to draw for one frame; positions in metres, headings in radians."""

    bounds: tuple[float, float, float, float]
    walls: Sequence[tuple[tuple[float, float], tuple[float, float]]] = ()
    obstacles: Sequence = ()
    landmarks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # landmark k labelled #k (Fig. 1)
    landmark_visible: np.ndarray | None = None
    chosen_landmark: int | None = None  # its line starts at robots[0]'s true pose
    robots: Sequence[RobotDrawing] = ()
    landmark_estimates: np.ndarray | None = None
    landmark_covariances: np.ndarray | None = None
    landmark_estimate_label: str = "landmark estimate"  # what the legend calls them (e.g. "map feature")
    observations: Sequence[tuple[int, int]] = ()  # (observer, target) robots: a line between their true positions
    landmark_observations: Sequence[tuple[int, int]] = ()  # (observer, landmark): a line, the landmark marked
    gps_denied_zones: Sequence = ()  # circles (center, radius) filled lightly under everything
    sensor_wedge: tuple[float, float, float] | None = None  # from robots[0]: axis azimuth, width [rad], length [m]
    goal: tuple[float, float] | None = None  # a target circle of goal_radius_m (at least a robot's size)
    goal_radius_m: float = 0.0
    inset_image: np.ndarray | None = None  # gray uint8 (e.g. the acquired frame), under the scene
    inset_title: str = ""
    inset_grid: tuple[int, int] | None = None  # (rows, columns) cells; those in inset_highlights outlined red
    inset_highlights: Sequence[int] = ()
    caption: str = ""


def covariance_ellipse(
    covariance_2x2, n_sigma: float = N_SIGMA, n_points: int = 48, min_radius: float = 0.0
) -> np.ndarray:
    """The (n_points, 2) outline offsets of a covariance's ``n_sigma`` ellipse, semi-axes at least ``min_radius``;
    the first point along the smallest principal axis. ``ValueError`` for a bad matrix or argument."""
    covariance = np.asarray(covariance_2x2, dtype=float)
    if covariance.shape != (2, 2):
        raise ValueError(f"covariance must be 2x2, got shape {covariance.shape}")
    if not np.all(np.isfinite(covariance)):
        raise ValueError("covariance contains NaN or infinite entries")
    if not (np.isfinite(n_sigma) and n_sigma > 0.0):
        raise ValueError(f"n_sigma must be positive and finite, got {n_sigma}")
    if not min_radius >= 0.0:
        raise ValueError(f"min_radius must be >= 0, got {min_radius}")
    if n_points < 3:
        raise ValueError(f"n_points must be at least 3, got {n_points}")
    eigenvalues, eigenvectors = np.linalg.eigh(0.5 * (covariance + covariance.T))
    radii = np.maximum(n_sigma * np.sqrt(np.clip(eigenvalues, 0.0, None)), min_radius)
    angles = np.linspace(0.0, 2.0 * np.pi, n_points, endpoint=False)
    return (np.stack([np.cos(angles), np.sin(angles)], axis=1) * radii) @ eigenvectors.T
