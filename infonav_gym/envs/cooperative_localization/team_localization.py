"""What ``cooperative_localization_v0`` is made of: its config, the parts built from it and its episode start."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from infonav_gym.config import Interval, check_choice, check_config, check_config_arguments, config_keys
from infonav_gym.envs.base import EPISODE_STEPS
from infonav_gym.estimation.state import INITIAL_POSE_STD
from infonav_gym.multi.team import DEFAULT_OUTAGE, gps_receivers, parse_suites
from infonav_gym.multi.team_sensing import SensingPairs, team_episode
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
    """The sensors of a team of R robots, as its config gives them (suites: ``parse_suites``): each robot's
    ``GPSSensor`` (with its outage spans) or None, the (observer, target) ``pairs`` and the odometry."""

    gps: list[GPSSensor | None]
    pairs: SensingPairs
    odometry: OdometrySensor

    @classmethod
    def of_config(cls, config: dict, owner: str) -> TeamParts:
        """Check the team keys of a merged config and build the team's sensors (``ValueError`` naming ``owner`` and
        the key, for a bad scenario, estimator, number, sensor suite, outage or a team that does not fit its field)."""
        check_choice(config, "scenario", scenario_names(team=True), owner)
        check_choice(config, "estimator", ESTIMATORS, owner)
        check_config(config, owner, CONFIG_INTERVALS)
        check_config_arguments(config, owner, "team_field", TEAM_FIELD_ARGUMENTS, TEAM_SCENARIO_KEYS)  # and convoy's
        n_robots = config["n_robots"]
        if config["scenario"] == "team_field":
            with config_keys(owner, {"n_robots": "n_robots"}):
                team_route_bands(n_robots, config["field_size_m"], DEFAULT_WAYPOINTS)
        suites = parse_suites(config["robot_sensors"], n_robots, config["scenario"])
        gps = gps_receivers(config, suites, owner)
        relative_sensors = [RELATIVE_POSE_SENSORS.get(suite.relative_sensor) for suite in suites]
        return cls(gps, SensingPairs.of_team(relative_sensors), odometry_sensor_from_config(config, owner))


def start_episode(config: dict, np_random: np.random.Generator, owner: str):
    """Draw an episode from ``np_random`` (``owner``: the env named in config errors): ``(scenario, poses (R, 3),
    covariances (R, 3, 3), odometry_rng, gps_rng, relative_rng)``, the scenario (one route per robot) drawn first
    (``team_episode``)."""
    scenario = scenario_from_config(config, np_random, TEAM_SCENARIO_KEYS, owner, config["n_robots"])
    return team_episode(config, scenario, np_random, 3)
