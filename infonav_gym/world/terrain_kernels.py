"""Compiled ground queries and ray casting of ``world.terrain``: the one implementation ``Terrain`` calls.

The ground is a ``grid`` ``(heights, x0, y0, cell_m)``: bilinear between the points of ``heights`` (H, W)
[m], grid point ``[i, j]`` at ``(x0 + j * cell_m, y0 + i * cell_m)``, the edge heights extending beyond the grid.
Obstacles are rows of an (M, 9) table ``(center x, center y, radius, low x, low y, low z, high x, high y,
high z)`` [m]: the first ``n_cylinders`` are vertical cylinders (centre, radius, ``low z`` to ``high z``), the rest
axis-aligned boxes (``low`` to ``high``); ``materials`` (M,) int8 hold their indices into ``MATERIALS``. A NaN in a
comparison makes it false. ``x / cell_m`` is ``x * (1 / cell_m)``: quicker, equal for a power-of-two cell (0.5 m).
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import inline, kernel

GROUND = 0  # material index of the ground (``MATERIALS[0]``)
NO_HIT = -1  # material index of a ray that hits nothing within range
REFINE_ITERATIONS = 4  # Illinois false-position steps refining a ground crossing on curved terrain
OBSTACLE_COLUMNS = 9  # center x, center y, radius, low x, low y, low z, high x, high y, high z


@inline
def blend(lower_left, lower_right, upper_left, upper_right, tx, ty):
    """Bilinear blend of four corner values at cell offsets ``tx``, ``ty`` in [0, 1]."""
    weight = 1.0 - tx
    return (lower_left * weight + lower_right * tx) * (1.0 - ty) + (upper_left * weight + upper_right * tx) * ty


@inline
def cell_position(grid, x, y):
    """The row and column ``(i, j)`` of the cell under ``(x, y)`` and the offsets ``(tx, ty)`` in it, clamped to the
    grid (a NaN coordinate to its first row or column)."""
    heights, x0, y0, cell_m = grid
    rows, columns = heights.shape
    tx, ty = (x - x0) * (1.0 / cell_m), (y - y0) * (1.0 / cell_m)
    tx = min(tx if tx >= 0.0 else 0.0, columns - 1.0)  # NaN to 0: the index stays inside the grid
    ty = min(ty if ty >= 0.0 else 0.0, rows - 1.0)
    j, i = min(int(tx), columns - 2), min(int(ty), rows - 2)
    return i, j, tx - j, ty - i


@inline
def cell_at(grid, x, y):
    """The corner heights ``(lower left, lower right, upper left, upper right)`` of the cell under ``(x, y)`` and the
    offsets ``(tx, ty)`` in it (``cell_position``'s)."""
    i, j, tx, ty = cell_position(grid, x, y)
    heights = grid[0]
    return heights[i, j], heights[i, j + 1], heights[i + 1, j], heights[i + 1, j + 1], tx, ty


@inline
def height(grid, x, y):
    """Bilinear ground elevation at ``(x, y)`` [m]."""
    lower_left, lower_right, upper_left, upper_right, tx, ty = cell_at(grid, x, y)
    return blend(lower_left, lower_right, upper_left, upper_right, tx, ty)


@inline
def ground_normal(grid, x, y):
    """Upward unit normal ``(nx, ny, nz)`` of the bilinear ground at ``(x, y)``; level beyond the grid."""
    lower_left, lower_right, upper_left, upper_right, tx, ty = cell_at(grid, x, y)
    return cell_normal(grid, x, y, lower_left, lower_right, upper_left, upper_right, tx, ty)


@inline
def cell_normal(grid, x, y, lower_left, lower_right, upper_left, upper_right, tx, ty):
    """``ground_normal`` at ``(x, y)`` from ``cell_at``'s corner heights and offsets there."""
    heights, x0, y0, cell_m = grid
    rows, columns = heights.shape
    slope_x = ((lower_right - lower_left) * (1.0 - ty) + (upper_right - upper_left) * ty) * (1.0 / cell_m)
    slope_y = ((upper_left - lower_left) * (1.0 - tx) + (upper_right - lower_right) * tx) * (1.0 / cell_m)
    if x < x0 or x > x0 + (columns - 1) * cell_m:
        slope_x = 0.0
    if y < y0 or y > y0 + (rows - 1) * cell_m:
        slope_y = 0.0
    length = math.sqrt(slope_x * slope_x + slope_y * slope_y + 1.0)
    return -(slope_x / length), -(slope_y / length), 1.0 / length


@kernel
def ground_at(grid, points):
    """Ground elevations (N,) [m] and upward unit normals (N, 3) at points (N, 2) [m]."""
    count = points.shape[0]
    elevations, normals = np.empty(count), np.empty((count, 3))
    for n in range(count):
        x, y = points[n, 0], points[n, 1]
        elevations[n] = height(grid, x, y)
        normals[n, 0], normals[n, 1], normals[n, 2] = ground_normal(grid, x, y)
    return elevations, normals


@inline
def slab(origin, direction, low, high):
    """Parameters ``(enter, exit)`` where ``origin + t * direction`` lies in ``[low, high]``; a zero direction
    gives the whole line when the origin is inside, else an empty interval."""
    if direction != 0.0:
        t_low, t_high = (low - origin) / direction, (high - origin) / direction
        return min(t_low, t_high), max(t_low, t_high)
    if low <= origin and origin <= high:
        return -np.inf, np.inf
    return np.inf, -np.inf


@inline
def footprint_crossing(obstacles, m, n_cylinders, origin_x, origin_y, heading_x, heading_y):
    """Horizontal distances ``(enter, exit)`` [m] of the line from the origin along the heading through obstacle
    ``m``'s footprint (enter > exit: it misses)."""
    if m < n_cylinders:
        offset_x, offset_y = origin_x - obstacles[m, 0], origin_y - obstacles[m, 1]
        half_b = heading_x * offset_x + heading_y * offset_y
        discriminant = half_b * half_b - ((offset_x * offset_x + offset_y * offset_y) - obstacles[m, 2] ** 2)
        if not discriminant >= 0.0:
            return np.inf, -np.inf
        root = math.sqrt(discriminant)
        return -half_b - root, -half_b + root
    x_enter, x_exit = slab(origin_x, heading_x, obstacles[m, 3], obstacles[m, 6])
    y_enter, y_exit = slab(origin_y, heading_y, obstacles[m, 4], obstacles[m, 7])
    return max(x_enter, y_enter), min(x_exit, y_exit)


@inline
def first_at_or_above(ascending, value, hint):
    """The first index of ``ascending`` (K,) whose value is at least ``value`` (K if none), searched from ``hint``
    (in [0, K], e.g. the answer for the previous of a row of sorted values): steps of doubling length from the hint
    towards the answer, then a binary search between the last two probes, a few reads when the answer is near."""
    size = ascending.shape[0]
    if hint < size and ascending[hint] < value:  # the answer is above the hint
        low, step = hint + 1, 1
        while low + step - 1 < size and ascending[low + step - 1] < value:
            low, step = low + step, 2 * step
        high = min(low + step - 1, size)
    else:
        high, step = hint, 1
        while high - step >= 0 and ascending[high - step] >= value:
            high, step = high - step, 2 * step
        low = max(high - step + 1, 0)
    while low < high:
        middle = (low + high) // 2
        if ascending[middle] < value:
            low = middle + 1
        else:
            high = middle
    return low


@inline
def false_position(low_s, high_s, low_f, high_f):
    """Where the chord from ``(low_s, low_f)`` to ``(high_s, high_f)`` crosses zero."""
    return (high_s - low_s) * low_f / (low_f - high_f) + low_s


@inline
def illinois_step(low_s, low_f, high_s, high_f, side, s, f):
    """The bracket ``(low_s, low_f, high_s, high_f)``, whose last point was on ``side`` (1 above the ground, 0 below,
    -1 none yet), narrowed by the clearance ``f`` above the ground at ``s``, the end kept twice in a row halved
    (Illinois); returns it, the side of ``s`` and the chord's zero, the next ``s``. Selects, no branches: a loop of
    steps over many rays compiles to vector instructions."""
    above = f > 0.0  # s replaces the low end, else the high end
    now = 1.0 if above else 0.0
    kept_factor = 1.0 - 0.5 * (now == side)
    low_s, high_s = s if above else low_s, high_s if above else s
    low_f, high_f = f if above else low_f * kept_factor, high_f * kept_factor if above else f
    return low_s, low_f, high_s, high_f, now, false_position(low_s, high_s, low_f, high_f)


@kernel
def first_hits(arrays, origin, azimuth, elevation, max_range_m):
    """First hits ``(range_m, material, obstacle)`` (R, C) in the scene ``arrays`` of rays from ``origin`` (3,) at
    azimuth ``azimuth[c]`` and elevation ``elevation[r, c]`` ((R, C) or (R, 1), in (-pi/2, pi/2)) [rad].

    A column is one vertical plane: the ground is sampled once per cell along it, and a ray meets it at the first
    sample whose slope seen from the origin reaches the ray's, refined by ``REFINE_ITERATIONS`` Illinois steps
    (exact on planar ground) unless an obstacle comes first. Obstacles are intersected analytically (an origin
    inside one: range 0; ties to the higher material index). No hit: ``inf``, ``NO_HIT``, obstacle -1 (also -1 for
    the ground). The refinement loops stay in this kernel: in a helper they compiled 10 to 50 % slower.
    """
    grid, obstacles, materials, n_cylinders = arrays
    rows, columns, wide = elevation.shape[0], azimuth.shape[0], elevation.shape[1] > 1
    origin_z = origin[2]
    step_m = grid[3]
    samples = math.ceil(max_range_m / step_m) + 1
    slopes, cosines = np.empty(elevation.shape), np.empty(elevation.shape)
    for r in range(elevation.shape[0]):
        for column in range(elevation.shape[1]):
            slopes[r, column], cosines[r, column] = math.tan(elevation[r, column]), math.cos(elevation[r, column])
    ground, horizon = np.empty(samples), np.empty(samples)
    n_obstacles = obstacles.shape[0]
    candidates, enters, exits = np.empty(n_obstacles, np.int64), np.empty(n_obstacles), np.empty(n_obstacles)
    refined, ground_s = np.empty(rows, np.int64), np.empty(rows)
    low_s, low_f, high_s, high_f = np.empty(rows), np.empty(rows), np.empty(rows), np.empty(rows)
    s, side, ray_slope = np.empty(rows), np.empty(rows), np.empty(rows)  # each bracket's next point, last side, slope
    cell_index, cell_tx, cell_ty = np.empty(rows, np.int64), np.empty(rows), np.empty(rows)  # the cells under s
    lower_left, lower_right, upper_left, upper_right = np.empty(rows), np.empty(rows), np.empty(rows), np.empty(rows)
    flat_heights, grid_columns = grid[0].ravel(), grid[0].shape[1]
    range_m = np.empty((rows, columns))
    material = np.empty((rows, columns), np.int8)
    obstacle = np.empty((rows, columns), np.int64)
    for c in range(columns):
        heading_x, heading_y = math.cos(azimuth[c]), math.sin(azimuth[c])
        column = c if wide else 0
        steepest = -np.inf
        for r in range(rows):
            steepest = max(steepest, slopes[r, column])
        horizon[0] = -np.inf  # the origin is above the ground
        ground[0] = height(grid, origin[0], origin[1])
        marched = samples
        for k in range(1, samples):
            distance = k * step_m
            ground[k] = height(grid, origin[0] + distance * heading_x, origin[1] + distance * heading_y)
            horizon[k] = max(horizon[k - 1], (ground[k] - origin_z) / distance)
            if horizon[k] >= steepest:
                marched = k + 1  # every ray meets the ground by here
                break
        count = 0
        for m in range(n_obstacles):
            enter, exit_ = footprint_crossing(obstacles, m, n_cylinders, origin[0], origin[1], heading_x, heading_y)
            if enter <= exit_ and exit_ >= 0.0:
                candidates[count], enters[count], exits[count] = m, enter, exit_
                count += 1
        n_refined, k = 0, marched  # k: the sample where the last ray meets the ground (marched: none)
        for r in range(rows):
            slope = slopes[r, column]
            nearest_s, nearest_material, nearest_obstacle = np.inf, NO_HIT, -1
            for q in range(count):
                m = candidates[q]
                z_enter, z_exit = slab(origin_z, slope, obstacles[m, 5], obstacles[m, 8])
                enter, exit_ = max(max(enters[q], z_enter), 0.0), min(exits[q], z_exit)
                if enter <= exit_ and (enter < nearest_s or (enter == nearest_s and materials[m] > nearest_material)):
                    nearest_s, nearest_material, nearest_obstacle = enter, materials[m], m
            range_m[r, c], material[r, c], obstacle[r, c] = nearest_s, nearest_material, nearest_obstacle
            ground_s[r] = np.inf
            k = first_at_or_above(horizon[:marched], slope, k)
            if k < marched and (k - 1) * step_m <= nearest_s:
                q = n_refined
                low_s[q], high_s[q] = (k - 1) * step_m, k * step_m
                low_f[q] = (origin_z + low_s[q] * slope) - ground[k - 1]
                high_f[q] = (origin_z + high_s[q] * slope) - ground[k]
                s[q], side[q] = false_position(low_s[q], high_s[q], low_f[q], high_f[q]), -1.0
                ray_slope[q], refined[q] = slope, r
                n_refined += 1
        for _ in range(REFINE_ITERATIONS):
            for q in range(n_refined):
                i, j, cell_tx[q], cell_ty[q] = cell_position(
                    grid, s[q] * heading_x + origin[0], s[q] * heading_y + origin[1]
                )
                cell_index[q] = i * grid_columns + j
            for q in range(n_refined):
                corner = cell_index[q]
                lower_left[q], lower_right[q] = flat_heights[corner], flat_heights[corner + 1]
                upper_left[q], upper_right[q] = (
                    flat_heights[corner + grid_columns],
                    flat_heights[corner + grid_columns + 1],
                )
            for q in range(n_refined):
                under = blend(lower_left[q], lower_right[q], upper_left[q], upper_right[q], cell_tx[q], cell_ty[q])
                f = (origin_z + s[q] * ray_slope[q]) - under
                low_s[q], low_f[q], high_s[q], high_f[q], side[q], s[q] = illinois_step(
                    low_s[q], low_f[q], high_s[q], high_f[q], side[q], s[q], f
                )
        for q in range(n_refined):
            ground_s[refined[q]] = s[q]
        for r in range(rows):
            nearest_s = range_m[r, c]
            distance = min(ground_s[r], nearest_s) / cosines[r, column]
            if not distance <= max_range_m:
                range_m[r, c], material[r, c], obstacle[r, c] = np.inf, NO_HIT, -1
            elif nearest_s < ground_s[r]:
                range_m[r, c] = distance
            else:
                range_m[r, c], material[r, c], obstacle[r, c] = distance, GROUND, -1
    return range_m, material, obstacle


@inline
def obstacle_normal(obstacles, m, n_cylinders, x, y, z):
    """Outward unit normal ``(nx, ny, nz)`` of obstacle ``m`` at a point ``(x, y, z)`` on its surface: its cap's
    where the point is nearer the cap plane than the side wall, else the cylinder's radial direction or the normal
    of the box face nearest the point."""
    cap = max(z - obstacles[m, 8], obstacles[m, 5] - z)
    radial_x = radial_y = wall_x = wall_y = 0.0
    if m < n_cylinders:
        radial_x, radial_y = x - obstacles[m, 0], y - obstacles[m, 1]
        side = math.hypot(radial_x, radial_y) - obstacles[m, 2]
    else:
        wall_x = max(x - obstacles[m, 6], obstacles[m, 3] - x)
        wall_y = max(y - obstacles[m, 7], obstacles[m, 4] - y)
        side = max(wall_x, wall_y)
    if cap > side:
        return 0.0, 0.0, 1.0 if z >= 0.5 * (obstacles[m, 5] + obstacles[m, 8]) else -1.0
    if m < n_cylinders:
        length = math.sqrt(radial_x * radial_x + radial_y * radial_y)
        return radial_x / length, radial_y / length, 0.0
    if wall_x >= wall_y:
        return 1.0 if x >= 0.5 * (obstacles[m, 3] + obstacles[m, 6]) else -1.0, 0.0, 0.0
    return 0.0, 1.0 if y >= 0.5 * (obstacles[m, 4] + obstacles[m, 7]) else -1.0, 0.0
