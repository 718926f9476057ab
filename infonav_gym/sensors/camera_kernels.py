"""Compiled radiometry of ``sensors.camera``: the ground texture and the shading of the pixels that hit the scene.

The geometry (ground and obstacle normals) is ``world.terrain_kernels``'; the ground texture is value noise on a
fixed lattice table (``texture_table`` (octaves, 256 * 256), lattice point ``(i, j)`` at ``[(j % 256) * 256 + i %
256]``), one octave per ``texture_cells`` [m] weighted by ``texture_weights``.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import inline, kernel
from infonav_gym.world.terrain_kernels import GROUND, blend, cell_normal, cell_position, obstacle_normal

TEXTURE_TABLE_SIZE = 256  # lattice values repeat every 256 cells
_WRAP = TEXTURE_TABLE_SIZE - 1  # & _WRAP == % TEXTURE_TABLE_SIZE, also for negative cells


@inline
def smoothstep(fraction):
    """``fraction**2 * (3 - 2 * fraction)``: the lattice weight of an offset in [0, 1)."""
    return fraction * fraction * (fraction * -2.0 + 3.0)


@inline
def lattice_cell(u, v):
    """The table indices ``(lower left, lower right, upper left, upper right)`` of the lattice cell around ``(u, v)``
    [cells] and the smoothstep weights of the offsets in it."""
    corner_u, corner_v = math.floor(u), math.floor(v)
    column, row = int(corner_u) & _WRAP, (int(corner_v) & _WRAP) * TEXTURE_TABLE_SIZE
    next_column, next_row = (column + 1) & _WRAP, (row + TEXTURE_TABLE_SIZE) & (_WRAP * TEXTURE_TABLE_SIZE)
    corners = row + column, row + next_column, next_row + column, next_row + next_column
    return *corners, smoothstep(u - corner_u), smoothstep(v - corner_v)


@inline
def texture(texture_table, cells_per_m, texture_weights, x, y):
    """Value noise at world ``(x, y)`` [m], in [-1, 1]: the octaves' weighted mean (``cells_per_m``: 1 / cell)."""
    total, weight_sum = 0.0, 0.0
    for octave in range(cells_per_m.shape[0]):
        lower_left, lower_right, upper_left, upper_right, weight_u, weight_v = lattice_cell(
            x * cells_per_m[octave], y * cells_per_m[octave]
        )
        table = texture_table[octave]
        value = blend(table[lower_left], table[lower_right], table[upper_left], table[upper_right], weight_u, weight_v)
        total += (value * 2.0 - 1.0) * texture_weights[octave]
        weight_sum += texture_weights[octave]
    return total / weight_sum


@kernel
def textures(points, texture_table, texture_cells, texture_weights):
    """``texture`` at each of points (N, 2) [m]: (N,)."""
    values, cells_per_m = np.empty(points.shape[0]), 1.0 / texture_cells
    for n in range(points.shape[0]):
        values[n] = texture(texture_table, cells_per_m, texture_weights, points[n, 0], points[n, 1])
    return values


@inline
def sun_cosine(sun, normal_x, normal_y, normal_z):
    """The cosine between the unit vector ``sun`` (3,) and a unit normal."""
    return normal_x * sun[0] + normal_y * sun[1] + normal_z * sun[2]


@inline
def lit_level(albedo, cosine, radiometry):
    """The gray level of a surface of ``albedo`` whose normal makes ``cosine`` with the sun (``shade``'s
    ``radiometry``)."""
    _, _, ambient, exposure, _, _ = radiometry
    return exposure * albedo * (ambient + (1.0 - ambient) * max(cosine, 0.0))


@kernel
def shade(arrays, origin, azimuth, elevation, range_m, material, obstacle, radiometry, texture_arrays):
    """Noise-free gray levels (R, C) of the rays ``Terrain.cast_rays`` cast from ``origin`` (3,) at azimuths (C,)
    and elevations (R,) [rad] into ``arrays``, with its hits (R, C) (the model: ``camera`` module).

    ``radiometry``: ``(albedos (4,), sun (3,), ambient, exposure, contrast, sky_level)``; ``texture_arrays``:
    ``(table, cells, weights)``. Ground pixels are shaded in loops that each do one thing (vectorized by the
    compiler); they stay in this kernel, as ``first_hits``' do.
    """
    grid, obstacles, _, n_cylinders = arrays
    albedos, sun, _, _, contrast, sky_level = radiometry
    texture_table, texture_cells, texture_weights = texture_arrays
    rows, columns = range_m.shape
    cells_per_m = 1.0 / texture_cells
    weight_sum = 0.0
    for octave in range(texture_weights.shape[0]):
        weight_sum += texture_weights[octave]
    cos_azimuth, sin_azimuth = np.empty(columns), np.empty(columns)
    for c in range(columns):
        cos_azimuth[c], sin_azimuth[c] = math.cos(azimuth[c]), math.sin(azimuth[c])
    flat_heights, grid_columns = grid[0].ravel(), grid[0].shape[1]
    ground_column, ground_x, ground_y = np.empty(columns, np.int64), np.empty(columns), np.empty(columns)
    index, tx, ty = np.empty(columns, np.int64), np.empty(columns), np.empty(columns)  # the cells under the points
    lower_left, lower_right = np.empty(columns), np.empty(columns)  # the corner values read at computed indices
    upper_left, upper_right = np.empty(columns), np.empty(columns)
    lattice = np.empty((4, columns), np.int64)  # the texture table's indices of a lattice cell's corners
    cosine, texture_sum, albedo = np.empty(columns), np.empty(columns), np.empty(columns)
    levels = np.empty((rows, columns))
    for r in range(rows):
        cos_elevation, sin_elevation = math.cos(elevation[r]), math.sin(elevation[r])
        n_ground = 0
        for c in range(columns):
            distance = range_m[r, c]
            if not math.isfinite(distance):
                levels[r, c] = sky_level
                continue
            x = origin[0] + cos_elevation * cos_azimuth[c] * distance
            y = origin[1] + cos_elevation * sin_azimuth[c] * distance
            if material[r, c] == GROUND:
                ground_column[n_ground], ground_x[n_ground], ground_y[n_ground] = c, x, y
                n_ground += 1
                continue
            z = origin[2] + sin_elevation * distance
            normal_x, normal_y, normal_z = obstacle_normal(obstacles, obstacle[r, c], n_cylinders, x, y, z)
            levels[r, c] = lit_level(albedos[material[r, c]], sun_cosine(sun, normal_x, normal_y, normal_z), radiometry)
        for q in range(n_ground):
            i, j, tx[q], ty[q] = cell_position(grid, ground_x[q], ground_y[q])
            index[q] = i * grid_columns + j
        for q in range(n_ground):
            corner = index[q]
            lower_left[q], lower_right[q] = flat_heights[corner], flat_heights[corner + 1]
            upper_left[q], upper_right[q] = flat_heights[corner + grid_columns], flat_heights[corner + grid_columns + 1]
        for q in range(n_ground):
            corners = lower_left[q], lower_right[q], upper_left[q], upper_right[q]
            normal_x, normal_y, normal_z = cell_normal(grid, ground_x[q], ground_y[q], *corners, tx[q], ty[q])
            cosine[q] = sun_cosine(sun, normal_x, normal_y, normal_z)
        if contrast > 0.0:
            for q in range(n_ground):
                texture_sum[q] = 0.0
            for octave in range(cells_per_m.shape[0]):
                table = texture_table[octave]
                for q in range(n_ground):
                    corners = lattice_cell(ground_x[q] * cells_per_m[octave], ground_y[q] * cells_per_m[octave])
                    lattice[0, q], lattice[1, q], lattice[2, q], lattice[3, q], tx[q], ty[q] = corners
                for q in range(n_ground):
                    lower_left[q], lower_right[q] = table[lattice[0, q]], table[lattice[1, q]]
                    upper_left[q], upper_right[q] = table[lattice[2, q]], table[lattice[3, q]]
                for q in range(n_ground):
                    value = blend(lower_left[q], lower_right[q], upper_left[q], upper_right[q], tx[q], ty[q])
                    texture_sum[q] += (value * 2.0 - 1.0) * texture_weights[octave]
            for q in range(n_ground):
                albedo[q] = albedos[GROUND] * (1.0 + contrast * (texture_sum[q] / weight_sum))
        else:
            for q in range(n_ground):
                albedo[q] = albedos[GROUND]
        for q in range(n_ground):
            levels[r, ground_column[q]] = lit_level(albedo[q], cosine[q], radiometry)
    return levels
