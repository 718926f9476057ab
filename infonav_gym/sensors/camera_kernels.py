"""Compiled radiometry of ``sensors.camera``: the ground texture and the shading of the pixels that hit the scene.

The geometry (ground and obstacle normals) is ``world.terrain_kernels``'; the ground texture is value noise on a
fixed lattice table (``texture_table`` (octaves, 256 * 256), lattice point ``(i, j)`` at ``[(j % 256) * 256 + i %
256]``), one octave per ``texture_cells`` [m] weighted by ``texture_weights``.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import inline, kernel
from infonav_gym.world.terrain_kernels import GROUND, blend, ground_normal, obstacle_normal

TEXTURE_TABLE_SIZE = 256  # lattice values repeat every 256 cells
_WRAP = TEXTURE_TABLE_SIZE - 1  # & _WRAP == % TEXTURE_TABLE_SIZE, also for negative cells


@inline
def smoothstep(fraction):
    """``fraction**2 * (3 - 2 * fraction)``: the lattice weight of an offset in [0, 1)."""
    return fraction * fraction * (fraction * -2.0 + 3.0)


@inline
def texture(texture_table, cells_per_m, texture_weights, x, y):
    """Value noise at world ``(x, y)`` [m], in [-1, 1]: the octaves' weighted mean (``cells_per_m``: 1 / cell)."""
    total, weight_sum = 0.0, 0.0
    for octave in range(cells_per_m.shape[0]):
        u, v = x * cells_per_m[octave], y * cells_per_m[octave]
        corner_u, corner_v = math.floor(u), math.floor(v)
        column, row = int(corner_u) & _WRAP, (int(corner_v) & _WRAP) * TEXTURE_TABLE_SIZE
        next_column, next_row = (column + 1) & _WRAP, (row + TEXTURE_TABLE_SIZE) & (_WRAP * TEXTURE_TABLE_SIZE)
        table = texture_table[octave]
        value = blend(
            table[row + column],
            table[row + next_column],
            table[next_row + column],
            table[next_row + next_column],
            smoothstep(u - corner_u),
            smoothstep(v - corner_v),
        )
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


@kernel
def shade(arrays, origin, azimuth, elevation, range_m, material, obstacle, radiometry, texture_arrays):
    """Noise-free gray levels (R, C) of the rays from ``origin`` (3,) at column azimuths (C,) and row elevations
    (R,) [rad] that ``Terrain.cast_rays`` cast into the scene ``arrays``, with its hits ``range_m``, ``material``
    and ``obstacle`` (R, C).

    ``radiometry`` is ``(albedos, sun, ambient, exposure, contrast, sky_level)``: the albedo of each material (4,),
    the unit vector towards the sun (3,) and the camera's scalars; ``texture_arrays`` is ``(texture_table,
    texture_cells, texture_weights)``. A pixel without a hit is the sky; a hit pixel reads
    ``exposure * albedo * (ambient + (1 - ambient) * max(0, n . sun))``, the ground's albedo scaled by ``1 +
    contrast * texture``.
    """
    grid, obstacles, _, n_cylinders = arrays
    albedos, sun, ambient, exposure, contrast, sky_level = radiometry
    rows, columns = range_m.shape
    cells_per_m = 1.0 / texture_arrays[1]
    cos_azimuth, sin_azimuth = np.empty(columns), np.empty(columns)
    for c in range(columns):
        cos_azimuth[c], sin_azimuth[c] = math.cos(azimuth[c]), math.sin(azimuth[c])
    levels = np.empty((rows, columns))
    for r in range(rows):
        cos_elevation, sin_elevation = math.cos(elevation[r]), math.sin(elevation[r])
        for c in range(columns):
            distance = range_m[r, c]
            if not math.isfinite(distance):
                levels[r, c] = sky_level
                continue
            x = origin[0] + cos_elevation * cos_azimuth[c] * distance
            y = origin[1] + cos_elevation * sin_azimuth[c] * distance
            z = origin[2] + sin_elevation * distance
            hit_material = material[r, c]
            albedo = albedos[hit_material]
            if hit_material == GROUND:
                normal_x, normal_y, normal_z = ground_normal(grid, x, y)
                if contrast > 0.0:
                    albedo *= 1.0 + contrast * texture(texture_arrays[0], cells_per_m, texture_arrays[2], x, y)
            else:
                normal_x, normal_y, normal_z = obstacle_normal(obstacles, obstacle[r, c], n_cylinders, x, y, z)
            cosine = normal_x * sun[0] + normal_y * sun[1] + normal_z * sun[2]
            levels[r, c] = exposure * albedo * (ambient + (1.0 - ambient) * max(cosine, 0.0))
    return levels
