"""What a team localization env is made of: its config, the parts built from it, its features and episode start.

``cooperative_localization_v0`` (``CooperativeLocalizationVectorEnv``) is built from these; the team exploration
env reuses the features (``team_observation_bounds``, ``team_observations``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from infonav_gym.compiled import contiguous, kernel
from infonav_gym.config import Interval, check_choice, check_config, check_config_arguments, config_keys
from infonav_gym.envs.base import EPISODE_STEPS
from infonav_gym.estimation.state import INITIAL_POSE_STD, POSE_DIM
from infonav_gym.information import gaussian_entropy_from_log_det
from infonav_gym.multi.team import DEFAULT_OUTAGE, RobotSuite, gps_receivers, parse_suites
from infonav_gym.multi.team_sensing import SensingPairs, team_prior
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.odometry import OdometrySensor, odometry_sensor_from_config
from infonav_gym.sensors.relative_pose import RELATIVE_POSE_SENSORS
from infonav_gym.world.physics import TIME_STEP_S
from infonav_gym.world.scenarios import (
    DEFAULT_WAYPOINTS,
    MAX_ROBOTS,
    TEAM_FIELD_ARGUMENTS,
    scenario_from_config,
    scenario_names,
    team_route_bands,
)
from infonav_gym.world.world_batch import start_poses

ESTIMATORS = ("joint", "independent")
TEAM_SCENARIO_KEYS = {  # scenario builder parameter: the config key that gives it
    "n_robots": "n_robots",
    "n_obstacles": "n_obstacles",
    "n_canopies": "n_canopies",
    "size_m": "field_size_m",
    "speed_mps": "speed_mps",
}
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "max_cycles": EPISODE_STEPS,
    "n_robots": Interval(2, MAX_ROBOTS, integer=True),  # a team; team_field: no more than fit in it
    "team_reward": Interval(0.0, 1.0),
    "time_step_s": TIME_STEP_S,
    **INITIAL_POSE_STD,
}


def team_localization_config() -> dict:
    """A fresh dict of every config key of ``cooperative_localization_v0`` with its default."""
    return {
        "max_cycles": 200,  # episode length [steps]; all agents are truncated after it
        "scenario": "team_field",  # "team_field" (random loops), "convoy" (the paper's Fig. 3), or registered
        "n_robots": 4,
        "robot_sensors": None,  # one suite per robot, e.g. ["gps+laser", "vision"]; None: the default team
        "gps_outages": (DEFAULT_OUTAGE,),  # (robot, start_s, end_s) spans without DGPS [s]
        "estimator": "joint",  # "joint" (cross-covariances) or "independent" (drops them)
        "team_reward": 0.0,  # weight of the team's MI in each robot's reward, in [0, 1]
        "observe_gains": False,  # True: each observation ends with the expected reward of each action
        "invalid_action": "noop",  # a masked action: "noop" or "raise" (ValueError)
        "time_step_s": 0.5,  # [s]
        "speed_mps": 1.0,  # cruise speed along the routes [m/s]
        "gps_std_m": 0.1,  # DGPS position noise per coordinate [m]
        "odometry_speed_std_mps": 0.05,  # [m/s]
        "odometry_turn_rate_std_rps": 0.02,  # [rad/s]
        "initial_position_std_m": 0.1,  # [m]
        "initial_heading_std_rad": 0.02,  # [rad]
        "n_obstacles": 6,  # team_field only
        "n_canopies": 2,  # GPS-denied zones, team_field only
        "field_size_m": 40.0,  # side of the square field, team_field only [m]
        "render_size_px": 600,  # longer side of rendered frames [px]
    }


class TeamParts(NamedTuple):
    """The sensors of a team of R robots, as its config gives them.

    Attributes:
        suites: what each robot carries besides odometry (R,).
        gps: each robot's ``GPSSensor`` (with its outage spans), None without DGPS (R,).
        pairs: the (observer, target) pairs of the robots with a relative-pose sensor.
        odometry: every robot's odometry sensor.
    """

    suites: tuple[RobotSuite, ...]
    gps: list[GPSSensor | None]
    pairs: SensingPairs
    odometry: OdometrySensor

    @classmethod
    def of_config(cls, config: dict, owner: str) -> TeamParts:
        """Check the team keys of a merged config and build the team's sensors.

        Raises:
            ValueError: naming ``owner`` and the key, for a bad scenario, estimator, number, sensor suite, outage
                or a team that does not fit in its field.
        """
        check_choice(config, "scenario", scenario_names(team=True), owner)
        check_choice(config, "estimator", ESTIMATORS, owner)
        check_config(config, owner, CONFIG_INTERVALS)
        check_config_arguments(
            config, owner, "team_field", TEAM_FIELD_ARGUMENTS, TEAM_SCENARIO_KEYS
        )  # the convoy's too
        n_robots = config["n_robots"]
        if config["scenario"] == "team_field":
            with config_keys(owner, {"n_robots": "n_robots"}):
                team_route_bands(n_robots, config["field_size_m"], DEFAULT_WAYPOINTS)
        suites = parse_suites(config["robot_sensors"], n_robots, config["scenario"])
        gps = gps_receivers(config, suites, owner)
        relative_sensors = [RELATIVE_POSE_SENSORS.get(suite.relative_sensor) for suite in suites]
        return cls(suites, gps, SensingPairs.of_team(relative_sensors), odometry_sensor_from_config(config, owner))


OWN_FEATURES = 10  # a robot's own features; then TEAMMATE_FEATURES per robot of the team
TEAMMATE_FEATURES = 5
_BIG = 1e4  # the bound of the unbounded features


def team_observation_bounds(n_robots: int, observe_gains: bool) -> tuple[np.ndarray, np.ndarray]:
    """The bounds (low, high) of one robot's ``team_observations`` features, float32."""
    own_low, own_high = [-_BIG, -_BIG, -1, -1, 0, 0, 0, -100, 0, 0], [_BIG, _BIG, 1, 1, _BIG, _BIG, _BIG, 100, 1, 1]
    teammate_low, teammate_high = [0, 0, -1, -1, 0], [1, _BIG, 1, 1, _BIG]
    gain_low, gain_high = ([0] * (n_robots + 1), [_BIG] * (n_robots + 1)) if observe_gains else ([], [])
    low = np.array(own_low + teammate_low * n_robots + gain_low, dtype=np.float32)
    high = np.array(own_high + teammate_high * n_robots + gain_high, dtype=np.float32)
    return low, high


def start_episode(config: dict, np_random: np.random.Generator, owner: str):
    """Start an episode of the team env: draw its scenario and the joint estimator's prior from ``np_random``.

    Draws in a fixed order (the scenario, the sensors' generators, the initial estimates).

    Args:
        config: a checked ``cooperative_localization_v0`` config.
        np_random: the episode's generator.
        owner: the env named in config errors.

    Returns:
        ``(scenario, poses, covariances, odometry_rng, gps_rng, relative_rng)``: the team scenario
        ``config["scenario"]`` (one route per robot), the robots' initial estimates (R, 3) and their
        covariances (R, 3, 3) (the ``JointEKF`` prior, no cross-covariance) and the sensors' generators.
    """
    n = config["n_robots"]
    scenario = scenario_from_config(config, np_random, TEAM_SCENARIO_KEYS, owner, n)
    odometry_rng, gps_rng, relative_rng = np_random.spawn(3)
    initial, covariances = team_prior(config, np.array(start_poses(scenario)), np_random)
    return scenario, initial, covariances, odometry_rng, gps_rng, relative_rng


def team_observations(
    estimates, pose_std, pose_log_det, gps_available, elapsed_fraction, teammate_valid, space: spaces.Box, gains=None
) -> np.ndarray:
    """Every robot's observation (see ``CooperativeLocalizationEnv``), float32 clipped to ``space``, for N copies of
    R robots.

    Args:
        estimates: estimated poses (N, R, 3).
        pose_std: x, y, heading standard deviations of each robot at the prior (N, R, 3).
        pose_log_det: ``ln det`` of each robot's pose covariance at the prior (N, R).
        gps_available: whether each robot has a DGPS fix now (N, R) bool.
        elapsed_fraction: elapsed fraction of ``max_cycles`` of each copy (N,).
        teammate_valid: whether each robot may observe each robot now (N, R, R) bool.
        space: one robot's observation space.
        gains: each robot's ``action_information_gain`` (N, R, R + 1) to append (``observe_gains``), or None.

    Returns:
        (N, R, 10 + 5 R), or (N, R, 11 + 6 R) with ``gains``.
    """
    n_copies, n_robots = estimates.shape[:2]
    features = np.zeros((n_copies, n_robots, space.shape[0]), dtype=np.float32)
    entropy = gaussian_entropy_from_log_det(pose_log_det, POSE_DIM)
    gains = np.zeros((n_copies, n_robots, 0)) if gains is None else gains
    arrays = (estimates, pose_std, entropy, gps_available, elapsed_fraction, teammate_valid, gains, space.low)
    team_features(*(contiguous(array) for array in arrays), contiguous(space.high), features)
    return features


@kernel
def team_features(estimates, pose_std, entropy, gps_available, elapsed_fraction, teammate_valid, gains, low, high, out):
    """``team_observations`` of N teams of R robots into ``out`` (N, R, F) float32 (zeros), clipped to [low, high].

    Robot ``i``'s row: its estimate (x, y, cos, sin of the heading), standard deviations, entropy, DGPS flag and
    elapsed fraction; then per robot ``j`` (zeros for ``j = i``): may observe, range, cos and sin of the bearing
    from ``i``'s estimate, ``j``'s position std (hypot of its x, y std); then ``gains`` (B, R, G). Each pair's range
    and each robot's position std are computed once per team (``hypot(-dx, -dy) = hypot(dx, dy)``).
    """
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
                bearing = np.arctan2(dy, dx) - heading
                row[start], row[start + 1] = teammate_valid[team, i, j], ranges[i, j]
                row[start + 2], row[start + 3] = np.cos(bearing), np.sin(bearing)
                row[start + 4] = position_std[j]
            for k in range(gains.shape[2]):
                row[teammates_end + k] = gains[team, i, k]
            for k in range(row.shape[0]):  # as np.clip: NaN stays NaN
                if row[k] < low[k]:
                    row[k] = low[k]
                elif row[k] > high[k]:
                    row[k] = high[k]
