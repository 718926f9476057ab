"""A 2.5D scene for range and image sensors: a height map plus solid obstacles with heights.

The scene is independent of Pymunk: the obstacles' footprints (circles, rectangles) are what
a 2D ``World`` would collide with. Coordinates are world metres, ``z`` up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

MATERIALS = ("ground", "vegetation", "rock", "building")
NO_HIT = -1  # material index of a ray that hits nothing within range
_PROFILE_SAMPLES_PER_CELL = 1  # ground samples per grid cell along a ray's horizontal track
_REFINE_ITERATIONS = 4  # Illinois false-position steps refining a ground crossing on curved terrain
_ANGLE_KEY_STRIDE = 4.0  # > pi: separates the columns' horizon-angle blocks in one sorted array [rad]
_BLOCK_ELEMENTS = 12288  # rays or ground samples per block of columns: small temporaries stay in cache and reuse
# freed heap memory instead of fresh pages (page faults dominated unblocked frames on a VM)


def finite_vector(value, length: int, name: str) -> tuple[float, ...]:
    """``value`` as a tuple of ``length`` finite floats, or ``ValueError`` naming it."""
    vector = np.asarray(value, dtype=float)
    if vector.shape != (length,) or not np.all(np.isfinite(vector)):
        raise ValueError(f"{name} must be {length} finite numbers, got {value!r}")
    return tuple(float(v) for v in vector)


def _check_material(material: str, owner: str) -> None:
    if material not in MATERIALS[1:]:
        raise ValueError(f"{owner} material must be one of {MATERIALS[1:]}, got {material!r}")


@dataclass(frozen=True)
class Cylinder:
    """A vertical solid cylinder: a tree trunk or canopy, a rock.

    Attributes:
        center_m: ``(x, y)`` of the axis [m].
        radius_m: radius [m].
        bottom_m: elevation of the base [m].
        top_m: elevation of the top [m].
        material: one of ``MATERIALS`` except ``"ground"``.
    """

    center_m: tuple[float, float]
    radius_m: float
    bottom_m: float
    top_m: float
    material: str = "vegetation"

    def __post_init__(self):
        object.__setattr__(self, "center_m", finite_vector(self.center_m, 2, "cylinder center_m"))
        if not (math.isfinite(self.radius_m) and self.radius_m > 0):
            raise ValueError(f"cylinder radius_m must be positive and finite, got {self.radius_m!r}")
        if not (math.isfinite(self.bottom_m) and math.isfinite(self.top_m) and self.bottom_m < self.top_m):
            raise ValueError(f"cylinder needs finite bottom_m < top_m, got {self.bottom_m!r} and {self.top_m!r}")
        _check_material(self.material, "cylinder")


@dataclass(frozen=True)
class Box:
    """An axis-aligned solid box: a wall or a building.

    Attributes:
        min_corner_m: ``(x, y, z)`` of the lowest corner [m].
        max_corner_m: ``(x, y, z)`` of the highest corner [m].
        material: one of ``MATERIALS`` except ``"ground"``.
    """

    min_corner_m: tuple[float, float, float]
    max_corner_m: tuple[float, float, float]
    material: str = "building"

    def __post_init__(self):
        low = finite_vector(self.min_corner_m, 3, "box min_corner_m")
        high = finite_vector(self.max_corner_m, 3, "box max_corner_m")
        if not all(a < b for a, b in zip(low, high, strict=True)):
            raise ValueError(f"box min_corner_m {low} must be below max_corner_m {high} on every axis")
        object.__setattr__(self, "min_corner_m", low)
        object.__setattr__(self, "max_corner_m", high)
        _check_material(self.material, "box")


@dataclass(frozen=True)
class RayHits:
    """Where a grid of rays first meets the scene.

    Attributes:
        range_m: distance along each ray to the first hit (R, C) [m]; ``inf`` for no hit within range.
        material_index: index into ``MATERIALS`` of what each ray hit (R, C); ``NO_HIT`` for none.
    """

    range_m: np.ndarray
    material_index: np.ndarray


def _slab(origin, direction, low, high) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``(enter, exit)`` where ``origin + t * direction`` lies in ``[low, high]`` (broadcast).

    A zero direction gives the whole line when the origin is inside, else an empty interval.
    """
    direction = np.asarray(direction, dtype=float)
    moving = direction != 0
    safe_direction = np.where(moving, direction, 1.0)
    t_low, t_high = (low - origin) / safe_direction, (high - origin) / safe_direction
    inside = (low <= origin) & (origin <= high)
    enter = np.where(moving, np.minimum(t_low, t_high), np.where(inside, -np.inf, np.inf))
    exit_ = np.where(moving, np.maximum(t_low, t_high), np.where(inside, np.inf, -np.inf))
    return enter, exit_


def blend_in_place(lower_left, lower_right, upper_left, upper_right, tx, ty) -> np.ndarray:
    """Bilinear blend of corner values at cell offsets ``tx``, ``ty`` in [0, 1].

    Rounds exactly like ``(1 - ty) * ((1 - tx) * lower_left + tx * lower_right) + ty * ((1 - tx) *
    upper_left + tx * upper_right)`` but overwrites the corner arrays (the result is ``lower_left``)
    instead of allocating temporaries.
    """
    weight = 1 - tx
    lower_left *= weight
    lower_right *= tx
    lower_left += lower_right
    upper_left *= weight
    upper_right *= tx
    upper_left += upper_right
    np.subtract(1, ty, out=weight)
    lower_left *= weight
    upper_left *= ty
    lower_left += upper_left
    return lower_left


def _false_position(low_s, low_f, high_s, high_f) -> np.ndarray:
    """Secant root ``low_s + (high_s - low_s) * low_f / (low_f - high_f)`` of brackets with ``low_f > 0 >= high_f``."""
    root = high_s - low_s
    root *= low_f
    root /= low_f - high_f
    root += low_s
    return root


@dataclass(frozen=True, eq=False)
class Terrain:
    """A height map on a regular grid plus solid obstacles.

    ``heights_m[i, j]`` is the ground elevation at ``(x0 + j * cell_m, y0 + i * cell_m)``;
    between grid points the ground is bilinear, beyond the grid the edge heights extend.

    Attributes:
        heights_m: ground elevations (H, W) with H, W >= 2 [m].
        origin_m: ``(x0, y0)`` of grid point ``[0, 0]`` [m].
        cell_m: grid spacing [m].
        cylinders: vertical cylinders (trees, rocks).
        boxes: axis-aligned boxes (walls, buildings).
    """

    heights_m: np.ndarray
    origin_m: tuple[float, float] = (0.0, 0.0)
    cell_m: float = 1.0
    cylinders: tuple[Cylinder, ...] = ()
    boxes: tuple[Box, ...] = ()
    _obstacle_arrays: dict = field(init=False, repr=False)

    def __post_init__(self):
        heights = np.array(self.heights_m, dtype=float)
        if heights.ndim != 2 or min(heights.shape) < 2:
            raise ValueError(f"terrain heights_m must be a 2D grid of at least 2 x 2 points, got shape {heights.shape}")
        if not np.all(np.isfinite(heights)):
            raise ValueError("terrain heights_m contains NaN or infinite values")
        if not (math.isfinite(self.cell_m) and self.cell_m > 0):
            raise ValueError(f"terrain cell_m must be positive and finite, got {self.cell_m!r}")
        heights.flags.writeable = False
        object.__setattr__(self, "heights_m", heights)
        object.__setattr__(self, "origin_m", finite_vector(self.origin_m, 2, "terrain origin_m"))
        object.__setattr__(self, "cylinders", tuple(self.cylinders))
        object.__setattr__(self, "boxes", tuple(self.boxes))
        for obstacle in self.cylinders + self.boxes:
            if not isinstance(obstacle, (Cylinder, Box)):
                raise ValueError(f"terrain obstacles must be Cylinder or Box, got {obstacle!r}")
        object.__setattr__(self, "_obstacle_arrays", self._stack_obstacles())

    def _stack_obstacles(self) -> dict:
        """The obstacles' parameters as arrays, for vectorized intersection."""
        cylinders, boxes = self.cylinders, self.boxes
        return {
            "cylinder_centers": np.array([c.center_m for c in cylinders]).reshape(-1, 2),
            "cylinder_radii": np.array([c.radius_m for c in cylinders]),
            "box_low": np.array([b.min_corner_m for b in boxes]).reshape(-1, 3),
            "box_high": np.array([b.max_corner_m for b in boxes]).reshape(-1, 3),
            "z_low": np.array([c.bottom_m for c in cylinders] + [b.min_corner_m[2] for b in boxes]),
            "z_high": np.array([c.top_m for c in cylinders] + [b.max_corner_m[2] for b in boxes]),
            "materials": np.array([MATERIALS.index(o.material) for o in cylinders + boxes], dtype=np.int8),
        }

    @property
    def bounds_m(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)`` covered by the height grid [m]."""
        rows, columns = self.heights_m.shape
        x0, y0 = self.origin_m
        return x0, y0, x0 + (columns - 1) * self.cell_m, y0 + (rows - 1) * self.cell_m

    def with_obstacles(self, cylinders=(), boxes=()) -> Terrain:
        """A copy with ``cylinders`` and ``boxes`` added to the existing obstacles."""
        return replace(self, cylinders=self.cylinders + tuple(cylinders), boxes=self.boxes + tuple(boxes))

    def _cell_corners(self, xy) -> tuple[np.ndarray, ...]:
        """Corner heights ``h00, h01, h10, h11`` of the cell under each point and the offsets ``tx, ty`` in it.

        Checks ``xy`` (..., 2); the results are flat (N,).
        """
        points = np.asarray(xy, dtype=float)
        if points.ndim < 1 or points.shape[-1] != 2 or not np.all(np.isfinite(points)):
            raise ValueError(f"terrain query points must be finite (..., 2) [m], got shape {points.shape}")
        flat = points.reshape(-1, 2)
        return self._corners(flat[:, 0], flat[:, 1])

    def _corners(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, ...]:
        """``_cell_corners`` of finite points given as flat coordinate arrays ``x``, ``y`` (N,), unchecked.

        Works in place on few temporaries: on this hot path, fresh memory costs more than arithmetic.
        """
        rows, columns = self.heights_m.shape
        tx = np.subtract(x, self.origin_m[0])
        tx /= self.cell_m
        np.clip(tx, 0, columns - 1, out=tx)
        ty = np.subtract(y, self.origin_m[1])
        ty /= self.cell_m
        np.clip(ty, 0, rows - 1, out=ty)
        j = tx.astype(np.intp)
        np.minimum(j, columns - 2, out=j)
        corner = ty.astype(np.intp)
        np.minimum(corner, rows - 2, out=corner)
        tx -= j
        ty -= corner
        corner *= columns
        corner += j
        flat_heights = self.heights_m.ravel()
        lower_left = flat_heights.take(corner)
        corner += 1
        lower_right = flat_heights.take(corner)
        corner += columns
        upper_right = flat_heights.take(corner)
        corner -= 1
        upper_left = flat_heights.take(corner)
        return lower_left, lower_right, upper_left, upper_right, tx, ty

    def _height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Bilinear ground elevation (N,) [m] at finite flat coordinates ``x``, ``y`` (N,), unchecked."""
        return blend_in_place(*self._corners(x, y))

    def height_at(self, xy) -> np.ndarray:
        """Bilinear ground elevation [m] at points ``xy`` (..., 2) -> (...)."""
        return blend_in_place(*self._cell_corners(xy)).reshape(np.shape(xy)[:-1])[()]

    def surface_normal_at(self, xy) -> np.ndarray:
        """Upward unit normals (..., 3) of the bilinear ground at points ``xy`` (..., 2); level beyond the grid."""
        h00, h01, h10, h11, tx, ty = self._cell_corners(xy)
        points, (x_min, y_min, x_max, y_max) = np.asarray(xy, dtype=float).reshape(-1, 2), self.bounds_m
        # slope_x = ((1 - ty) * (h01 - h00) + ty * (h11 - h10)) / cell_m and its y twin, in place
        slope_x, upper = h01 - h00, h11 - h10
        weight = 1 - ty
        slope_x *= weight
        upper *= ty
        slope_x += upper
        slope_x /= self.cell_m
        slope_y, right = np.subtract(h10, h00, out=h10), np.subtract(h11, h01, out=h11)
        np.subtract(1, tx, out=weight)
        slope_y *= weight
        right *= tx
        slope_y += right
        slope_y /= self.cell_m
        slope_x[(points[:, 0] < x_min) | (points[:, 0] > x_max)] = 0.0
        slope_y[(points[:, 1] < y_min) | (points[:, 1] > y_max)] = 0.0
        # the normal (-slope_x, -slope_y, 1) over its length sqrt(slope_x**2 + slope_y**2 + 1)
        length = np.square(slope_x)
        length += np.square(slope_y, out=weight)
        length += 1
        np.sqrt(length, out=length)
        normals = np.empty((points.shape[0], 3))
        np.divide(slope_x, length, out=normals[:, 0])
        np.divide(slope_y, length, out=normals[:, 1])
        np.negative(normals[:, :2], out=normals[:, :2])
        np.divide(1.0, length, out=normals[:, 2])
        return normals.reshape(*np.shape(xy)[:-1], 3)

    def cast_rays(self, origin_m, azimuth_rad, elevation_rad, max_range_m: float) -> RayHits:
        """First hits of a grid of rays whose columns share an azimuth (a scanner's or an upright camera's).

        Ray ``(r, c)`` leaves ``origin_m`` towards azimuth ``azimuth_rad[c]`` (world frame,
        counterclockwise from +x) at elevation ``elevation_rad[r]`` (or ``[r, c]``) above the
        horizontal. Since a column's rays share one vertical plane, the ground is sampled once
        per column; a ray meets it at the first sample whose elevation angle seen from the
        origin reaches the ray's, refined by linear interpolation (exact on planar ground) and
        false-position steps. Obstacles are intersected analytically; an origin inside one
        gives range 0. Columns are cast in blocks of about ``_BLOCK_ELEMENTS`` rays or ground
        samples, which keeps the temporaries small.

        Args:
            origin_m: ``(x, y, z)`` of the ray origin, above the ground [m].
            azimuth_rad: (C,) world azimuth of each column [rad].
            elevation_rad: (R,) or (R, C) elevation of each ray, inside (-pi/2, pi/2) [rad].
            max_range_m: hits farther than this are dropped [m].

        Returns:
            The range and material of each ray's first hit, (R, C).
        """
        origin = np.array(finite_vector(origin_m, 3, "ray origin_m"))
        azimuth = np.asarray(azimuth_rad, dtype=float)
        elevation = np.asarray(elevation_rad, dtype=float)
        if azimuth.ndim != 1 or not np.all(np.isfinite(azimuth)):
            raise ValueError(f"azimuth_rad must be a finite (C,) array, got shape {azimuth.shape}")
        if elevation.ndim == 1:
            elevation = elevation[:, None]
        if elevation.ndim != 2 or elevation.shape[1] not in (1, azimuth.size):
            raise ValueError(f"elevation_rad must be (R,) or (R, C={azimuth.size}), got shape {elevation.shape}")
        if not np.all(np.abs(elevation) < math.pi / 2):
            raise ValueError("elevation_rad must lie strictly inside (-pi/2, pi/2)")
        if not (math.isfinite(max_range_m) and max_range_m > 0):
            raise ValueError(f"max_range_m must be positive and finite, got {max_range_m!r}")
        if not origin[2] > self.height_at(origin[:2]):
            raise ValueError(f"ray origin_m {tuple(origin)} is not above the ground")
        heading = np.stack([np.cos(azimuth), np.sin(azimuth)], axis=-1)  # (C, 2) horizontal unit vectors
        slope = np.tan(elevation)  # dz per horizontal metre, (R, 1) or (R, C)
        step_m = self.cell_m / _PROFILE_SAMPLES_PER_CELL
        distances = np.arange(math.ceil(max_range_m / step_m) + 1) * step_m  # ground samples along each column
        key_offsets = _ANGLE_KEY_STRIDE * np.arange(azimuth.size)
        shape = (elevation.shape[0], azimuth.size)
        range_m, material = np.empty(shape), np.empty(shape, dtype=np.int8)
        block_columns = max(1, _BLOCK_ELEMENTS // max(shape[0], distances.size))
        for start in range(0, azimuth.size, block_columns):
            block = slice(start, start + block_columns)
            rays = slice(None) if elevation.shape[1] == 1 else block
            range_m[:, block], material[:, block] = self._first_hits(
                origin, heading[block], elevation[:, rays], slope[:, rays], distances, key_offsets[block], max_range_m
            )
        return RayHits(range_m, material)

    def _first_hits(self, origin, heading, elevation, slope, distances, key_offsets, max_range_m) -> tuple:
        """``cast_rays`` for a block of columns: range (R, C) [m] and material index (R, C) of the first hits."""
        obstacle_s, obstacle_material = self._obstacle_crossing(origin, heading, slope)
        ground_s = self._ground_crossing(origin, heading, elevation, slope, distances, key_offsets, obstacle_s)
        nearest_s = np.minimum(ground_s, obstacle_s)
        range_m = nearest_s / np.cos(elevation)
        hit = range_m <= max_range_m
        material = np.where(obstacle_s < ground_s, obstacle_material, np.int8(MATERIALS.index("ground")))
        return np.where(hit, range_m, np.inf), np.where(hit, material, np.int8(NO_HIT))

    def _ground_crossing(self, origin, heading, elevation, slope, distances, key_offsets, obstacle_s) -> np.ndarray:
        """Horizontal distance (R, C) [m] at which each ray first goes below the ground; ``inf`` if never.

        The ground is sampled at horizontal ``distances`` (K,) [m] along each column; ``key_offsets``
        (C,) separate the columns' horizon angles in one sorted array. Rays that meet an obstacle
        (at ``obstacle_s`` (R, C)) before the ground sample bracketing their crossing are not
        refined and read ``inf`` too: the obstacle is nearer either way.
        """
        sample_count = distances.size
        track_x = origin[0] + distances * heading[:, :1]  # (C, K) horizontal tracks
        track_y = origin[1] + distances * heading[:, 1:]
        ground = self._height(track_x.ravel(), track_y.ravel()).reshape(track_x.shape)
        angles = np.subtract(ground, origin[2])
        np.arctan2(angles, distances, out=angles)
        angles[:, 0] = -math.pi / 2  # the origin is above the ground
        np.maximum.accumulate(angles, axis=1, out=angles)  # horizon: nondecreasing along each column
        angles += key_offsets[:, None]
        sample = np.searchsorted(angles.ravel(), elevation + key_offsets, side="left")
        sample -= np.arange(heading.shape[0]) * sample_count  # index within the ray's own column
        crossing = np.full(sample.shape, np.inf)
        rows, columns = np.nonzero(sample < sample_count)
        k = sample[rows, columns]
        nearer = distances[k - 1] <= obstacle_s[rows, columns]
        rows, columns, k = rows[nearer], columns[nearer], k[nearer]
        if rows.size == 0:
            return crossing
        ray_heading = heading[columns]
        ray_slope = np.broadcast_to(slope, sample.shape)[rows, columns]

        def height_above_ground(s, ground_m):
            """``origin[2] + s * ray_slope - ground_m``, overwriting ``ground_m``."""
            ground_m -= origin[2] + s * ray_slope
            return np.negative(ground_m, out=ground_m)

        low_s, high_s = distances[k - 1], distances[k]
        low_f = height_above_ground(low_s, ground[columns, k - 1])
        high_f = height_above_ground(high_s, ground[columns, k])
        s, was_above = _false_position(low_s, low_f, high_s, high_f), None
        for _ in range(_REFINE_ITERATIONS):
            track_x, track_y = s * ray_heading[:, 0], s * ray_heading[:, 1]
            track_x += origin[0]
            track_y += origin[1]
            f = height_above_ground(s, self._height(track_x, track_y))
            above = f > 0
            if was_above is not None:
                # Illinois rule: halve the end kept twice in a row, so the bracket shrinks from both sides
                np.multiply(high_f, 0.5, out=high_f, where=above & was_above)
                np.multiply(low_f, 0.5, out=low_f, where=~(above | was_above))
            np.copyto(low_s, s, where=above)
            np.copyto(low_f, f, where=above)
            np.copyto(high_s, s, where=~above)
            np.copyto(high_f, f, where=~above)
            was_above = above
            s = _false_position(low_s, low_f, high_s, high_f)
        crossing[rows, columns] = s
        return crossing

    def _obstacle_crossing(self, origin, heading, slope) -> tuple[np.ndarray, np.ndarray]:
        """Horizontal distance (R, C) [m] to the nearest obstacle along each ray and its material index.

        Footprints are intersected per column (one vertical plane each); only the (column,
        obstacle) pairs whose plane crosses the footprint ahead are checked against the heights.
        """
        arrays = self._obstacle_arrays
        shape = (slope.shape[0], heading.shape[0])
        distance, material = np.full(shape, np.inf), np.full(shape, NO_HIT, dtype=np.int8)
        offset = origin[:2] - arrays["cylinder_centers"]  # (Mc, 2)
        half_b = heading @ offset.T  # (C, Mc)
        discriminant = half_b**2 - (np.sum(offset**2, axis=1) - arrays["cylinder_radii"] ** 2)
        root = np.sqrt(np.maximum(discriminant, 0))
        cylinder_enter = np.where(discriminant >= 0, -half_b - root, np.inf)
        cylinder_exit = np.where(discriminant >= 0, -half_b + root, -np.inf)
        x_enter, x_exit = _slab(origin[0], heading[:, :1], arrays["box_low"][:, 0], arrays["box_high"][:, 0])
        y_enter, y_exit = _slab(origin[1], heading[:, 1:], arrays["box_low"][:, 1], arrays["box_high"][:, 1])
        footprint_enter = np.concatenate([cylinder_enter, np.maximum(x_enter, y_enter)], axis=1)  # (C, M)
        footprint_exit = np.concatenate([cylinder_exit, np.minimum(x_exit, y_exit)], axis=1)
        columns, obstacles = np.nonzero((footprint_enter <= footprint_exit) & (footprint_exit >= 0))  # by column
        if columns.size == 0:
            return distance, material
        pair_slope = np.broadcast_to(slope, shape)[:, columns]  # (R, P)
        z_enter, z_exit = _slab(origin[2], pair_slope, arrays["z_low"][obstacles], arrays["z_high"][obstacles])
        enter = np.maximum(np.maximum(footprint_enter[columns, obstacles], z_enter), 0.0)
        exit_ = np.minimum(footprint_exit[columns, obstacles], z_exit)
        enter = np.where(enter <= exit_, enter, np.inf)
        seen_columns, first_pair, pair_count = np.unique(columns, return_index=True, return_counts=True)
        nearest = np.minimum.reduceat(enter, first_pair, axis=1)  # (R, columns with candidates)
        is_nearest = np.isfinite(enter) & (enter == np.repeat(nearest, pair_count, axis=1))
        pair_material = np.where(is_nearest, arrays["materials"][obstacles], np.int8(NO_HIT))
        distance[:, seen_columns] = nearest
        material[:, seen_columns] = np.maximum.reduceat(pair_material, first_pair, axis=1)
        return distance, material
