"""What a robot of a team env observes: its own estimate and uncertainty, each teammate's range, bearing and
uncertainty."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from infonav_gym.compiled import contiguous, kernel
from infonav_gym.envs.observation_kernels import clip_into, range_bearing_features
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.information import gaussian_entropy_from_log_det

OWN_FEATURES = 10  # a robot's own features; then TEAMMATE_FEATURES per robot of the team
TEAMMATE_FEATURES = 5
_BIG = 1e4  # the bound of the unbounded features


def team_observation_bounds(n_robots: int, observe_gains: bool) -> tuple[np.ndarray, np.ndarray]:
    """The bounds (low, high) of one robot's ``team_observations`` features, float32."""
    own_low, own_high = [-_BIG, -_BIG, -1, -1, 0, 0, 0, -100, 0, 0], [_BIG, _BIG, 1, 1, _BIG, _BIG, _BIG, 100, 1, 1]
    teammate_low, teammate_high = [0, 0, -1, -1, 0], [1, _BIG, 1, 1, _BIG]
    gain_low, gain_high = ([0] * (n_robots + 1), [_BIG] * (n_robots + 1)) if observe_gains else ([], [])
    low, high = own_low + teammate_low * n_robots + gain_low, own_high + teammate_high * n_robots + gain_high
    return np.array(low, dtype=np.float32), np.array(high, dtype=np.float32)


def team_observations(state, decision, rows, horizon: int, teammate_valid, space: spaces.Box, gains=None) -> np.ndarray:
    """Every robot's observation (see ``CooperativeLocalizationEnv``) in the copies ``rows`` of a ``TeamState`` at their
    ``decision``, float32 clipped to ``space``: (n, R, 10 + 5 R), or (n, R, 11 + 6 R) with the ``gains`` (n, R, R + 1);
    ``horizon``: ``max_cycles`` [steps]; who may observe whom now ``teammate_valid`` (n, R, R) bool."""
    gps_available = state.gps_available[rows]
    features = np.zeros((*gps_available.shape, space.shape[0]), dtype=np.float32)
    entropy = gaussian_entropy_from_log_det(decision.pose_log_det, POSE_DIM)
    gains = np.zeros((*gps_available.shape, 0)) if gains is None else gains
    estimates, elapsed_fraction = state.x[rows].reshape(*gps_available.shape, POSE_DIM), state.elapsed[rows] / horizon
    arrays = (estimates, decision.pose_std, entropy, gps_available, elapsed_fraction, teammate_valid, gains, space.low)
    team_features(*(contiguous(array) for array in arrays), contiguous(space.high), features)
    return features


@kernel
def team_features(estimates, pose_std, entropy, gps_available, elapsed_fraction, teammate_valid, gains, low, high, out):
    """``team_observations`` into ``out`` (N, R, F) float32 (zeros), clipped to [low, high]; each pair's range and each
    robot's position std (the hypot of its x, y std) are computed once per team."""
    n_teams, n_robots = estimates.shape[0], estimates.shape[1]
    teammates_end = OWN_FEATURES + TEAMMATE_FEATURES * n_robots
    ranges, position_std = np.empty((n_robots, n_robots)), np.empty(n_robots)
    for team in range(n_teams):
        for j in range(n_robots):
            position_std[j] = np.hypot(pose_std[team, j, 0], pose_std[team, j, 1])
            for i in range(j):
                dx, dy = estimates[team, j, 0] - estimates[team, i, 0], estimates[team, j, 1] - estimates[team, i, 1]
                ranges[i, j] = ranges[j, i] = np.hypot(dx, dy)
        for i in range(n_robots):
            row = out[team, i]
            x, y, heading = estimates[team, i, 0], estimates[team, i, 1], estimates[team, i, 2]
            row[0], row[1], row[2], row[3] = x, y, np.cos(heading), np.sin(heading)
            for k in range(POSE_DIM):
                row[4 + k] = pose_std[team, i, k]
            row[7], row[8], row[9] = entropy[team, i], gps_available[team, i], elapsed_fraction[team]
            for j in range(n_robots):
                if j == i:
                    continue
                start = OWN_FEATURES + TEAMMATE_FEATURES * j
                dx, dy = estimates[team, j, 0] - x, estimates[team, j, 1] - y
                row[start], row[start + 4] = teammate_valid[team, i, j], position_std[j]
                range_bearing_features(row[start + 1 : start + 4], ranges[i, j], np.arctan2(dy, dx) - heading)
            for k in range(gains.shape[2]):
                row[teammates_end + k] = gains[team, i, k]
            clip_into(row, row, low, high)
