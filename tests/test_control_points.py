"""ICP control point selection (the paper's Section V-A): contract, information, and registration accuracy."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from infonav_gym.information import expected_information_gain
from infonav_gym.registration import icp, range_image_to_points
from infonav_gym.registration.control_points import (
    CONTROL_POINT_STRATEGIES,
    DEFAULT_POSE_COVARIANCE,
    NORMAL_SPACE_BINS,
    ControlPointGeometry,
    balanced_picks,
    control_point_geometry,
    select_control_points,
    single_point_information,
    stretches,
)
from infonav_gym.sensors.ladar import Ladar, LadarScan, point_cloud
from infonav_gym.world.terrain import Box, Cylinder
from infonav_gym.world.terrain_generation import flat_terrain, make_terrain


def _rugged_scan(seed: int) -> LadarScan:
    rng = np.random.default_rng(seed)
    terrain = make_terrain(rng, roughness=1.0, n_trees=25, n_rocks=8)
    return Ladar().scan(terrain, [0.0, 0.0, rng.uniform(-math.pi, math.pi)], rng)


@pytest.fixture(scope="module")
def wall_scan() -> LadarScan:
    """Level ground with a building wall 12 m ahead and two trunks: the only x / y / yaw structure."""
    terrain = flat_terrain(size_m=120.0, cell_m=1.0).with_obstacles(
        cylinders=[Cylinder((8.0, 5.0), 0.4, 0.0, 10.0), Cylinder((10.0, -6.0), 0.5, 0.0, 10.0)],
        boxes=[Box((12.0, -3.0, 0.0), (14.0, 3.0, 6.0))],
    )
    return Ladar().scan(terrain, [0.0, 0.0, 0.0], np.random.default_rng(0))


@pytest.fixture(scope="module")
def corridor_scan() -> LadarScan:
    """A corridor along x (walls at y = +-3 m) over level ground, with one low block 15 m ahead: the ground and walls
    fix z, roll, pitch, y and yaw many times over, only the block's face fixes the along-track x."""
    walls = [Box((-40.0, 3.0, 0.0), (40.0, 3.5, 4.0)), Box((-40.0, -3.5, 0.0), (40.0, -3.0, 4.0))]
    block = Box((15.0, -0.4, 0.0), (15.8, 0.4, 1.0))
    terrain = flat_terrain(size_m=120.0, cell_m=1.0).with_obstacles(boxes=[*walls, block])
    return Ladar().scan(terrain, [0.0, 0.0, 0.0], np.random.default_rng(0))


def _stability(geometry: ControlPointGeometry, indices) -> np.ndarray:
    """Gelfand et al.'s covariance ``C = sum F F^T`` of the returns ``indices``, ``F = [(p - c) x n / L, n]``, with
    the centroid ``c`` and mean distance ``L`` of all usable returns (the same frame for every selector)."""
    usable = np.isfinite(geometry.error_var_m2)
    centroid = geometry.points_m[usable].mean(axis=0)
    scale = np.linalg.norm(geometry.points_m[usable] - centroid, axis=1).mean()
    chosen = np.asarray(indices)[usable[indices]]
    offsets, normals = geometry.points_m[chosen] - centroid, geometry.normals[chosen]
    constraints = np.concatenate([np.cross(offsets, normals) / scale, normals], axis=1)
    return constraints.T @ constraints


@pytest.fixture(scope="module")
def rugged_scans() -> list[LadarScan]:
    return [_rugged_scan(seed) for seed in range(4)]


def _returns(scan: LadarScan) -> int:
    return int(np.count_nonzero(~scan.no_return))


# ---------------------------------------------------------------- contract


@pytest.mark.parametrize("strategy", CONTROL_POINT_STRATEGIES)
@pytest.mark.parametrize("k", [1, 37, 600])
def test_indices_are_valid_sorted_unique_and_counted(rugged_scans, strategy, k):
    for scan in rugged_scans:
        count = _returns(scan)
        indices = select_control_points(scan, k, strategy, np_random=np.random.default_rng(1))
        assert indices.dtype == np.int64
        assert np.all(np.diff(indices) > 0), "sorted and unique"
        assert indices[0] >= 0 and indices[-1] < count
        assert len(indices) == (count if strategy == "all" else min(k, count))
        assert len(point_cloud(scan)[indices]) == len(indices)


@pytest.mark.parametrize("strategy", CONTROL_POINT_STRATEGIES)
def test_k_beyond_the_returns_gives_every_return(wall_scan, strategy):
    count = _returns(wall_scan)
    indices = select_control_points(wall_scan, count + 5, strategy, np_random=np.random.default_rng(0))
    np.testing.assert_array_equal(indices, np.arange(count))


@pytest.mark.parametrize("strategy", CONTROL_POINT_STRATEGIES)
def test_deterministic_given_the_seed(rugged_scans, strategy):
    scan = rugged_scans[0]
    first = select_control_points(scan, 500, strategy, np_random=np.random.default_rng(7))
    again = select_control_points(scan, 500, strategy, np_random=np.random.default_rng(7))
    np.testing.assert_array_equal(first, again)


def test_random_draws_differ_between_seeds(rugged_scans):
    scan = rugged_scans[0]
    draws = [tuple(select_control_points(scan, 300, "random", np_random=np.random.default_rng(s))) for s in range(5)]
    assert len(set(draws)) == 5


def test_all_ignores_k(wall_scan):
    np.testing.assert_array_equal(select_control_points(wall_scan, 1, "all"), np.arange(_returns(wall_scan)))


@pytest.mark.parametrize("k", [40, 400])
def test_uniform_spreads_over_every_column_band_and_row_band(rugged_scans, k):
    for scan in rugged_scans:
        rows, columns = np.nonzero(~scan.no_return)
        indices = select_control_points(scan, k, "uniform")
        for band in range(4):  # every band of the image that has returns gets control points
            in_column_band = (columns * 4 // scan.ranges_m.shape[1]) == band
            if np.count_nonzero(in_column_band) >= len(rows) / 8:
                assert np.any(in_column_band[indices]), f"column band {band} got no control point"
        gaps = np.diff(indices)
        assert gaps.max() <= math.ceil(len(rows) / k), "evenly spaced in row-major order"


# ---------------------------------------------------------------- information


def test_mutual_information_matches_the_gaussian_update_closed_form():
    """Independent errors: 0.5 ln det(I + P sum J^T J / a), the EKF update's information gain (Section III)."""
    rng = np.random.default_rng(3)
    n = 40
    jacobians = rng.standard_normal((n, 6))
    variance = rng.uniform(0.01, 0.1, n) ** 2
    patch = np.repeat(np.arange(4), n // 4)
    geometry = ControlPointGeometry(
        points_m=np.zeros((n, 3)),
        normals=np.zeros((n, 3)),
        jacobians=jacobians,
        error_var_m2=variance,
        spread_m=np.zeros(n),
        structure_m=np.ones(n),
        patch=patch,
        pose_covariance=DEFAULT_POSE_COVARIANCE,
    )
    chosen = np.array([0, 3, 11, 12, 25, 39])
    expected = expected_information_gain(DEFAULT_POSE_COVARIANCE, jacobians[chosen], np.diag(variance[chosen]))
    assert geometry.mutual_information(chosen) == pytest.approx(expected, rel=1e-10)
    closed_form = (
        0.5
        * np.linalg.slogdet(
            np.eye(6) + DEFAULT_POSE_COVARIANCE @ (jacobians[chosen].T / variance[chosen]) @ jacobians[chosen]
        )[1]
    )
    assert geometry.mutual_information(chosen) == pytest.approx(closed_form, rel=1e-10)


def test_error_model_grows_with_the_footprint_and_the_spread(wall_scan):
    """Far returns (bigger pixel footprint) and returns the prior motion uncertainty spreads past their surface."""
    geometry = control_point_geometry(wall_scan)
    ground = np.isfinite(geometry.error_var_m2) & (geometry.points_m[:, 2] < -1.9)
    distance = np.linalg.norm(geometry.points_m, axis=1)
    near, far = ground & (distance < 8.0), ground & (distance > 20.0)
    assert np.median(geometry.error_std_m[far]) > 2 * np.median(geometry.error_std_m[near])
    assert geometry.error_std_m[ground].min() >= math.sqrt(2) * 0.02, "at least the range noise of both frames"
    wider = control_point_geometry(wall_scan, 100 * DEFAULT_POSE_COVARIANCE)
    usable = np.isfinite(geometry.error_var_m2)
    assert np.all(wider.error_std_m[usable] >= geometry.error_std_m[usable])
    assert np.mean(wider.error_std_m[usable] > 1.5 * geometry.error_std_m[usable]) > 0.5
    np.testing.assert_allclose(wider.spread_m, 10 * geometry.spread_m)


def test_error_model_takes_the_range_noise_of_the_scans_ladar(wall_scan):
    """The scan carries its LADAR's range noise, so a noisier LADAR's control points are less reliable."""
    assert wall_scan.range_std_m == Ladar().range_std_m
    noisy = dataclasses.replace(wall_scan, range_std_m=0.1)
    quiet, loud = control_point_geometry(wall_scan), control_point_geometry(noisy)
    usable = np.isfinite(quiet.error_var_m2)
    np.testing.assert_array_equal(np.isfinite(loud.error_var_m2), usable)
    assert np.all(loud.error_var_m2[usable] > quiet.error_var_m2[usable])
    assert loud.error_std_m[usable].min() >= math.sqrt(2) * 0.1, "at least the range noise of both frames"


def test_entropy_picks_the_wall_and_trunks_as_well_as_the_ground(wall_scan):
    geometry = control_point_geometry(wall_scan)
    height = geometry.points_m[:, 2]  # the sensor is 2 m above the level ground
    on_structure, on_ground = height > -1.8, height < -1.9
    assert 0.02 < on_structure.mean() < 0.3
    for k in (50, 200, 800):
        indices = select_control_points(wall_scan, k, "entropy")
        assert on_structure[indices].mean() > 0.1, f"k={k}: too few control points on the wall and trunks"
        assert on_ground[indices].mean() >= 0.08, f"k={k}: too few control points on the ground"


def test_entropy_beats_random_and_uniform_in_mutual_information(rugged_scans, wall_scan):
    for scan in [*rugged_scans, wall_scan]:
        geometry = control_point_geometry(scan)
        for fraction in (0.05, 0.25):
            k = int(fraction * _returns(scan))
            entropy = geometry.mutual_information(select_control_points(scan, k, "entropy"))
            assert entropy >= geometry.mutual_information(select_control_points(scan, k, "uniform"))
            for seed in range(20):
                random = select_control_points(scan, k, "random", np_random=np.random.default_rng(seed))
                assert entropy >= geometry.mutual_information(random)


def test_covariance_sampling_keeps_the_weak_direction_and_the_lowest_condition_number(corridor_scan):
    geometry = control_point_geometry(corridor_scan)
    weakest = np.linalg.eigh(_stability(geometry, np.arange(_returns(corridor_scan))))[1][:, 0]
    assert abs(weakest[3]) > 0.9, "the corridor's weak direction is the along-track translation"
    for k in (100, 400):
        picks = {
            strategy: select_control_points(corridor_scan, k, strategy, np_random=np.random.default_rng(3))
            for strategy in ("random", "uniform", "normal_space", "covariance")
        }
        stability = {strategy: _stability(geometry, indices) for strategy, indices in picks.items()}
        condition = {strategy: np.linalg.cond(matrix) for strategy, matrix in stability.items()}
        weak = {strategy: weakest @ matrix @ weakest for strategy, matrix in stability.items()}
        for other in ("random", "uniform", "normal_space"):
            assert condition["covariance"] < condition[other], f"k={k}: {condition}"
            assert weak["covariance"] > 2 * weak[other], f"k={k}: {weak}"


def test_normal_space_sampling_takes_every_normal_bucket_in_turn(corridor_scan):
    geometry = control_point_geometry(corridor_scan)
    usable = np.flatnonzero(np.isfinite(geometry.error_var_m2))
    normals = geometry.normals
    bands, sectors = NORMAL_SPACE_BINS  # equal-area bands of the normal's z, sectors of its azimuth
    band = np.minimum(((normals[:, 2] + 1) / 2 * bands).astype(int), bands - 1)
    sector = np.minimum(
        ((np.arctan2(normals[:, 1], normals[:, 0]) + np.pi) / (2 * np.pi) * sectors).astype(int), sectors - 1
    )
    bucket = band * sectors + sector
    sizes = np.bincount(bucket[usable], minlength=bands * sectors)
    assert np.count_nonzero(sizes) >= 4 and sizes.max() > 20 * sizes[sizes > 0].min()  # the ground dominates
    for k in (np.count_nonzero(sizes), 300):
        indices = select_control_points(corridor_scan, k, "normal_space", np_random=np.random.default_rng(5))
        taken = np.bincount(bucket[indices], minlength=bands * sectors)
        expected = np.zeros_like(sizes)  # every bucket gets a pick before any gets a second, and so on
        for _ in range(k):
            expected[np.argmin(np.where(expected < sizes, expected, np.iinfo(int).max))] += 1
        np.testing.assert_array_equal(np.sort(taken), np.sort(expected))
        assert set(indices.tolist()) <= set(usable.tolist())


def test_the_balanced_picks_follow_gelfands_greedy_rule():
    """The compiled loop against the rule written out: pick for the least constrained direction its strongest
    untaken return."""
    rng = np.random.default_rng(11)
    squared = rng.random((60, 6)) ** 3
    orders = np.argsort(-squared, axis=0, kind="stable").T
    expected, totals, taken = [], np.zeros(6), set()
    for _ in range(40):
        direction = int(np.argmin(totals))
        point = next(int(p) for p in orders[direction] if int(p) not in taken)
        taken.add(point)
        expected.append(point)
        totals += squared[point]
    np.testing.assert_array_equal(balanced_picks(squared, orders, 40, 1e-9, 1e-12), expected)


def test_single_point_information_is_each_returns_own_gaussian_update(rugged_scans):
    """``0.5 ln(1 + J P J^T / a)``: the mutual information of one return alone (the matrix determinant lemma)."""
    geometry = control_point_geometry(rugged_scans[0])
    information = single_point_information(geometry)
    usable = np.flatnonzero(np.isfinite(geometry.error_var_m2))
    for index in usable[:: len(usable) // 25]:
        assert information[index] == pytest.approx(geometry.mutual_information([index]), rel=1e-9)
    assert np.all(information[~np.isfinite(geometry.error_var_m2)] == 0.0)


@pytest.mark.parametrize(("count", "k"), [(10, 3), (7, 7), (1000, 37), (5760, 1440)])
def test_stretches_cover_every_index_once_in_runs_of_near_equal_length(count, k):
    table = stretches(count, k)
    taken = table[table >= 0]
    np.testing.assert_array_equal(taken, np.arange(count))  # row by row: consecutive runs, in order
    lengths = (table >= 0).sum(axis=1)
    assert lengths.min() >= count // k and lengths.max() <= -(-count // k)


def test_stratified_information_takes_the_most_informative_return_of_each_stretch(rugged_scans, wall_scan):
    """Brute force: walk the stretches of the usable returns and keep each one's first best (ties: 1e-9)."""
    for scan in [*rugged_scans[:2], wall_scan]:
        geometry = control_point_geometry(scan)
        usable = np.flatnonzero(np.isfinite(geometry.error_var_m2))
        information = 0.5 * np.log1p(geometry.spread_m**2 / geometry.error_var_m2)
        for k in (13, 300):
            expected = []
            for stretch in range(k):
                members = usable[math.floor(stretch * len(usable) / k) : math.floor((stretch + 1) * len(usable) / k)]
                best = information[members].max()  # the first within the decision tolerance of the best
                expected.append(next(i for i in members if information[i] >= best - 1e-9 * abs(best) - 1e-12))
            np.testing.assert_array_equal(select_control_points(scan, k, "stratified_information"), expected)


def test_stratified_information_picks_the_same_from_a_perturbed_scan(wall_scan):
    """Level ground with a wall: many returns tell the same in exact arithmetic; a 1e-13 nudge changes no pick."""
    rng = np.random.default_rng(4)
    nudged = dataclasses.replace(
        wall_scan, ranges_m=wall_scan.ranges_m * (1 + 1e-13 * rng.standard_normal(wall_scan.ranges_m.shape))
    )
    for k in (50, 400):
        np.testing.assert_array_equal(
            select_control_points(nudged, k, "stratified_information"),
            select_control_points(wall_scan, k, "stratified_information"),
        )


# ---------------------------------------------------------------- registration accuracy (needs icp)

PAIR_SEEDS = range(24)
FRACTION = 0.25  # control points as a share of the returns
ODOMETRY_ERROR = (0.2, math.radians(2.0))  # ICP warm start: the true motion off by 0.2 m and 2 degrees
SOLVABLE_M = 0.03  # pairs the all-points registration misses by more than this say nothing about control points


def _world_from_sensor(scan: LadarScan) -> np.ndarray:
    transform = np.eye(4)
    transform[:3, :3] = Rotation.from_euler("z", scan.vehicle_pose[2]).as_matrix()
    transform[:3, 3] = scan.sensor_position_m
    return transform


def _motion_error(estimate: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Translation [m] and rotation [deg] of ``truth^-1 estimate``."""
    error = np.linalg.inv(truth) @ estimate
    return float(np.linalg.norm(error[:3, 3])), math.degrees(Rotation.from_matrix(error[:3, :3]).magnitude())


def _register_pair(seed: int) -> dict[str, tuple[int, float, float]]:
    """Scan a rugged scene, drive 1 m and turn 2 degrees, scan again; register the second frame onto the first."""
    rng = np.random.default_rng(seed)
    terrain = make_terrain(rng, roughness=1.0, n_trees=25, n_rocks=8)
    heading = rng.uniform(-math.pi, math.pi)
    ladar = Ladar()
    previous = ladar.scan(terrain, [0.0, 0.0, heading], rng)
    turn = math.radians(2.0) * rng.choice([-1.0, 1.0])
    current = ladar.scan(terrain, [math.cos(heading), math.sin(heading), heading + turn], rng)
    truth = np.linalg.inv(_world_from_sensor(previous)) @ _world_from_sensor(current)
    axis, direction = rng.standard_normal(3), rng.standard_normal(3)
    odometry_error = np.eye(4)
    odometry_error[:3, :3] = Rotation.from_rotvec(ODOMETRY_ERROR[1] * axis / np.linalg.norm(axis)).as_matrix()
    odometry_error[:3, 3] = ODOMETRY_ERROR[0] * direction / np.linalg.norm(direction)
    source, target = (
        range_image_to_points(scan.ranges_m, scan.azimuth_rad, scan.elevation_rad, scan.no_return)
        for scan in (current, previous)
    )
    results = {}
    for strategy in CONTROL_POINT_STRATEGIES:
        chosen = select_control_points(
            current, int(FRACTION * len(source)), strategy, np_random=np.random.default_rng(seed)
        )
        result = icp(
            source[chosen], target, truth @ odometry_error, max_correspondence_distance=1.0, method="point_to_plane"
        )
        results[strategy] = (len(chosen), *_motion_error(result.transform, truth))
    return results


@pytest.fixture(scope="module")
def registration_errors() -> dict[str, np.ndarray]:
    """Per strategy, (seeds, 3) of points used, translation error [m] and rotation error [deg]."""
    pairs = [_register_pair(seed) for seed in PAIR_SEEDS]
    pairs = [pair for pair in pairs if pair["all"][1] < SOLVABLE_M]
    assert len(pairs) >= 20
    return {strategy: np.array([pair[strategy] for pair in pairs]) for strategy in CONTROL_POINT_STRATEGIES}


def test_entropy_uses_a_quarter_of_the_points(registration_errors):
    assert np.all(registration_errors["entropy"][:, 0] <= FRACTION * registration_errors["all"][:, 0])


def test_entropy_registers_better_than_uniform_and_typically_better_than_random(registration_errors):
    entropy, random, uniform = (registration_errors[s] for s in ("entropy", "random", "uniform"))
    assert entropy[:, 1].mean() < uniform[:, 1].mean() and entropy[:, 2].mean() < uniform[:, 2].mean()
    assert np.median(entropy[:, 1]) < np.median(random[:, 1])


# The control-point criterion on terrain_frame_pair pairs (recall and median, the default registration):
# tests/test_registration_recall.py.


# ---------------------------------------------------------------- bad input


def test_bad_strategy_and_k(wall_scan):
    with pytest.raises(ValueError, match=r"unknown control point strategy 'best'.*'entropy'"):
        select_control_points(wall_scan, 10, "best")
    for k in (0, -3, 2.5, True, None):
        with pytest.raises(ValueError, match=r"k \(the number of control points\) must be an integer >= 1"):
            select_control_points(wall_scan, k)


@pytest.mark.parametrize("strategy", ["random", "normal_space"])
def test_drawing_strategies_need_a_generator(wall_scan, strategy):
    with pytest.raises(ValueError, match=f"strategy '{strategy}' needs np_random"):
        select_control_points(wall_scan, 10, strategy)


@pytest.mark.parametrize("strategy", ["entropy", "stratified_information", "normal_space", "covariance"])
def test_too_few_returns_with_a_normal_is_a_clear_error(wall_scan, strategy):
    rows, columns = np.indices(wall_scan.no_return.shape)
    checkered = dataclasses.replace(wall_scan, no_return=wall_scan.no_return | ((rows + columns) % 2 == 1))
    with pytest.raises(
        ValueError, match=f"0 returns with a surface normal .* fewer than k = 10: strategy '{strategy}'"
    ):
        select_control_points(checkered, 10, strategy, np_random=np.random.default_rng(0))
    assert len(select_control_points(checkered, 10, "uniform")) == 10  # the strategies without normals still choose


@pytest.mark.parametrize(
    ("covariance", "message"),
    [
        (np.eye(3), r"pose_covariance must be a \(6, 6\) covariance .* got shape \(3, 3\)"),
        (np.eye(6) + np.triu(np.ones((6, 6)), 1), "pose_covariance is not symmetric"),
        (-np.eye(6), "pose_covariance is not positive definite"),
        (np.diag([1.0, 1.0, 1.0, 1.0, 1.0, np.nan]), "pose_covariance contains NaN"),
    ],
)
def test_bad_pose_covariance(wall_scan, covariance, message):
    with pytest.raises(ValueError, match=message):
        select_control_points(wall_scan, 10, pose_covariance=covariance)
    with pytest.raises(ValueError, match=message):
        control_point_geometry(wall_scan, covariance)


def test_bad_range_image(wall_scan):
    empty = LadarScan(
        wall_scan.ranges_m,
        np.ones_like(wall_scan.no_return),
        wall_scan.azimuth_rad,
        wall_scan.elevation_rad,
        wall_scan.vehicle_pose,
        wall_scan.sensor_position_m,
        wall_scan.max_range_m,
    )
    for strategy in CONTROL_POINT_STRATEGIES:
        with pytest.raises(ValueError, match="range_image has no returns"):
            select_control_points(empty, 10, strategy, np_random=np.random.default_rng(0))
    with pytest.raises(ValueError, match="range_image must be a LadarScan"):
        select_control_points(wall_scan.ranges_m, 10)
