"""CooperativeExplorationVectorEnv: copy i equals its PettingZoo view (N = 1, no autoreset) seeded seed + i, step for
step, through the episodes' ends (a robot lost, the coverage target reached, the horizon) and the autoresets after
them.

Autoreset modes, seeding, bad input and rendering: ``test_team_vector_envs.py``, for every team vector env.
"""

import filterpy_reference as oracle
import numpy as np
import pytest
from conftest import greedy_actions, random_valid_actions
from team_vector_checks import (
    exploration_observation_updates,
    greedy,
    record_relative_measurements,
    run_against_parallel_envs,
)

from infonav_gym.envs.cooperative_exploration import N_MOTIONS, CooperativeExplorationVectorEnv, scenario
from infonav_gym.envs.cooperative_exploration.exploration_decision import TeamSight
from infonav_gym.multi import cooperative_exploration_v0
from infonav_gym.world import world_batch
from infonav_gym.world.physics import ContactSpace

ID = "cooperative_exploration_v0"


def test_copies_equal_the_parallel_env_through_successes_failures_and_autoresets():
    """Greedy with a random step in three: robots get lost and teams reach the coverage target, then start again."""
    ended = run_against_parallel_envs(ID, {"max_cycles": 150}, 3, 5, "mixed", 260)
    assert ended["terminated"] >= 3


@pytest.mark.parametrize(
    "config",
    [
        {"team_reward": 0.0},
        {"max_observations": 0},
        {"max_observations": 3, "observation_cost_nats": 0.2},
        {"robot_sensors": ["gps+laser", "gps", "laser", "vision"], "gps_outages": [(0, 5.0, 12.0)]},
        {"n_robots": 2, "robot_sensors": ["vision", "gps+vision"], "robot_speeds_mps": [1.5, 0.5]},
        {"n_robots": 3, "n_obstacles": 12, "n_canopies": 1, "field_size_m": 30.0, "map_cells_per_side": 7},
        {"time_step_s": 0.5, "turn_time_s": 0.1, "scan_radius_m": 2.5, "terrain_slope": 2.0},
    ],
    ids=["own-reward", "no-budget", "budget-runs-out", "gps-only-robot", "pair", "small", "short-steps"],
)
def test_copies_equal_the_parallel_env_on_other_teams_maps_and_rewards(config):
    assert run_against_parallel_envs(ID, {"max_cycles": 30, **config}, 2, 3, "mixed", 32)["truncated"] >= 1


@pytest.mark.parametrize(
    "config",
    [
        {"team_reward": 1.0, "coverage_target": 0.1},  # the team succeeds within a few steps
        {"n_landmarks": 0, "max_position_std_m": 0.2, "odometry_speed_std_mps": 0.2},  # a robot is soon lost
    ],
    ids=["covered", "lost"],
)
def test_copies_equal_the_parallel_env_through_many_quick_episode_ends(config):
    assert run_against_parallel_envs(ID, {"max_cycles": 30, **config}, 2, 3, "mixed", 32)["terminated"] >= 4


def test_the_comparison_covers_landmarks_teammates_motions_scans_and_close_passes(monkeypatch):
    """A greedy run observes landmarks and teammates, drives every way, maps cells and passes close to teammates
    or walls (steps ``WorldBatch`` checks are contact-free, then takes as Pymunk's substeps: the masks leave none
    with a contact)."""
    substeps, free_substeps = [], world_batch.free_substeps
    monkeypatch.setattr(
        world_batch, "free_substeps", lambda poses, *args: substeps.append(len(poses)) or free_substeps(poses, *args)
    )
    drive = ContactSpace.drive
    monkeypatch.setattr(ContactSpace, "drive", lambda *args: pytest.fail("a contact") or drive(*args))
    vector = CooperativeExplorationVectorEnv(4, max_cycles=60, autoreset_mode="next_step")  # the last step's info
    _, info = vector.reset(seed=5)
    n_landmarks = vector.config["n_landmarks"]
    slots, motions = set(), set()
    for _ in range(60):
        actions = greedy(vector.action_masks(), info)
        _, _, _, _, info = vector.step(actions)
        slot, motion = np.divmod(info["chosen_action"], N_MOTIONS)
        slots |= {"landmark" if 0 < s <= n_landmarks else "teammate" if s > n_landmarks else "none" for s in slot.flat}
        motions |= set(motion.flat)
    assert slots == {"none", "landmark", "teammate"} and motions == set(range(N_MOTIONS))
    assert np.all(info["coverage"] > 0.0) and sum(substeps) > 10
    gains, mask = info["action_information_gain"], info["action_mask"]
    assert np.all(gains[mask == 0] == 0.0) and np.any(gains[mask == 1] > 0.0)


# ----------------------------------------------------------------------------- the filter against filterpy's


def recorded(function, sink: list):
    """``function`` that also appends each result to ``sink``."""
    return lambda *args: sink.append(function(*args)) or sink[-1]


def test_the_filter_equals_filterpys_ekf_update_for_update(monkeypatch):
    """Along a whole episode (DGPS under canopies, landmark and teammate observations, turns and drives) the env's EKF
    equals raw filterpy fed the same readings (x 1e-12, P 1e-10), and each own-pose reward its MI."""
    priors, readings, fixes, landmark = [], [], [], []
    monkeypatch.setattr(scenario, "start_episode", recorded(scenario.start_episode, priors))
    relative = record_relative_measurements(monkeypatch)
    measure_landmarks = TeamSight.landmark_measurements
    monkeypatch.setattr(TeamSight, "landmark_measurements", lambda *args: recorded(measure_landmarks, landmark)(*args))
    env = cooperative_exploration_v0.parallel_env(max_cycles=60, max_position_std_m=100.0)
    vector, parts = env.vector, env.vector.parts
    for sensor, sink in ((vector.env_scenario.odometry, readings), (vector.env_scenario.gps, fixes)):
        measure = sensor.measure_with_noise
        monkeypatch.setattr(
            type(sensor), "measure_with_noise", lambda _, *args, m=measure, s=sink: recorded(m, s)(*args)
        )
    _, infos = env.reset(seed=4)
    poses, covariances = priors[-1][1:3]
    ekf = oracle.filterpy_filter(poses.ravel(), oracle.block_diagonal(covariances))
    n_robots, n_landmarks = len(env.possible_agents), env.config["n_landmarks"]
    odometry_covariances = np.repeat(parts.odometry.noise_covariance()[None], n_robots, axis=0)
    gps_covariances = np.repeat(vector.env_scenario.gps.noise_covariance()[None], n_robots, axis=0)
    turn_s, drive_s = env.config["turn_time_s"], env.config["time_step_s"] - env.config["turn_time_s"]

    def fuse_gps(infos):
        robots = np.flatnonzero([infos[agent]["gps_available"] for agent in env.possible_agents])
        if robots.size:
            H, R = oracle.gps_jacobian(robots, 3 * n_robots), oracle.block_diagonal(gps_covariances[robots])
            oracle.filterpy_update(ekf, fixes[-1][0][robots].ravel(), H @ ekf.x, H, R, [], n_robots)
        return robots.size

    counts = np.array([0, 0, fuse_gps(infos)])  # teammate and landmark observations, DGPS fixes
    rng = np.random.default_rng(4)
    while env.agents:
        actions = greedy_actions(env, infos) if rng.random() < 0.5 else random_valid_actions(env, infos, rng)
        prior_pose_P = oracle.pose_blocks(ekf.P)
        _, _, _, _, infos = env.step(actions)
        slots = np.array([infos[agent]["chosen_action"] for agent in env.possible_agents]) // N_MOTIONS
        landmarks = landmark[-1][0] if ((slots > 0) & (slots <= n_landmarks)).any() else None
        teammates = relative[-1].reshape(n_robots, 3) if (slots > n_landmarks).any() else None
        observed = exploration_observation_updates(ekf, env, slots, teammates, landmarks)
        own = 0.5 * (np.linalg.slogdet(prior_pose_P)[1] - np.linalg.slogdet(oracle.pose_blocks(ekf.P))[1])
        for robot, agent in enumerate(env.possible_agents):
            assert infos[agent]["reward_own_pose_information"] == pytest.approx(own[robot], abs=1e-10)
        for phase_s, reading in zip((turn_s, drive_s), readings[-2:]):
            oracle.filterpy_predict(ekf, reading[0], odometry_covariances, phase_s)
        counts += [*observed, fuse_gps(infos)]
        x, P = vector.joint_state()
        np.testing.assert_allclose(x[0], ekf.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(P[0], ekf.P, rtol=0, atol=1e-10)
    assert len(readings) == 2 * 60 and np.all(counts > 10), counts
