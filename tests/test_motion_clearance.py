"""Motion clearance: swept discs against walls and obstacles, teammates' moves, and the env's motion mask."""

import itertools
import math

import numpy as np
import pytest
from conftest import random_valid_actions

from infonav_gym.envs.cooperative_exploration.exploration_planning import MOTION_HEADINGS_RAD, N_MOTIONS, STAY
from infonav_gym.multi import cooperative_exploration_v0
from infonav_gym.world import StaticGeometry
from infonav_gym.world.clearance import clear_moves, teammate_conflicts
from infonav_gym.world.exploration_scenarios import exploration_field
from infonav_gym.world.visibility import swept_discs_clear

SAMPLES = np.linspace(0.0, 1.0, 2001)  # times along a move, for brute-force distances


def point_segment_distances(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Distance from each point (P, 2) to each segment (S, 2)-(S, 2), closed form (P, S) [m]."""
    along = ends - starts
    t = np.einsum("psi,si->ps", points[:, None] - starts, along) / np.maximum(
        np.einsum("si,si->s", along, along), 1e-300
    )
    closest = starts + np.clip(t, 0.0, 1.0)[..., None] * along
    return np.linalg.norm(points[:, None] - closest, axis=-1)


def test_a_swept_disc_is_clear_exactly_when_every_point_of_its_path_keeps_its_radius_from_every_shape():
    scenario = exploration_field(np.random.default_rng(4))
    geometry = StaticGeometry.from_scenario(scenario, 0.3)
    rng = np.random.default_rng(0)
    starts = rng.uniform(-1.0, 41.0, (1, 3000, 2))
    ends = starts + rng.normal(0.0, 2.0, starts.shape)
    radius = 0.35
    clear = swept_discs_clear(geometry, starts, ends, radius)[0]
    path = starts[0, :, None] + SAMPLES[:, None] * (ends - starts)[0, :, None]  # (K, T, 2)
    walls = np.array(scenario.walls, dtype=float)
    gaps = []
    for points in path:
        to_walls = point_segment_distances(points, walls[:, 0], walls[:, 1]) - 0.15
        centers = np.array([o.center for o in scenario.obstacles])
        to_discs = np.linalg.norm(points[:, None] - centers, axis=-1) - [o.radius for o in scenario.obstacles]
        gaps.append(min(to_walls.min(), to_discs.min()))
    gaps = np.array(gaps)
    decided = np.abs(gaps - radius) > 1e-3  # the sampled path is within 1e-3 m of exact
    assert decided.mean() > 0.99 and 0.2 < clear.mean() < 0.95
    np.testing.assert_array_equal(clear[decided], gaps[decided] > radius)


def test_teammate_conflicts_are_the_closest_approach_of_two_straight_moves():
    rng = np.random.default_rng(1)
    positions = rng.uniform(0.0, 3.0, (20, 3, 2))
    displacements = rng.normal(0.0, 1.0, (20, 3, 4, 2))
    conflicts = teammate_conflicts(positions, displacements, 0.65)
    for copy, i, m_i, j, m_j in itertools.product(range(20), range(3), range(4), range(3), range(4)):
        path_i = positions[copy, i] + SAMPLES[:, None] * displacements[copy, i, m_i]
        path_j = positions[copy, j] + SAMPLES[:, None] * displacements[copy, j, m_j]
        closest = np.linalg.norm(path_i - path_j, axis=1).min()
        if i == j:
            assert not conflicts[copy, i, m_i, j, m_j]
        elif abs(closest - 0.65) > 1e-3:
            assert conflicts[copy, i, m_i, j, m_j] == (closest < 0.65), (copy, i, m_i, j, m_j, closest)


def test_any_combination_of_clear_moves_keeps_every_pair_of_robots_apart_and_staying_is_always_clear():
    rng = np.random.default_rng(2)
    geometry = StaticGeometry.stack([StaticGeometry.from_scenario(exploration_field(rng), 0.3)] * 30)
    positions = rng.uniform(18.0, 22.0, (30, 3, 2))
    for copy in range(30):  # robots that start clear of each other
        while min(math.dist(*positions[copy, pair]) for pair in itertools.combinations(range(3), 2)) < 0.65:
            positions[copy] = rng.uniform(18.0, 22.0, (3, 2))
    moves = rng.normal(0.0, 1.0, (30, 3, 4, 2))
    moves[:, :, 0] = 0.0
    clear = clear_moves(geometry, positions, moves, robot_radius_m=0.3)
    assert clear[..., 0].all() and 0.1 < clear[..., 1:].mean() < 0.9
    for copy in range(30):
        for choice in itertools.product(*(np.flatnonzero(clear[copy, robot]) for robot in range(3))):
            paths = positions[copy, :, None] + SAMPLES[:, None] * moves[copy, np.arange(3), list(choice)][:, None]
            for i, j in itertools.combinations(range(3), 2):
                assert np.linalg.norm(paths[i] - paths[j], axis=1).min() >= 0.6 + 0.05 - 1e-9


def test_clearance_functions_reject_bad_input_with_one_line_errors():
    geometry = StaticGeometry.from_scenario(exploration_field(np.random.default_rng(0)), 0.3)
    with pytest.raises(ValueError, match="margin_m must be >= 0"):
        geometry.grown(-0.1)
    with pytest.raises(ValueError, match="ends \\[m\\] \\(one per start\\)"):
        swept_discs_clear(geometry, np.zeros((1, 3, 2)), np.zeros((1, 2, 2)), 0.3)
    with pytest.raises(ValueError, match="2 rows of starts for a geometry of 1 copies"):
        swept_discs_clear(geometry, np.zeros((2, 3, 2)), np.zeros((2, 3, 2)), 0.3)
    with pytest.raises(ValueError, match="starts \\[m\\] must be a finite array"):
        swept_discs_clear(geometry, np.full((1, 1, 2), np.nan), np.zeros((1, 1, 2)), 0.3)


def test_every_motion_the_mask_allows_is_executed_exactly_as_the_ekf_models_it():
    """No contact: after the turn on the spot, the true pose moves straight by speed x drive time, exactly."""
    env = cooperative_exploration_v0.parallel_env(max_cycles=150, max_position_std_m=100.0)
    drive_s = env.config["time_step_s"] - env.config["turn_time_s"]
    masked = 0
    for seed in range(4):
        _, infos = env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        while env.agents:
            masked += sum(int(info["action_mask"][:N_MOTIONS].sum() < N_MOTIONS) for info in infos.values())
            before, headings = env.vector.true_poses[0], env.vector.joint_state()[0][0, 2::3]
            actions = random_valid_actions(env, infos, rng)
            motions = np.array([actions[agent] % N_MOTIONS for agent in env.agents])
            _, _, _, _, infos = env.step(actions)
            turned = before[:, 2] + np.where(
                motions != STAY, (MOTION_HEADINGS_RAD[motions] - headings + math.pi) % (2 * math.pi) - math.pi, 0.0
            )
            travel = drive_s * env.vector.parts.speeds_mps * (motions != STAY)
            expected = before[:, :2] + travel[:, None] * np.column_stack([np.cos(turned), np.sin(turned)])
            np.testing.assert_allclose(env.vector.true_poses[0, :, :2], expected, atol=1e-9)
    assert masked > 20, "the walls, obstacles and teammates masked some motions"
