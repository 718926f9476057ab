"""Compiled segment queries of ``world.visibility``: Chipmunk's tests, one query and one shape at a time.

The floating-point operations of ``pymunk``'s ``segment_query_first`` at radius 0 in its order (``world.visibility``);
a NaN in a comparison makes it false.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import inline, inlined_kernel, inner_kernel, kernel
from infonav_gym.geometry import wrap_angle_kernel as wrap

SMALLEST_NORMAL = np.finfo(float).tiny  # Chipmunk's CPFLOAT_MIN, added to a length before dividing by it
WALL, DISC = 0, 1  # the shape kinds of ``shape_hits``


@inner_kernel
def enters_box(left, bottom, right, top, origin_x, origin_y, delta_x, delta_y) -> bool:
    """Whether a query enters the box before its end (Chipmunk's ``cpBBSegmentQuery`` < 1)."""
    t_min, t_max = -np.inf, np.inf
    for low, high, start, delta in ((left, right, origin_x, delta_x), (bottom, top, origin_y, delta_y)):
        if delta != 0.0:
            t_low, t_high = (low - start) / delta, (high - start) / delta
            entering = t_low if t_low < t_high else t_high
            leaving = t_low if t_low > t_high else t_high
            if math.isnan(entering) or math.isnan(leaving) or math.isnan(t_min) or math.isnan(t_max):
                return False
            t_min, t_max = max(t_min, entering), min(t_max, leaving)
        elif start < low or high < start:
            return False
    return t_min <= t_max and 0.0 <= t_max and t_min < 1.0


@inner_kernel
def hits_circle(center_x, center_y, radius, origin_x, origin_y, target_x, target_y) -> bool:
    """Whether a query enters the circle before its target (Chipmunk's ``CircleSegmentQuery``, alpha < 1)."""
    da_x, da_y, db_x, db_y = origin_x - center_x, origin_y - center_y, target_x - center_x, target_y - center_y
    da_da, da_db, db_db = da_x * da_x + da_y * da_y, da_x * db_x + da_y * db_y, db_x * db_x + db_y * db_y
    qa = da_da - 2.0 * da_db + db_db
    qb = da_db - da_da
    rsum = radius + 0.0
    det = qb * qb - qa * (da_da - rsum * rsum)
    if not det >= 0.0:
        return False
    t = (-qb - math.sqrt(det)) / qa
    return 0.0 <= t and t < 1.0


@inner_kernel
def hits_wall(origin_x, origin_y, target_x, target_y, a_x, a_y, b_x, b_y, r) -> bool:
    """Whether a query hits the wall (capsule ``a``-``b`` of radius ``r``) before its target."""
    # the point query at the origin (cpSegmentShapePointQuery): inside or on the wall blocks at once
    along_x, along_y = a_x - b_x, a_y - b_y
    fraction = (along_x * (origin_x - b_x) + along_y * (origin_y - b_y)) / (along_x * along_x + along_y * along_y)
    fraction = fraction if fraction < 1.0 else 1.0
    fraction = 0.0 if 0.0 > fraction else fraction
    offset_x, offset_y = origin_x - (b_x + along_x * fraction), origin_y - (b_y + along_y * fraction)
    if math.sqrt(offset_x * offset_x + offset_y * offset_y) - r <= 0.0:
        return True
    # the segment query (cpSegmentShapeSegmentQuery): through the near face, else into an end disc
    wall_x, wall_y = b_x - a_x, b_y - a_y
    inverse_length = 1.0 / (math.sqrt(wall_x * wall_x + wall_y * wall_y) + SMALLEST_NORMAL)
    normal_x, normal_y = wall_y * inverse_length, -(wall_x * inverse_length)
    d = (a_x - origin_x) * normal_x + (a_y - origin_y) * normal_y
    r_query = r + 0.0
    beyond = d > 0.0
    face_x = (-normal_x if beyond else normal_x) * r_query - origin_x
    face_y = (-normal_y if beyond else normal_y) * r_query - origin_y
    delta_x, delta_y = target_x - origin_x, target_y - origin_y
    cross_a = delta_x * (a_y + face_y) - delta_y * (a_x + face_x)
    cross_b = delta_x * (b_y + face_y) - delta_y * (b_x + face_x)
    if cross_a * cross_b <= 0.0:  # through the face
        d_offset = d + (-r_query if beyond else r_query)
        ad = -d_offset
        bd = (delta_x * normal_x + delta_y * normal_y) - d_offset
        return ad * bd < 0.0 and ad / (ad - bd) < 1.0
    if r_query == 0.0:
        return False
    return hits_circle(a_x, a_y, r, origin_x, origin_y, target_x, target_y) or hits_circle(
        b_x, b_y, r, origin_x, origin_y, target_x, target_y
    )


@inner_kernel
def hits_disc(origin_x, origin_y, target_x, target_y, center_x, center_y, r) -> bool:
    """Whether a query hits the disc before its target (inside or on it: at once, cpCircleShapePointQuery)."""
    offset_x, offset_y = origin_x - center_x, origin_y - center_y
    if math.sqrt(offset_x * offset_x + offset_y * offset_y) - r <= 0.0:
        return True
    return hits_circle(center_x, center_y, r, origin_x, origin_y, target_x, target_y)


@kernel
def shape_hits(copy, origins, targets, points, radii, boxes, usable, culled, kind):
    """Which shapes (of ``kind``: walls' ends (N, S, 4) or discs' centres (N, S, 2) in ``points``) the M queries
    ``origins`` -> ``targets`` (M, 2) of copies ``copy`` hit where Chipmunk's tree would test them (M, S)."""
    n_queries, n_shapes = len(copy), radii.shape[1]
    hits = np.zeros((n_queries, n_shapes), dtype=np.bool_)
    for query in range(n_queries):
        c = copy[query]
        origin_x, origin_y = origins[query, 0], origins[query, 1]
        target_x, target_y = targets[query, 0], targets[query, 1]
        low_x, high_x = min(origin_x, target_x), max(origin_x, target_x)
        low_y, high_y = min(origin_y, target_y), max(origin_y, target_y)
        for shape in range(n_shapes):
            if not usable[c, shape]:
                continue
            left, bottom, right, top = boxes[c, shape, 0], boxes[c, shape, 1], boxes[c, shape, 2], boxes[c, shape, 3]
            if culled[c]:
                touching = low_x <= right and left <= high_x and low_y <= top and bottom <= high_y
                if not touching:
                    continue
                delta_x, delta_y = target_x - origin_x, target_y - origin_y
                if not enters_box(left, bottom, right, top, origin_x, origin_y, delta_x, delta_y):
                    continue
            p = points[c, shape]
            if kind == WALL:
                hit = hits_wall(origin_x, origin_y, target_x, target_y, p[0], p[1], p[2], p[3], radii[c, shape])
            else:
                hit = hits_disc(origin_x, origin_y, target_x, target_y, p[0], p[1], radii[c, shape])
            hits[query, shape] = hit
    return hits


@kernel
def blocked(copy, origins, targets, walls, discs, culled):
    """Whether each of M queries ``origins`` -> ``targets`` (M, 2) of copy ``copy`` (M,) hits a wall or disc (M,) bool.

    ``walls`` and ``discs``: each shape kind's ``(points, radii, boxes, usable)`` (see ``shape_hits``).
    """
    wall_hits = shape_hits(copy, origins, targets, walls[0], walls[1], walls[2], walls[3], culled, WALL)
    disc_hits = shape_hits(copy, origins, targets, discs[0], discs[1], discs[2], discs[3], culled, DISC)
    hit = np.zeros(len(copy), dtype=np.bool_)
    for query in range(len(copy)):  # a loop, not ndarray.any (one more numba function to compile)
        for shape in range(wall_hits.shape[1]):
            hit[query] |= wall_hits[query, shape]
        for shape in range(disc_hits.shape[1]):
            hit[query] |= disc_hits[query, shape]
    return hit


@inlined_kernel
def covered(poses, targets, max_range_m, fov_rad):
    """Whether each target (N, K, 2) [m] lies within ``max_range_m`` and the field of view ``fov_rad`` around the
    heading of its copy's pose (N, 3): (N, K) bool (``RangeBearingSensor.in_coverage`` of the noise-free reading)."""
    n_copies, n_targets = targets.shape[0], targets.shape[1]
    inside = np.zeros((n_copies, n_targets), dtype=np.bool_)
    for c in range(n_copies):
        for k in range(n_targets):
            dx, dy = targets[c, k, 0] - poses[c, 0], targets[c, k, 1] - poses[c, 1]
            inside[c, k] = within_coverage(dx, dy, poses[c, 2], max_range_m, 0.5 * fov_rad)
    return inside


@inline
def within_coverage(dx, dy, heading, max_range_m, half_fov_rad) -> bool:
    """Whether a target at offset ``(dx, dy)`` [m] from a sensor heading ``heading`` [rad] lies within ``max_range_m``
    and ``half_fov_rad`` of the heading."""
    return math.hypot(dx, dy) <= max_range_m and abs(wrap(math.atan2(dy, dx) - heading)) <= half_fov_rad
