"""CooperativeExplorationVectorEnv: copy i equals its PettingZoo view (N = 1, no autoreset) seeded seed + i, step for
step, through the episodes' ends (a robot lost, the coverage target reached, the horizon) and the autoresets after
them.

Autoreset modes, seeding, bad input and rendering: ``test_team_vector_envs.py``, for every team vector env.
"""

import numpy as np
import pytest
from team_vector_checks import greedy, run_against_parallel_envs

from infonav_gym.multi.cooperative_exploration import N_MOTIONS
from infonav_gym.multi.cooperative_exploration_vector import CooperativeExplorationVectorEnv
from infonav_gym.world import World
from infonav_gym.world.world_batch import WorldBatch

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
    substeps, free_substeps = [], WorldBatch._free_substeps
    monkeypatch.setattr(
        WorldBatch,
        "_free_substeps",
        lambda batch, poses, *args: substeps.append(len(poses)) or free_substeps(batch, poses, *args),
    )
    drive_in_contact = World.drive_in_contact
    monkeypatch.setattr(World, "drive_in_contact", lambda *args: pytest.fail("a contact") or drive_in_contact(*args))
    vector = CooperativeExplorationVectorEnv(4, max_cycles=60)
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
