"""Compiled pieces of the one-robot envs' observations: the pose features both envs lead with, and the clipping.

Values are computed in float64, clipped to the observation space's bounds, then rounded to float32 (the same
numbers as rounding first and clipping to the float32 bounds after).
"""

from __future__ import annotations

import math

from infonav_gym.compiled import inner_kernel

POSE_FEATURES = 10  # x, y, cos, sin of the heading, the pose's three stds, the x-y correlation, entropy, elapsed
BIG = 1e4  # the bound of the unbounded features
POSE_LOW = [-BIG, -BIG, -1, -1, 0, 0, 0, -1, -100, 0]  # the bounds of the ``pose_features``
POSE_HIGH = [BIG, BIG, 1, 1, BIG, BIG, BIG, 1, 100, 1]


@inner_kernel
def pose_features(values, x, P, pose_entropy, elapsed_fraction):
    """One copy's leading features into ``values[:10]``: the estimated ``x, y`` [m], ``cos, sin`` of the heading, the
    standard deviations of ``x, y, heading``, the ``x-y`` correlation, the pose entropy [nats] and the elapsed fraction
    of the horizon; from its state ``x`` (n,) and covariance ``P`` (n, n)."""
    values[0], values[1] = x[0], x[1]
    values[2], values[3] = math.cos(x[2]), math.sin(x[2])
    for i in range(3):
        values[4 + i] = math.sqrt(P[i, i])
    values[7] = P[0, 1] / math.sqrt(P[0, 0] * P[1, 1])
    values[8], values[9] = pose_entropy, elapsed_fraction


@inner_kernel
def range_bearing_features(values, range_m, bearing_rad):
    """``range, cos(bearing), sin(bearing)`` into ``values[:3]``."""
    values[0], values[1], values[2] = range_m, math.cos(bearing_rad), math.sin(bearing_rad)


READING_FEATURES = 4  # per target of a real log: measured flag, measured range [m], cos and sin of the bearing
READING_LOW, READING_HIGH = [0, 0, -1, -1], [1, BIG, 1, 1]  # their bounds


@inner_kernel
def reading_features(values, start, measured, readings):
    """Per target ``k`` of a real log, ``READING_FEATURES`` values from ``values[start + 4 k]`` on: whether it was
    ``measured`` (T,) (1 or 0), its reading's range and ``cos, sin`` of its bearing (``readings`` (T, 2); zeros where
    not measured)."""
    for k in range(len(measured)):
        if measured[k]:
            row = start + READING_FEATURES * k
            values[row] = 1.0
            range_bearing_features(values[row + 1 : row + 4], readings[k, 0], readings[k, 1])


@inner_kernel
def clip_into(row, values, low, high):
    """``values`` (float64) clipped to ``[low, high]`` into the float32 ``row``; NaN stays NaN."""
    for j in range(len(values)):
        value = values[j]
        if value < low[j]:
            value = low[j]
        elif value > high[j]:
            value = high[j]
        row[j] = value
