"""Generalized ICP and the robust kernels: covariances against numpy, weights against their formulas, known motions.

The synthetic pairs are ``test_icp``'s ``face_cloud`` (20,000 points on the faces of a box of sides
2-4 m), moved by up to 10 degrees and 0.5 m, the noise on the source only.
"""

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation
from test_icp import errors, face_cloud, random_motion

from infonav_gym.registration import icp
from infonav_gym.registration.gicp import PLANE_EPSILON, gicp_covariances, gicp_step, pair_information
from infonav_gym.registration.robust_kernels import ROBUST_KERNELS, robust_weights


def moved_source(rng, target, motion, noise_std_m):
    """Source points with ``target ~ motion @ source``, plus Gaussian noise of ``noise_std_m`` per axis."""
    source = (target - motion[:3, 3]) @ motion[:3, :3]
    return source + rng.normal(scale=noise_std_m, size=source.shape)


def reference_gicp_covariances(points, neighbours):
    """numpy's: ``np.cov`` of each point's ``neighbours`` nearest (scipy's ``cKDTree``), eigenvalues set by ``eigh``."""
    _, index = cKDTree(points).query(points, k=neighbours)
    covariances = np.array([np.cov(points[row].T) for row in index])
    _, axes = np.linalg.eigh(covariances)
    return np.einsum("nik,k,njk->nij", axes, [PLANE_EPSILON, 1.0, 1.0], axes)


@pytest.mark.parametrize("offset_m", [0.0, 1000.0])
def test_gicp_covariances_equal_numpys_of_the_k_nearest_points(offset_m):
    """Patches thin along one axis, also 1 km from the origin (the one-pass scatter is summed about a patch point)."""
    points = np.random.default_rng(0).uniform(-1.0, 1.0, (400, 3)) * [1.0, 0.5, 0.05] + offset_m
    np.testing.assert_allclose(gicp_covariances(points, 12), reference_gicp_covariances(points, 12), atol=1e-10)


def test_pair_information_inverts_the_combined_covariances_of_the_pairs():
    rng = np.random.default_rng(7)
    source_covariances, target_covariances = (gicp_covariances(rng.uniform(-1.0, 1.0, (50, 3)), 8) for _ in range(2))
    source_index, target_index = rng.integers(0, 50, 30), rng.integers(0, 50, 30)
    rotation = Rotation.random(random_state=rng).as_matrix()
    combined = target_covariances[target_index] + rotation @ source_covariances[source_index] @ rotation.T
    information = pair_information(source_covariances, target_covariances, source_index, target_index, rotation)
    np.testing.assert_allclose(information, np.linalg.inv(combined), rtol=1e-9, atol=1e-9)


def test_gicp_step_solves_the_normal_equations_of_the_stacked_jacobians():
    """Against ``sum J^T M J x = -sum J^T M d`` with ``J = [[a]_x, -I]`` stacked per pair."""
    rng = np.random.default_rng(6)
    moved = rng.standard_normal((40, 3))
    matched = moved + 0.1 * rng.standard_normal((40, 3))
    roots = rng.standard_normal((40, 3, 3))
    information = np.linalg.inv(roots @ np.swapaxes(roots, 1, 2) + 0.1 * np.eye(3))
    arm = moved - moved.mean(axis=0)
    jacobian = np.concatenate([np.cross(arm[:, :, None], np.eye(3)[None], axis=1), np.tile(-np.eye(3), (40, 1, 1))], 2)
    np.testing.assert_allclose(jacobian[:, :, :3] @ [0.1, 0.2, 0.3], np.cross(arm, [0.1, 0.2, 0.3]))  # [a]_x w = a x w
    hessian = np.einsum("nki,nkl,nlj->ij", jacobian, information, jacobian)
    gradient = np.einsum("nki,nkl,nl->i", jacobian, information, matched - moved)
    expected = np.linalg.solve(hessian, -gradient)
    np.testing.assert_allclose(gicp_step(moved, matched, information), expected, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize(
    ("kernel", "residuals", "expected"),
    [
        ("huber", [0.0, 0.5, -1.0, 2.0, -4.0], [1.0, 1.0, 1.0, 0.5, 0.25]),  # 1, else c / |r|
        ("cauchy", [0.0, 1.0, -2.0, 3.0], [1.0, 0.5, 0.2, 0.1]),  # 1 / (1 + (r / c)^2)
        ("tukey", [0.0, 0.5, -0.5, 1.0, 3.0], [1.0, 0.5625, 0.5625, 0.0, 0.0]),  # (1 - (r / c)^2)^2 inside c, else 0
    ],
)
def test_robust_weights_follow_their_formulas(kernel, residuals, expected):
    scale = 0.04
    weights = robust_weights(scale * np.array(residuals), kernel, scale)
    np.testing.assert_allclose(weights, expected, rtol=1e-12)


def test_a_kernel_wider_than_every_residual_changes_nothing():
    rng = np.random.default_rng(2)
    target = face_cloud(rng, 5000)
    truth = random_motion(rng)
    source = moved_source(rng, target, truth, 0.01)
    for method in ("point_to_plane", "gicp"):
        plain = icp(source, target, method=method)
        for kernel in ROBUST_KERNELS:
            wide = icp(source, target, method=method, robust_kernel=kernel, kernel_scale=1e6)
            np.testing.assert_allclose(wide.transform, plain.transform, atol=1e-9)


def test_gicp_recovers_a_noiseless_motion_exactly():
    rng = np.random.default_rng(3)
    target = face_cloud(rng, 5000)
    truth = random_motion(rng)
    result = icp(moved_source(rng, target, truth, 0.0), target, method="gicp")
    assert result.converged
    np.testing.assert_allclose(result.transform, truth, atol=1e-9)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize(
    ("noise_std_m", "max_rotation_deg", "max_translation_m"),
    [
        (0.01, 0.05, 3e-3),  # a quarter of a percent of the 4 m extent: the bar
        (0.04, 0.15, 5e-3),  # 1% at 5 cm point spacing blurs the source's covariances: the point-to-plane test's bar
    ],
)
def test_gicp_recovers_a_known_motion(seed, noise_std_m, max_rotation_deg, max_translation_m):
    rng = np.random.default_rng(seed)
    target = face_cloud(rng)
    truth = random_motion(rng)
    result = icp(moved_source(rng, target, truth, noise_std_m), target, method="gicp")
    rotation_error_deg, translation_error_m = errors(result.transform, truth)
    assert result.converged and rotation_error_deg < max_rotation_deg and translation_error_m < max_translation_m


def test_given_covariances_are_used_as_computed_ones():
    rng = np.random.default_rng(4)
    target = face_cloud(rng, 3000)
    truth = random_motion(rng)
    source = moved_source(rng, target, truth, 0.01)
    computed = icp(source, target, method="gicp", covariance_neighbours=15)
    given = icp(
        source,
        target,
        method="gicp",
        source_covariances=gicp_covariances(source, 15),
        target_covariances=gicp_covariances(target, 15),
    )
    np.testing.assert_array_equal(given.transform, computed.transform)


def ghost_outliers(rng, source, fraction=0.2, offset_m=0.03):
    """``source`` with ``fraction`` of its points added again, shifted ``offset_m`` along one random direction."""
    direction = rng.standard_normal(3)
    copies = source[rng.choice(len(source), int(fraction * len(source)), replace=False)]
    return np.vstack([source, copies + offset_m * direction / np.linalg.norm(direction)])


@pytest.mark.parametrize("seed", range(5))
def test_a_robust_kernel_keeps_the_accuracy_with_a_fifth_of_gross_outliers(seed):
    """A ghost layer 3 cm off (20% more points, inside the MAD test's band) pulls least squares, not Tukey's kernel."""
    rng = np.random.default_rng(seed)
    target = face_cloud(rng)
    truth = random_motion(rng)
    source = ghost_outliers(rng, moved_source(rng, target, truth, 0.01))
    plain = errors(icp(source, target, method="point_to_plane").transform, truth)
    robust = errors(icp(source, target, method="gicp", robust_kernel="tukey", kernel_scale=0.02).transform, truth)
    assert not (plain[0] < 0.05 and plain[1] < 3e-3)
    assert robust[0] < 0.05 and robust[1] < 3e-3


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"method": "plane_to_plane"}, r"unknown ICP method 'plane_to_plane'; expected one of .*gicp"),
        ({"method": "gicp", "robust_kernel": "welsch"}, r"unknown robust_kernel 'welsch'; expected None or .*tukey"),
        ({"method": "point_to_plane", "robust_kernel": "L1"}, "unknown robust_kernel 'L1'"),
        ({"method": "gicp", "robust_kernel": "huber", "kernel_scale": 0.0}, "kernel_scale must be a positive number"),
        ({"method": "gicp", "kernel_scale": -1.0}, "kernel_scale must be a positive number"),
        ({"method": "gicp", "kernel_scale": math.nan}, "kernel_scale must be a positive number"),
        ({"robust_kernel": "cauchy"}, "robust_kernel 'cauchy' applies to method point_to_plane or gicp"),
        ({"method": "gicp", "covariance_neighbours": 2}, r"neighbours \(points per covariance\) must be"),
        ({"method": "gicp", "covariance_neighbours": 11}, "source has 10 points, too few for covariances from neigh"),
        ({"method": "gicp", "source_covariances": np.zeros((9, 3, 3))}, r"source_covariances .* got \(9, 3, 3\)"),
        ({"method": "gicp", "target_covariances": np.full((10, 3, 3), np.nan)}, "target_covariances must be finite"),
    ],
)
def test_bad_gicp_input_is_refused_with_a_clear_message(kwargs, message):
    cloud = np.random.default_rng(5).uniform(-1.0, 1.0, (10, 3))
    with pytest.raises(ValueError, match=message):
        icp(cloud, cloud, covariance_neighbours=kwargs.pop("covariance_neighbours", 5), **kwargs)


@pytest.mark.parametrize(
    ("points", "message"),
    [
        (np.zeros((4, 3)), "points has 4 points, too few for covariances from neighbours=5"),
        (np.zeros((6, 2)), r"points must be an \(N, 3\) array of points, got shape \(6, 2\)"),
        (np.full((6, 3), np.inf), "points must be finite, but 6 of its 6 points hold NaN or inf"),
    ],
)
def test_bad_points_for_the_covariances_are_refused(points, message):
    with pytest.raises(ValueError, match=message):
        gicp_covariances(points, 5)
