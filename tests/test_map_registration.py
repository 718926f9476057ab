"""Registration to an a-priori map (``prior_map``, ``map_registration``) and ``infonav/MapRegistration-v0``'s own
checks; the shared env checks run on it from the registry."""

from __future__ import annotations

import dataclasses
import math
import runpy
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from scipy.stats import chi2

import infonav_gym  # noqa: F401  (registers the envs)
from infonav_gym.envs.vector_infos import reward_terms_of
from infonav_gym.experiments.benchmark import GOALS, lower_is_better
from infonav_gym.experiments.map_consistency import consistency_markdown, summary
from infonav_gym.experiments.registration_timing import MAP_TIME_RATIO, map_step_figures
from infonav_gym.geometry import rigid_transform, rotation_matrix, wrap_angle
from infonav_gym.registration.frame_pairs import scan_on_terrain
from infonav_gym.registration.icp import icp
from infonav_gym.registration.kdtree import KdTree
from infonav_gym.registration.map_registration import (
    PRIOR_INFORMATION,
    Matches,
    match_to_map,
    motion_covariances,
    planar_pose_map,
    point_jacobians,
    register_to_map,
    sensor_pose_on_map,
)
from infonav_gym.registration.normals import estimate_normals
from infonav_gym.registration.prior_map import MapErrors, prior_map, surface_samples
from infonav_gym.sensors.ladar import Ladar, sensor_points
from infonav_gym.world.terrain import Box, Cylinder, Terrain
from infonav_gym.world.terrain_scenario import terrain_loop
from infonav_gym.world.world import World

EXACT = {"height_std_m": 0.0, "feature_offset_std_m": 0.0, "missing_fraction": 0.0, "extra_features": 0}


def errors(**fields) -> MapErrors:
    return MapErrors(**{**EXACT, **fields})


def small_motion(vector: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The (4, 4) motion ``(t, w)`` (rotation vector ``w``) about ``centre``."""
    angle = np.linalg.norm(vector[3:])
    axis = vector[3:] / angle if angle else np.zeros(3)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rotation = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
    return rigid_transform(rotation, centre + vector[:3] - rotation @ centre)


def test_surface_samples_lie_on_their_surfaces_with_outward_unit_normals():
    slope = 0.2
    x, y = np.meshgrid(np.arange(11.0), np.arange(11.0))
    terrain = Terrain(slope * x, (0.0, 0.0), 1.0).with_obstacles(
        cylinders=[Cylinder((3.0, 4.0), 0.5, 0.0, 3.0)], boxes=[Box((6.0, 6.0, 0.0), (8.0, 9.0, 4.0))]
    )
    points, normals, features = surface_samples(terrain)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    ground = features == -1
    assert np.count_nonzero(ground) == 121
    np.testing.assert_allclose(normals[ground], np.tile([-slope, 0.0, 1.0] / np.hypot(slope, 1.0), (121, 1)))
    cylinder = features == 0
    np.testing.assert_allclose(np.hypot(points[cylinder, 0] - 3.0, points[cylinder, 1] - 4.0), 0.5)
    np.testing.assert_allclose(normals[cylinder, :2] * 0.5, points[cylinder, :2] - [3.0, 4.0], atol=1e-12)
    box = points[features == 1]
    on_face = np.isclose(box[:, 0], 6) | np.isclose(box[:, 0], 8) | np.isclose(box[:, 1], 6)
    on_face |= np.isclose(box[:, 1], 9) | np.isclose(box[:, 2], 4)
    assert on_face.all()
    centre = np.array([7.0, 7.5, 2.0])
    assert np.all(np.einsum("ij,ij->i", box - centre, normals[features == 1]) > 0)  # outward


def test_prior_map_perturbs_what_its_arguments_say():
    rng = np.random.default_rng(0)
    terrain = terrain_loop(rng).terrain
    exact = prior_map(terrain, np.random.default_rng(1), errors(cell_m=terrain.cell_m))
    np.testing.assert_array_equal(exact.terrain.heights_m, terrain.heights_m)
    assert len(exact.terrain.cylinders) == len(terrain.cylinders) and len(exact.terrain.boxes) == len(terrain.boxes)
    none = prior_map(terrain, np.random.default_rng(1), errors(missing_fraction=1.0, extra_features=4))
    assert len(none.terrain.boxes) == 0 and len(none.terrain.cylinders) == 4
    noisy = prior_map(terrain, np.random.default_rng(1), errors(cell_m=terrain.cell_m, height_std_m=0.1))
    assert np.std(noisy.terrain.heights_m - terrain.heights_m) == pytest.approx(0.1, rel=0.05)
    moved = prior_map(terrain, np.random.default_rng(1), errors(feature_offset_std_m=0.5))
    shifts = [np.subtract(m.center_m, t.center_m) for m, t in zip(moved.terrain.cylinders, terrain.cylinders)]
    assert np.std(shifts) == pytest.approx(0.5, rel=0.3)


@pytest.mark.parametrize("argument, value", [("cell_m", 0.0), ("missing_fraction", 1.5), ("extra_features", -1)])
def test_map_errors_refuse_a_bad_value_naming_it(argument, value):
    with pytest.raises(ValueError, match=argument):
        MapErrors(**{argument: value})


def test_point_jacobians_are_the_residuals_finite_differences():
    rng = np.random.default_rng(3)
    points, normals = rng.normal(size=(5, 3)) * 10, rng.normal(size=(5, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    matched, centre = points + rng.normal(size=(5, 3)) * 0.1, rng.normal(size=3)
    jacobians = point_jacobians(points, normals, centre)
    step = 1e-7
    for axis in range(6):
        delta = np.zeros(6)
        delta[axis] = step
        moved = points @ small_motion(delta, centre)[:3, :3].T + small_motion(delta, centre)[:3, 3]
        back = points @ small_motion(-delta, centre)[:3, :3].T + small_motion(-delta, centre)[:3, 3]
        numeric = np.einsum("ij,ij->i", moved - matched, normals) - np.einsum("ij,ij->i", back - matched, normals)
        np.testing.assert_allclose(numeric / (2 * step), jacobians[:, axis], atol=1e-6)


def test_planar_pose_map_inverts_sensor_pose_and_its_A_is_the_pose_derivative():
    pose, attitude, mount = np.array([3.0, -2.0, 0.7]), (0.05, -0.08), 2.0
    transform = sensor_pose_on_map(pose, attitude, 1.5, mount)
    recovered, A = planar_pose_map(transform, mount)
    np.testing.assert_allclose(recovered, pose, atol=1e-12)
    step = 1e-7
    for axis in range(6):
        delta = np.zeros(6)
        delta[axis] = step
        plus = planar_pose_map(small_motion(delta, transform[:3, 3]) @ transform, mount)[0]
        minus = planar_pose_map(small_motion(-delta, transform[:3, 3]) @ transform, mount)[0]
        np.testing.assert_allclose((plus - minus) / (2 * step), A[:, axis], atol=1e-6)


def test_motion_covariance_is_the_sandwich_of_the_stated_errors():
    """Brute force: ``H^-1 J^T S J H^-1`` with ``S`` the residuals' covariance built entry by entry."""
    rng = np.random.default_rng(5)
    n = 40
    jacobians = rng.normal(size=(n, 6))
    normals = rng.normal(size=(n, 3))
    cells, features = rng.integers(0, 6, n), rng.integers(-1, 3, n)
    matches = Matches(normals, np.zeros(n), cells, features, np.ones(n, dtype=bool))
    subset = rng.random(n) < 0.7
    variance, feature_std = 0.01, 0.2
    got = motion_covariances(jacobians, matches, subset[None], variance, feature_std)[0]
    S = variance * (cells[:, None] == cells[None, :])
    same_feature = (features[:, None] == features[None, :]) & (features[:, None] >= 0)
    S = S + feature_std**2 * same_feature * (normals[:, :2] @ normals[:, :2].T)
    J, eps = jacobians[subset], PRIOR_INFORMATION * np.eye(6)  # the vague prior of both factors
    bread = np.linalg.inv(J.T @ J + eps)
    expected = bread @ (J.T @ S[np.ix_(subset, subset)] @ J + eps) @ bread
    np.testing.assert_allclose(got, expected, rtol=1e-5)
    independent = Matches(normals, np.zeros(n), np.arange(n), np.full(n, -1), np.ones(n, dtype=bool))
    closed_form = variance * np.linalg.inv(jacobians.T @ jacobians)
    got = motion_covariances(jacobians, independent, np.ones((1, n), bool), variance, 0.0)[0]
    np.testing.assert_allclose(got, closed_form, rtol=1e-4)


def test_an_empty_subset_has_a_huge_covariance_not_a_singular_one():
    matches = Matches(np.zeros((3, 3)), np.zeros(3), np.zeros(3, int), np.full(3, -1), np.ones(3, bool))
    covariance = motion_covariances(np.ones((3, 6)), matches, np.zeros((1, 3), bool), 0.01, 0.1)[0]
    assert np.all(np.linalg.eigvalsh(covariance) > 1e5)


def first_scan(seed: int):
    rng = np.random.default_rng(seed)
    scene = terrain_loop(rng)
    world = World()
    world.reset(scene.scenario)
    for _ in range(4):
        world.step(0.5)
    return scene.terrain, world.pose.copy(), scan_on_terrain(Ladar(), scene.terrain, world.pose, rng)


def test_registration_to_an_exact_map_recovers_the_pose():
    terrain, pose, scan = first_scan(0)
    prior = prior_map(terrain, np.random.default_rng(0), errors(cell_m=terrain.cell_m))
    start = pose + np.array([0.4, -0.3, math.radians(2.0)])
    mount = Ladar().mount_height_m
    init = sensor_pose_on_map(start, scan.attitude_rad, float(prior.terrain.height_at(start[:2])), mount)
    fix = register_to_map(sensor_points(scan), prior, init, mount, 0.0)
    error = fix.pose - pose
    assert np.hypot(*error[:2]) < 0.03 and abs(wrap_angle(error[2])) < math.radians(0.2)
    assert fix.inliers > 0.8 * len(sensor_points(scan))
    assert register_to_map(sensor_points(scan)[:10], prior, init, mount, 0.0) is None  # too few points


def test_match_to_map_marks_far_points_as_outliers():
    terrain, pose, scan = first_scan(1)
    prior = prior_map(terrain, np.random.default_rng(0), errors())
    far = np.array([[0.0, 0.0, 500.0]])
    near = prior.points[:50] + 0.01 * np.random.default_rng(0).standard_normal((50, 3))
    matches = match_to_map(np.concatenate([near, far]), prior, 2.0)
    assert matches.inliers[:50].all() and not matches.inliers[50]


def test_icp_with_given_normals_and_tree_equals_icp_estimating_them():
    rng = np.random.default_rng(2)
    target = rng.normal(size=(400, 3)) * [5, 5, 0.3]
    source = target[::3] @ rotation_matrix(0, 0, 0.02).T + [0.1, -0.05, 0.0]
    tree = KdTree(target)
    normals = estimate_normals(target, tree)
    given = icp(source, target, method="point_to_plane", target_normals=normals, target_tree=tree)
    estimated = icp(source, target, method="point_to_plane")
    np.testing.assert_allclose(given.transform, estimated.transform, atol=1e-12)
    with pytest.raises(ValueError, match="target_normals"):
        icp(source, target, method="point_to_plane", target_normals=normals[:10])


def test_a_fused_fix_is_filterpys_kalman_update_and_its_reward_the_mi():
    env = gym.make("infonav/MapRegistration-v0").unwrapped
    env.reset(seed=3)
    scenario, captured = env.vector.env_scenario, []
    register = scenario._register

    fix_points = []

    def spy(state, copy, subset):
        fix_points.append(state.points[copy][subset])
        captured.append(register(state, copy, subset))
        return captured[-1]

    scenario._register = spy
    for _ in range(4):
        x, P = env.vector.state.x[0].copy(), env.vector.state.P[0].copy()
        _, reward, _, _, info = env.step(1)  # register every return
        if not info["fused"]:
            continue
        fix = captured[-1]
        kf = KalmanFilter(dim_x=3, dim_z=3)
        kf.x, kf.P, kf.H, kf.R = x.copy(), P.copy(), np.eye(3), fix.covariance
        residual = fix.pose - x
        residual[2] = wrap_angle(residual[2])
        kf.update(x + residual)
        mi = 0.5 * (np.linalg.slogdet(P)[1] - np.linalg.slogdet(kf.P)[1])
        assert reward_terms_of(info)["mutual_information"] == pytest.approx(mi, rel=1e-9)
        assert reward == pytest.approx(mi + reward_terms_of(info)["point_cost"], rel=1e-9)
        assert reward_terms_of(info)["point_cost"] == pytest.approx(-1e-4 * info["registered_points"])
        assert info["registered_points"] == len(fix_points[-1])
        assert info["registration_nees"] >= 0
        return
    pytest.fail("no fix was fused in four steps")


def test_none_is_always_valid_with_no_gain_and_registers_nothing():
    env = gym.make("infonav/MapRegistration-v0")
    _, info = env.reset(seed=0)
    assert info["action_mask"][0] == 1 and info["action_information_gain"][0] == 0.0
    _, reward, _, _, info = env.step(0)
    assert reward == 0.0 and info["registered_points"] == 0 and not info["fused"]


@pytest.mark.parametrize(
    "key, value", [("map_cell_m", 0.0), ("map_missing_fraction", 2.0), ("n_sectors", 0), ("gate_nis", -1.0)]
)
def test_a_bad_config_value_is_refused_naming_its_key(key, value):
    with pytest.raises(ValueError, match=key):
        gym.make("infonav/MapRegistration-v0", **{key: value})


def test_the_benchmark_times_a_map_step_against_a_registering_frame_pair_step():
    figures = map_step_figures(1, 0.01, 0)
    assert figures["map_registration_step_ms"] > 0 and figures["range_registration_registering_step_ms"] > 0
    ratio = figures["map_registration_step_ms"] / figures["range_registration_registering_step_ms"]
    assert figures[MAP_TIME_RATIO] == pytest.approx(ratio)
    assert lower_is_better(MAP_TIME_RATIO) and MAP_TIME_RATIO in GOALS


def test_the_consistency_summary_counts_what_it_says():
    run = {"agent": "everything", "seeds": [0, 3], "nees": [0.5, 3.0, 9.5, 2.0], "tried": 5, "refused": 1}
    row = summary(run)
    assert row["mean_nees"] == pytest.approx(3.75) and row["failures"] == 1 and row["refused_rate"] == 0.2
    low, high = chi2.ppf([0.025, 0.975], 3)
    assert row["inside_95_band"] == np.mean([low <= v <= high for v in run["nees"]]) and row["in_band"]
    assert "| everything | 0..3 | 4 | 3.75 |" in consistency_markdown([row], "cmd")


@pytest.mark.parametrize("argv", [["--registrations", "0"], ["--agents", "oracle"]])
def test_the_consistency_script_refuses_bad_input_before_any_work(argv, capsys):
    script = runpy.run_path(str(Path(__file__).parents[1] / "scripts" / "map_registration_consistency.py"))
    with pytest.raises(SystemExit) as exit_info:
        script["main"](argv)
    assert exit_info.value.code == 2 and argv[1] in capsys.readouterr().err


def test_a_scan_without_returns_leaves_only_none_valid_and_steps_on(monkeypatch):
    from infonav_gym.envs.map_registration import scenario as module

    def blind(ladar, terrain, pose, np_random):
        scan = scan_on_terrain(ladar, terrain, pose, np_random)
        return dataclasses.replace(scan, no_return=np.ones_like(scan.no_return))

    monkeypatch.setattr(module, "scan_on_terrain", blind)
    env = gym.make("infonav/MapRegistration-v0")
    _, info = env.reset(seed=0)
    assert info["action_mask"].tolist() == [1] + [0] * (env.action_space.n - 1)
    for action in range(env.action_space.n):
        _, reward, _, _, info = env.step(action)
        assert reward == 0.0 and not info["fused"] and info["registered_points"] == 0
