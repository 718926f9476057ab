"""The registration's backend: small_gicp's k-d tree against scipy's, the compiled normals against numpy's ``eigh``,
and GICP against small_gicp's on a LADAR frame pair."""

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from infonav_gym.experiments.registration_timing import _ours, _small_gicp, alternating_times_ms, frame_pair
from infonav_gym.geometry import transform_error
from infonav_gym.registration.kdtree import KdTree
from infonav_gym.registration.normals import least_variance_axes


def test_kdtree_finds_the_neighbours_scipys_cKDTree_finds():
    rng = np.random.default_rng(0)
    points, queries = rng.uniform(-5.0, 5.0, (3000, 3)), rng.uniform(-6.0, 6.0, (500, 3))
    distance, index = KdTree(points).query(queries, k=7)
    expected_distance, expected_index = cKDTree(points).query(queries, k=7)
    np.testing.assert_array_equal(index, expected_index)
    np.testing.assert_allclose(distance, expected_distance, rtol=1e-12)


@pytest.mark.parametrize(
    ("scale", "neighbours"),
    [((1.0, 1.0, 1.0), 5), ((1.0, 0.5, 0.05), 20), ((30.0, 10.0, 0.02), 10)],  # isotropic, thin, a terrain patch
)
def test_least_variance_axes_equal_numpys_eigh(scale, neighbours):
    """The projector ``n n^T`` (the sign is arbitrary) against ``eigh``'s, 1 km from the origin too."""
    rng = np.random.default_rng(1)
    for offset_m in (0.0, 1000.0):
        points = rng.uniform(-1.0, 1.0, (2000, 3)) * scale + offset_m
        _, index = cKDTree(points).query(points, k=neighbours)
        patches = points[index] - points[index].mean(axis=1, keepdims=True)
        values, axes = np.linalg.eigh(np.einsum("nki,nkj->nij", patches, patches))
        gap = (values[:, 1] - values[:, 0]) / values[:, 2]
        normals = least_variance_axes(points, index)
        error = np.abs(
            np.einsum("ni,nj->nij", normals, normals) - np.einsum("ni,nj->nij", axes[:, :, 0], axes[:, :, 0])
        )
        assert np.all(error.max(axis=(1, 2)) <= 1e-13 / gap)  # an axis is as well defined as its eigenvalue gap


def test_a_patch_of_one_repeated_point_has_the_x_axis_as_eigh_gives():
    normals = least_variance_axes(np.ones((4, 3)), np.zeros((4, 3), dtype=np.int64))
    np.testing.assert_array_equal(normals, np.tile([1.0, 0.0, 0.0], (4, 1)))


def test_gicp_is_as_accurate_as_small_gicps_on_a_ladar_frame_pair():
    """``registration_timing``'s comparison: the same warm start, neighbours, distance limit and thresholds."""
    clouds = frame_pair(0)
    errors = [transform_error(register(), clouds[2]) for register in (_ours(*clouds, "gicp"), _small_gicp(*clouds))]
    (translation_m, rotation), (peer_translation_m, peer_rotation) = errors
    assert math.degrees(rotation) <= math.degrees(peer_rotation) + 0.02
    assert translation_m <= peer_translation_m + 0.005


def test_registrations_are_timed_in_turn_after_one_warm_up_each():
    order = []
    calls = {name: (lambda name=name: order.append(name) or name.upper()) for name in ("ours", "peer")}
    timed = alternating_times_ms(calls, 3)
    assert order == ["ours", "peer"] * 4  # the warm-ups, then three rounds
    assert {name: (result, len(times)) for name, (result, times) in timed.items()} == {
        "ours": ("OURS", 3),
        "peer": ("PEER", 3),
    }
    assert all(time_ms >= 0.0 for _, times in timed.values() for time_ms in times)
