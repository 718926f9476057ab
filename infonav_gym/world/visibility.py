"""Batched visibility: which of K targets each of N robots sees (the queries compiled: ``visibility_kernels``).

``segments_clear`` repeats the floating-point operations of Chipmunk's segment queries (Pymunk's
``segment_query_first``, radius 0, static shapes only) in their order, so it agrees with
``ContactSpace.line_of_sight`` bit for bit, degenerate cases included (an origin inside or on a shape is
blocked; a target on a surface is visible; bounding-box culling unless the world has one static shape).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from infonav_gym.compiled import contiguous
from infonav_gym.world.physics import WORLD_ARGUMENTS
from infonav_gym.world.scenarios import Scenario
from infonav_gym.world.visibility_kernels import blocked, covered

if TYPE_CHECKING:
    from infonav_gym.sensors.range_bearing import RangeBearingSensor


def _read_only(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array


@dataclass(frozen=True)
class StaticGeometry:
    """The static walls (N, S) (ends [m], radius: half the thickness [m]) and discs (N, D) (centre, radius [m]) of
    N worlds, padded to the largest counts (``*_valid``: not padding)."""

    wall_starts: np.ndarray
    wall_ends: np.ndarray
    wall_radii: np.ndarray
    wall_valid: np.ndarray
    disc_centers: np.ndarray
    disc_radii: np.ndarray
    disc_valid: np.ndarray

    @classmethod
    def from_scenario(cls, scenario: Scenario, wall_thickness_m: float) -> StaticGeometry:
        """The static shapes ``ContactSpace`` builds of ``scenario`` (one copy); ``ValueError`` for bad ones."""
        return cls.from_scenarios([scenario], wall_thickness_m)

    @classmethod
    def from_scenarios(cls, scenarios: list, wall_thickness_m: float) -> StaticGeometry:
        """``stack`` of each of ``scenarios``' ``from_scenario`` (one copy each), built at once."""
        WORLD_ARGUMENTS["wall_thickness_m"].check("StaticGeometry.from_scenario", "wall_thickness_m", wall_thickness_m)
        try:
            walls = np.array([wall for scenario in scenarios for wall in scenario.walls], dtype=float).reshape(-1, 4)
            wall_counts = [len(scenario.walls) for scenario in scenarios]
        except (TypeError, ValueError):
            walls, wall_counts = np.full((1, 4), np.nan), []
        discs = np.array([(*o.center, o.radius) for s in scenarios for o in s.obstacles], dtype=float).reshape(-1, 3)
        walls_fine = np.isfinite(walls).all() and len(walls) == sum(wall_counts)
        if not (walls_fine and np.isfinite(discs).all() and (discs[:, 2] >= 0.0).all()):
            if len(scenarios) > 1:
                for scenario in scenarios:  # raises naming the first bad one
                    cls.from_scenario(scenario, wall_thickness_m)
            what, got = ("walls must be pairs ((x0, y0), (x1, y1)) of finite numbers [m]", scenarios[0].walls)
            if walls_fine:
                what, got = ("obstacles need a finite centre [m] and a finite radius >= 0 [m]", scenarios[0].obstacles)
            raise ValueError(f"scenario {scenarios[0].name!r}: {what}, got {got!r}")
        (points, wall_valid), disc_counts = _padded_rows(walls, wall_counts), [len(s.obstacles) for s in scenarios]
        (discs, disc_valid), radii = _padded_rows(discs, disc_counts), np.where(wall_valid, wall_thickness_m / 2, 0.0)
        shapes = points[..., :2], points[..., 2:], radii, wall_valid, discs[..., :2], discs[..., 2], disc_valid
        return cls(*(_read_only(np.ascontiguousarray(array)) for array in shapes))  # in the order of the fields

    def single(self, copy: int) -> StaticGeometry:
        """Copy ``copy`` alone (views, padded as all copies)."""
        return StaticGeometry(*(getattr(self, name)[copy : copy + 1] for name in self.__dataclass_fields__))

    @classmethod
    def stack(cls, geometries) -> StaticGeometry:
        """The copies of all ``geometries`` one after the other, padded; ``ValueError`` for none or another type."""
        geometries = list(geometries)
        if not geometries or not all(isinstance(geometry, StaticGeometry) for geometry in geometries):
            raise ValueError(f"StaticGeometry.stack needs one or more StaticGeometry, got {geometries!r}")
        return cls._padded(geometries, lambda name, count: np.concatenate([_pad(g, name, count) for g in geometries]))

    @classmethod
    def _padded(cls, geometries: list, make) -> StaticGeometry:
        """The geometry whose field ``name`` is ``make(name, count)``, count the largest of ``geometries``'."""
        walls = max(geometry.wall_radii.shape[1] for geometry in geometries)
        discs = max(geometry.disc_radii.shape[1] for geometry in geometries)
        fields = {name: make(name, discs if name.startswith("disc") else walls) for name in cls.__dataclass_fields__}
        return cls(**{name: _read_only(array) for name, array in fields.items()})

    def with_copies(self, copies, replacement: StaticGeometry) -> StaticGeometry:
        """This geometry with copies ``copies`` (n,) replaced by the n copies of ``replacement``, padded to fit."""
        copies = np.asarray(copies, dtype=int)
        if replacement.n_copies != len(copies):
            raise ValueError(
                f"StaticGeometry.with_copies: {len(copies)} copies to replace, but the replacement holds "
                f"{replacement.n_copies}"
            )

        def merged(name: str, count: int) -> np.ndarray:
            result = _pad(self, name, count)
            result[copies] = _pad(replacement, name, count)
            return result

        return self._padded([self, replacement], merged)

    def tiled(self, n_copies: int) -> StaticGeometry:
        """Copy 0 of this geometry ``n_copies`` times (read-only views: nothing is copied)."""
        first = {name: getattr(self, name)[:1] for name in self.__dataclass_fields__}
        return StaticGeometry(**{name: np.broadcast_to(a, (n_copies, *a.shape[1:])) for name, a in first.items()})

    def grown(self, margin_m: float) -> StaticGeometry:
        """These shapes grown by ``margin_m`` [m] >= 0: a disc of that radius swept along a line touches a shape
        where the line hits the grown one."""
        if not margin_m >= 0.0:
            raise ValueError(f"StaticGeometry.grown: margin_m must be >= 0 [m], got {margin_m}")
        if margin_m not in self._grown:  # kept: a grown geometry's boxes are computed once
            radii = {name: _read_only(getattr(self, name) + margin_m) for name in ("wall_radii", "disc_radii")}
            self._grown[margin_m] = replace(self, **radii)
        return self._grown[margin_m]

    @functools.cached_property
    def _grown(self) -> dict:
        return {}

    @property
    def n_copies(self) -> int:
        return len(self.wall_radii)

    @functools.cached_property
    def wall_boxes(self) -> np.ndarray:
        """Chipmunk's bounding box of each wall (cpSegmentShapeCacheData) (N, S, 4) ``(left, bottom, right, top)``."""
        a_x, a_y, b_x, b_y = np.moveaxis(self.wall_points, -1, 0)
        radii = self.wall_radii
        left, right = np.where(a_x < b_x, a_x, b_x) - radii, np.where(a_x < b_x, b_x, a_x) + radii
        bottom, top = np.where(a_y < b_y, a_y, b_y) - radii, np.where(a_y < b_y, b_y, a_y) + radii
        return _read_only(np.stack([left, bottom, right, top], axis=-1))

    @functools.cached_property
    def wall_points(self) -> np.ndarray:
        """Each wall's ends side by side (N, S, 4) ``(x0, y0, x1, y1)`` [m]."""
        return _read_only(np.concatenate([self.wall_starts, self.wall_ends], axis=-1))

    @functools.cached_property
    def disc_boxes(self) -> np.ndarray:
        """Chipmunk's bounding box of each disc (cpBBNewForCircle) (N, D, 4)."""
        centers, radii = self.disc_centers, self.disc_radii
        return _read_only(np.concatenate([centers - radii[..., None], centers + radii[..., None]], axis=-1))

    @functools.cached_property
    def culled(self) -> np.ndarray:
        """Whether Chipmunk culls each copy's shapes by bounding box: it has more than one static shape (N,) bool."""
        return self.wall_valid.sum(axis=1) + self.disc_valid.sum(axis=1) > 1


def _padded_rows(flat: np.ndarray, counts: list) -> tuple[np.ndarray, np.ndarray]:
    """Copy ``i``'s ``counts[i]`` rows of ``flat`` (M, ...), zero-padded to the most (N, C, ...), and which are real."""
    valid = np.arange(max(counts, default=0)) < np.array(counts, dtype=int)[:, None]
    padded = np.zeros((*valid.shape, *flat.shape[1:]), dtype=flat.dtype)
    padded[valid] = flat
    return padded, valid


def _pad(geometry: StaticGeometry, name: str, count: int) -> np.ndarray:
    """``geometry``'s field ``name`` zero-padded to ``count`` walls or discs."""
    array = getattr(geometry, name)
    padded = np.zeros((len(array), count, *array.shape[2:]), dtype=array.dtype)
    padded[:, : array.shape[1]] = array
    return padded


def _finite_array(value, shape: tuple, what: str) -> np.ndarray:
    """``value`` as a finite float array of ``shape`` (None: any size there), else a ``ValueError`` naming ``what``."""
    array = np.asarray(value, dtype=float)
    fits = array.ndim == len(shape) and all(size is None or size == n for size, n in zip(shape, array.shape))
    if not fits or not np.all(np.isfinite(array)):
        expected = "(" + ", ".join("any" if size is None else str(size) for size in shape) + ")"
        raise ValueError(f"{what} must be a finite array of shape {expected}, got shape {array.shape}")
    return array


def _check_copies(function: str, geometry: StaticGeometry, count: int, what: str) -> None:
    if not isinstance(geometry, StaticGeometry):
        raise ValueError(f"{function}: geometry must be a StaticGeometry, got {type(geometry).__name__}")
    if count != geometry.n_copies:
        raise ValueError(f"{function}: {count} {what} for a geometry of {geometry.n_copies} copies (one each)")


def segments_clear(geometry: StaticGeometry, copies, starts, ends, *, check_input: bool = True) -> np.ndarray:
    """Whether each line ``starts[m]`` -> ``ends[m]`` (M, 2) [m] in copy ``copies[m]`` misses every shape (M,), as
    ``World.line_of_sight``; ``check_input=False`` skips the checks (``ValueError``) for hot loops."""
    if check_input:
        if not isinstance(geometry, StaticGeometry):
            raise ValueError(f"segments_clear: geometry must be a StaticGeometry, got {type(geometry).__name__}")
        starts = _finite_array(starts, (None, 2), "segments_clear: starts [m]")
        ends = _finite_array(ends, (len(starts), 2), "segments_clear: ends [m] (one per start)")
        copies = np.asarray(copies)
        if copies.shape != (len(starts),) or (copies.size and copies.dtype.kind not in "iu"):
            raise ValueError(f"segments_clear: copies must be {len(starts)} ints (one per line), got {copies!r}")
        if np.any((copies < 0) | (copies >= geometry.n_copies)):
            raise ValueError(f"segments_clear: copies must be in [0, {geometry.n_copies - 1}], got {copies.tolist()}")
    return ~_blocked(geometry, copies, starts, ends)


def _blocked(geometry: StaticGeometry, copy, origins, targets) -> np.ndarray:
    """Whether each of M segments ``origins`` -> ``targets`` (M, 2) of copy ``copy`` (M,) hits a wall or disc (M,)."""
    return blocked(
        contiguous(np.asarray(copy, dtype=np.int64)),
        contiguous(np.asarray(origins, dtype=float)),
        contiguous(np.asarray(targets, dtype=float)),
        *shape_arrays(geometry),
    )


def shape_arrays(geometry: StaticGeometry) -> tuple:
    """``geometry``'s shapes as the kernels (``visibility_kernels.blocked``) take them: ``(walls, discs, culled)``."""
    walls = (geometry.wall_points, geometry.wall_radii, geometry.wall_boxes, geometry.wall_valid)
    discs = (geometry.disc_centers, geometry.disc_radii, geometry.disc_boxes, geometry.disc_valid)
    return walls, discs, geometry.culled


def swept_discs_clear(geometry: StaticGeometry, starts, ends, radius_m: float) -> np.ndarray:
    """Whether a disc of ``radius_m`` [m] moved straight along each of K moves per copy (N, K, 2) [m] touches no
    shape (N, K): one that starts touching is not clear, one that ends touching is. ``ValueError`` for bad input.
    """
    starts = _finite_array(starts, (None, None, 2), "swept_discs_clear: starts [m]")
    ends = _finite_array(ends, starts.shape, "swept_discs_clear: ends [m] (one per start)")
    _check_copies("swept_discs_clear", geometry, len(starts), "rows of starts")
    copy = np.repeat(np.arange(len(starts)), starts.shape[1])
    blocked = _blocked(geometry.grown(radius_m), copy, starts.reshape(-1, 2), ends.reshape(-1, 2))
    return ~blocked.reshape(starts.shape[:2])


def in_coverage(sensor: RangeBearingSensor, poses, targets) -> np.ndarray:
    """Whether each of K targets per copy (N, K, 2) [m] lies in ``sensor``'s range and field of view from the
    copy's pose ``[x, y, heading]`` (N, 3) (N, K); ``ValueError`` for a wrong shape or a non-finite value."""
    return _in_coverage(sensor, *_poses_and_targets(poses, targets))


def _poses_and_targets(poses, targets) -> tuple[np.ndarray, np.ndarray]:
    poses = _finite_array(poses, (None, 3), "in_coverage: poses [m, m, rad]")
    return poses, _finite_array(targets, (len(poses), None, 2), "in_coverage: targets [m] (one row per pose)")


def _in_coverage(sensor: RangeBearingSensor, poses: np.ndarray, targets: np.ndarray) -> np.ndarray:
    poses, targets = contiguous(np.asarray(poses, dtype=float)), contiguous(np.asarray(targets, dtype=float))
    return covered(poses, targets, float(sensor.max_range_m), float(sensor.fov_rad))


def visible(geometry: StaticGeometry, sensor: RangeBearingSensor, poses, targets, *, check_input: bool = True):
    """Which targets each copy's robot sees: in ``sensor``'s coverage and line of sight (N, K) bool;
    ``check_input=False`` skips the checks (as ``in_coverage``'s, and one pose per copy), for hot loops."""
    if check_input:
        poses, targets = _poses_and_targets(poses, targets)
        _check_copies("visible", geometry, len(poses), "poses")
    seen = _in_coverage(sensor, poses, targets)
    copy, target = np.nonzero(seen)
    seen[copy, target] = ~_blocked(geometry, copy, poses[copy, :2], targets[copy, target])
    return seen
