"""What ``cooperative_exploration_v0`` and its planning model are made of: config, parts, features, episode start."""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from infonav_gym.compiled import contiguous, kernel
from infonav_gym.config import Interval, check_config, check_config_arguments, config_keys
from infonav_gym.envs.base import EPISODE_STEPS, MAX_EPISODE_STEPS, REWARD_WEIGHT
from infonav_gym.envs.cooperative_exploration.terrain_map import TerrainMapModel
from infonav_gym.envs.observation_kernels import clip_into, range_bearing_features
from infonav_gym.estimation.state import INITIAL_POSE_STD
from infonav_gym.multi.team import gps_receivers, parse_speeds, parse_suites
from infonav_gym.multi.team_sensing import SensingPairs, team_episode
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.odometry import OdometrySensor, odometry_sensor_from_config
from infonav_gym.sensors.relative_pose import RELATIVE_POSE_SENSORS, RelativePoseSensor
from infonav_gym.world.exploration_scenarios import EXPLORATION_FIELD_ARGUMENTS, exploration_field
from infonav_gym.world.physics import TIME_STEP_S
from infonav_gym.world.scenarios import MAX_ROBOTS, MAX_SPEED_MPS

DEFAULT_SPEEDS_MPS = (0.8, 0.8, 1.2, 1.2)  # robot k of the default team: the DGPS robots are the slower ones
RANGE_KEYS = {"laser": "laser_range_m", "vision": "vision_range_m"}  # the config key of each sensor's range
REWARD_TERMS = ("own_pose_information", "team_map_information", "sensing_cost", "motion_cost", "lost_penalty")
SCENARIO_KEYS = {  # exploration_field parameter: the config key that gives it
    "n_robots": "n_robots",
    "n_obstacles": "n_obstacles",
    "n_canopies": "n_canopies",
    "n_landmarks": "n_landmarks",
    "size_m": "field_size_m",
}
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "max_cycles": EPISODE_STEPS,
    "n_robots": Interval(2, MAX_ROBOTS, integer=True),
    "team_reward": Interval(0.0, 1.0),
    "time_step_s": TIME_STEP_S,
    "turn_time_s": TIME_STEP_S,  # and below time_step_s
    "map_cells_per_side": Interval(2, 100, integer=True),
    "map_prior_std_m": Interval(0.0, 100.0, open_low=True, unit="m"),  # and above covered_std_m
    "scan_radius_m": Interval(0.0, 1000.0, open_low=True, unit="m"),
    "scan_std_m": Interval(1e-3, 100.0, unit="m"),
    "terrain_slope": Interval(0.0, 10.0, unit="m/m"),
    "covered_std_m": Interval(0.0, 100.0, open_low=True, unit="m"),
    "coverage_target": Interval(0.0, 1.0, open_low=True),
    "max_position_std_m": Interval(0.0, 1000.0, open_low=True, unit="m"),  # and above initial_position_std_m
    "max_observations": Interval(0, MAX_EPISODE_STEPS, integer=True),
    **INITIAL_POSE_STD,
    **{key: REWARD_WEIGHT for key in ("observation_cost_nats", "motion_cost_per_step", "lost_penalty")},
}
FLOORS = (  # (key, the key it must exceed)
    ("max_position_std_m", "initial_position_std_m"),
    ("map_prior_std_m", "covered_std_m"),
    ("time_step_s", "turn_time_s"),
)
LANDMARK_FEATURES = 4  # per landmark: valid, range, cos and sin of the bearing
_BIG = 1e4  # the bound of the unbounded features


def exploration_config() -> dict:
    """A fresh dict of every config key of ``cooperative_exploration_v0`` with its default."""
    return {
        "max_cycles": 200,  # episode length [steps]
        "n_robots": 4,
        "robot_sensors": None,  # one suite per robot, e.g. ["gps+laser", "vision"]; None: the default team
        "robot_speeds_mps": None,  # one cruise speed per robot [m/s]; None: DEFAULT_SPEEDS_MPS
        "gps_outages": (),  # (robot, start_s, end_s) spans without DGPS [s], besides the canopies
        "team_reward": 0.5,  # weight of the team's map information against the own pose MI, in [0, 1]
        "observe_gains": False,  # True: each observation ends with the expected gain of each action (as the planner)
        "invalid_action": "noop",  # a masked action: "noop" or "raise" (ValueError)
        "time_step_s": 1.0,  # [s]
        "turn_time_s": 0.25,  # the turn phase of a step: a robot turns on the spot, then drives straight [s]
        "laser_range_m": 10.0,  # range of the lasers, on landmarks and teammates [m]
        "vision_range_m": 8.0,  # range of the cameras [m]
        "gps_std_m": 0.1,  # DGPS position noise per coordinate [m]
        "odometry_speed_std_mps": 0.05,  # [m/s]
        "odometry_turn_rate_std_rps": 0.02,  # [rad/s]
        "initial_position_std_m": 0.1,  # [m]
        "initial_heading_std_rad": 0.02,  # [rad]
        "max_position_std_m": 1.5,  # a robot whose largest position std exceeds this is lost [m]
        "max_observations": 100,  # sensing budget of each robot per episode
        "observation_cost_nats": 0.05,  # [nats] per observation
        "motion_cost_per_step": 0.01,  # [nats] per step driven
        "lost_penalty": 10.0,  # [nats], subtracted from every robot's reward when one is lost
        "map_cells_per_side": 20,  # the coverage map is a grid of this many cells squared (2 m cells)
        "map_prior_std_m": 1.0,  # terrain height std of an unscanned cell [m]
        "scan_radius_m": 4.0,  # a scan sees the cells whose centre lies this close [m]
        "scan_std_m": 0.1,  # height noise of a scan from a known position [m]
        "terrain_slope": 0.5,  # height error per metre of position error [m/m]
        "covered_std_m": 0.3,  # a cell is covered once its height std is at most this [m]
        "coverage_target": 0.6,  # success: this fraction of the cells covered, no robot lost
        "n_obstacles": 6,
        "n_canopies": 3,  # GPS-denied zones
        "n_landmarks": 4,
        "field_size_m": 40.0,  # side of the square field [m]
        "render_size_px": 600,  # longer side of rendered frames [px]
    }


class ExplorationParts(NamedTuple):
    """The team and map of ``cooperative_exploration_v0`` from its config: each robot's cruise speed (R,) [m/s],
    ``GPSSensor`` (with its outage spans) or None, ``RelativePoseSensor`` at the env's range (its range-bearing part
    sees the landmarks) or None, the (observer, target) ``pairs``, the odometry and the terrain ``map_model``."""

    speeds_mps: np.ndarray
    gps: list[GPSSensor | None]
    relative_sensors: list[RelativePoseSensor | None]
    pairs: SensingPairs
    odometry: OdometrySensor
    map_model: TerrainMapModel

    @classmethod
    def of_config(cls, config: dict, owner: str) -> ExplorationParts:
        """Check the keys of a merged config and build the team and its map (``ValueError`` naming ``owner`` and the
        key, for a number outside its interval or not above its floor, a bad field argument, suite, speed or outage)."""
        check_config(config, owner, CONFIG_INTERVALS)
        check_config_arguments(config, owner, "exploration_field", EXPLORATION_FIELD_ARGUMENTS, SCENARIO_KEYS)
        for key, floor in FLOORS:
            if config[key] <= config[floor]:
                raise ValueError(
                    f"config key {key!r} of {owner} must exceed {floor} ({config[floor]}), got {config[key]}"
                )
        n_robots = config["n_robots"]
        suites = parse_suites(config["robot_sensors"], n_robots, "exploration_field")
        speeds = np.array(parse_speeds(config["robot_speeds_mps"], DEFAULT_SPEEDS_MPS, n_robots, MAX_SPEED_MPS))
        gps = gps_receivers(config, suites, owner)
        relative_sensors = [ranged_sensor(config, suite.relative_sensor, owner) for suite in suites]
        map_model = TerrainMapModel.square(
            config["field_size_m"],
            config["map_cells_per_side"],
            prior_std_m=config["map_prior_std_m"],
            **{name: config[name] for name in ("scan_radius_m", "scan_std_m", "terrain_slope", "covered_std_m")},
        )
        odometry = odometry_sensor_from_config(config, owner)
        return cls(speeds, gps, relative_sensors, SensingPairs.of_team(relative_sensors), odometry, map_model)


def ranged_sensor(config: dict, name: str | None, owner: str) -> RelativePoseSensor | None:
    """The relative-pose sensor ``name`` at the config's range for it (``RANGE_KEYS``), None for no sensor."""
    if name is None:
        return None
    sensor, key = RELATIVE_POSE_SENSORS[name], RANGE_KEYS[name]
    with config_keys(owner, {"max_range_m": key}):
        return replace(sensor, range_bearing=replace(sensor.range_bearing, max_range_m=config[key]))


def start_episode(config: dict, np_random: np.random.Generator):
    """Draw an episode's field and joint EKF prior from ``np_random``: ``(scenario, poses (R, 3), covariances
    (R, 3, 3), odometry_rng, gps_rng, relative_rng, landmark_rng)`` (``team_episode``)."""
    scenario = exploration_field(np_random, **{name: config[key] for name, key in SCENARIO_KEYS.items()})
    return team_episode(config, scenario, np_random, 4)


def exploration_observation_bounds(team_low, team_high, n_landmarks: int, n_cells: int, n_gains: int = 0) -> tuple:
    """The bounds (low, high) of one robot's observation, float32: the team features (``team_low``,
    ``team_high``), then landmarks, extras, the map and ``n_gains`` action gains (``observe_gains``)."""
    low = [*team_low, *[0, 0, -1, -1] * n_landmarks, 0, 0, 0, *[0] * n_cells, *[0] * n_gains]
    high = [*team_high, *[1, _BIG, 1, 1] * n_landmarks, _BIG, 1, 1, *[1] * n_cells, *[_BIG] * n_gains]
    return np.array(low, dtype=np.float32), np.array(high, dtype=np.float32)


def exploration_observations(
    team, landmark_valid, landmarks_seen, speeds_mps, budget_left, coverage, cell_std, space, gains=None
) -> np.ndarray:
    """Every robot's observation (see ``CooperativeExplorationEnv``), float32 clipped to ``space``, of N teams of R
    robots: the ``team_observations`` part (N, R, 10 + 5 R), whether observing each landmark is valid (N, R, L), its
    range [m] and bearing [rad] from the robot's estimate (N, R, L, 2), each robot's speed (R,) [m/s], budget left
    (fraction, (N, R)), the coverage (N,), each cell's height std left (fraction of the prior's, (N, G)) and the
    ``action_information_gain`` (N, R, A) to append (``observe_gains``) or None."""
    features = np.empty((*np.shape(team)[:2], space.shape[0]), dtype=np.float32)
    gains = np.zeros((*np.shape(team)[:2], 0)) if gains is None else gains
    arrays = (landmark_valid, landmarks_seen, speeds_mps, budget_left, coverage, cell_std, gains, space.low, space.high)
    floats = (contiguous(np.asarray(array, dtype=float)) for array in arrays)  # the team part stays float32
    exploration_features(contiguous(np.asarray(team, dtype=np.float32)), *floats, features)
    return features


@kernel
def exploration_features(
    team, landmark_valid, landmarks_seen, speeds_mps, budget_left, coverage, cell_std, gains, low, high, out
):
    """``exploration_observations`` (``team`` float32, the others float64 arrays, ``space``'s bounds) into ``out``."""
    n_copies, n_robots, n_team = team.shape
    n_landmarks, n_cells = landmark_valid.shape[2], cell_std.shape[1]
    extras = n_team + LANDMARK_FEATURES * n_landmarks
    values = np.empty(len(low))
    for c in range(n_copies):
        for i in range(n_robots):
            for k in range(n_team):
                values[k] = team[c, i, k]
            for k in range(n_landmarks):
                start = n_team + LANDMARK_FEATURES * k
                values[start] = landmark_valid[c, i, k]
                range_m, bearing = landmarks_seen[c, i, k, 0], landmarks_seen[c, i, k, 1]
                range_bearing_features(values[start + 1 : start + LANDMARK_FEATURES], range_m, bearing)
            values[extras], values[extras + 1], values[extras + 2] = speeds_mps[i], budget_left[c, i], coverage[c]
            for k in range(n_cells):
                values[extras + 3 + k] = cell_std[c, k]
            for k in range(gains.shape[2]):
                values[extras + 3 + n_cells + k] = gains[c, i, k]
            clip_into(out[c, i], values, low, high)
