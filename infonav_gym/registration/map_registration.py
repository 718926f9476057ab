"""Registration of a LADAR scan to an a-priori map (``prior_map``): the vehicle's pose on the map and its covariance.

A scan point ``q`` (map coordinates) matched to map point ``m`` with normal ``n`` has the point-to-plane residual
``n . (q - m)``. A small motion ``(t, w)`` of the sensor about its optical centre ``c`` moves ``q`` by ``t + w x (q -
c)``: the residual's Jacobian is ``J = [n, (q - c) x n]`` (``point_jacobians``). ICP's least-squares estimate has the
covariance ``H^-1 B H^-1`` with ``H = sum J_i^T J_i`` (Gauss-Newton's normal matrix), and ``B`` the covariance of
the score ``sum J_i^T e_i`` under the map's errors, which are not independent point by point
(``motion_covariances``, "sandwich" form):

* within a square of ``CORRELATION_CELLS`` map cells a side the points share an error (the map's height samples and
  its interpolation between them), of the variance ``sigma^2`` of the residuals: ``sigma^2 sum_squares g g^T``,
  ``g`` the sum of the square's ``J_i``;
* the points on one map feature share its position error, of std ``s_f`` along x and y:
  ``s_f^2 sum_features G G^T``, ``G`` the sum of the feature's ``J_i n_i[:2]^T`` (6, 2).

The vehicle's planar pose ``v = (x, y, yaw)`` of its ground point ``g = c - R e_z h`` moves by ``A (t, w)``, ``A =
[[I_2, rows x, y of -[g - c]_x], [0, d yaw / d w]]`` (``planar_pose_map``); its covariance is ``A H^-1 B H^-1 A^T``.
``H`` and ``B`` get ``PRIOR_INFORMATION`` on their diagonals (a vague prior pseudo-observation): a subset that fixes
no motion gets a huge covariance, not a singular one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from infonav_gym.geometry import cross, rigid_transform, rotation_matrix
from infonav_gym.registration.icp import MAD_TO_STD, ROBUST_K, icp
from infonav_gym.registration.prior_map import PriorMap

PRIOR_INFORMATION = 1e-6  # [1/m^2, 1/rad^2] on every axis of the motion: a std of 1 km or rad, i.e. none
MIN_INLIERS = 30  # fewer matched points do not make a registration
CORRELATION_CELLS = 2  # map cells along a side of the squares whose points share an error (a bilinear map's height
# samples each shape the 2 x 2 cells around them)
TOLERANCE = 5e-4  # [m, rad]: ICP's increments below this converge (0.5 mm, 0.5 mrad: a tenth of a fix's std)


@dataclass(frozen=True)
class MapFix:
    """A converged registration: ``map_from_sensor`` (4, 4), the vehicle's planar pose on the map ``pose`` (3,) [m,
    m, rad] and its ``covariance`` (3, 3), the matched points and their ``residual_std_m``, ICP's increments."""

    map_from_sensor: np.ndarray
    pose: np.ndarray
    covariance: np.ndarray
    inliers: int
    residual_std_m: float
    iterations: int


@dataclass(frozen=True)
class Matches:
    """Scan points (n, 3, map coordinates) against the map: each one's matched map ``normals`` (n, 3), point-to-
    plane ``residuals`` (n,), error square ``cells`` (n,) (module docstring) and ``features`` (n,) (-1: the ground),
    and which are ``inliers`` (n,) bool (within the correspondence distance and the robust bound)."""

    normals: np.ndarray
    residuals: np.ndarray
    cells: np.ndarray
    features: np.ndarray
    inliers: np.ndarray


def sensor_pose_on_map(planar_pose, attitude_rad, ground_height_m: float, mount_height_m: float) -> np.ndarray:
    """``map_from_sensor`` (4, 4) of a vehicle at ``planar_pose`` (x, y, yaw) on the map with ``attitude_rad`` (roll,
    pitch), its wheels at ``ground_height_m``, the optical centre ``mount_height_m`` up its axis."""
    rotation = rotation_matrix(*attitude_rad, planar_pose[2])
    ground = np.array([planar_pose[0], planar_pose[1], ground_height_m])
    return rigid_transform(rotation, ground + rotation[:, 2] * mount_height_m)


def planar_pose_map(map_from_sensor: np.ndarray, mount_height_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The vehicle's planar pose (x, y, yaw) under ``map_from_sensor`` and ``A`` (3, 6) (module docstring)."""
    rotation, centre = map_from_sensor[:3, :3], map_from_sensor[:3, 3]
    arm = -rotation[:, 2] * mount_height_m  # g - c
    A = np.zeros((3, 6))
    A[0, 0] = A[1, 1] = A[2, 5] = 1.0
    A[:2, 3:] = -np.array([[0.0, -arm[2], arm[1]], [arm[2], 0.0, -arm[0]]])  # rows x, y of -[arm]_x
    heading = rotation[0, 0] ** 2 + rotation[1, 0] ** 2  # yaw = atan2(R10, R00), R -> [w]_x R
    A[2, 3:5] = -rotation[2, 0] * rotation[:2, 0] / heading
    pose = np.array([centre[0] + arm[0], centre[1] + arm[1], math.atan2(rotation[1, 0], rotation[0, 0])])
    return pose, A


def point_jacobians(points: np.ndarray, normals: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """``J`` (n, 6) of the point-to-plane residuals of ``points`` (n, 3) on planes of ``normals`` (n, 3) w.r.t. a
    motion ``(t, w)`` about ``centre`` (3,)."""
    return np.concatenate([normals, cross(points - centre, normals)], axis=1)


def match_to_map(points: np.ndarray, prior: PriorMap, max_correspondence_distance: float) -> Matches:
    """Each of ``points`` (n, 3, map coordinates) matched to its nearest map point (``Matches``); inliers within
    ``max_correspondence_distance`` whose residual lies within ``ROBUST_K`` robust sigmas of the median (ICP's test)."""
    if len(points) == 0:
        nothing = np.zeros(0, dtype=np.int64)
        return Matches(np.zeros((0, 3)), np.zeros(0), nothing, nothing, np.zeros(0, dtype=bool))
    distance, index = prior.tree.query(points, k=1)
    nearest = index[:, 0]
    normals = prior.normals[nearest]
    residuals = np.einsum("ij,ij->i", points - prior.points[nearest], normals)
    inliers = distance[:, 0] < max_correspondence_distance
    if np.count_nonzero(inliers):
        median = float(np.median(residuals[inliers]))
        spread = ROBUST_K * MAD_TO_STD * float(np.median(np.abs(residuals[inliers] - median)))
        inliers &= np.abs(residuals - median) <= spread
    squares = np.floor(points[:, :2] / (CORRELATION_CELLS * prior.terrain.cell_m)).astype(np.int64)
    if len(points):
        squares -= squares.min(axis=0)
    cells = squares[:, 0] * (squares[:, 1].max(initial=0) + 1) + squares[:, 1]
    return Matches(normals, residuals, cells, prior.features[nearest], inliers)


def motion_covariances(
    jacobians: np.ndarray, matches: Matches, subsets: np.ndarray, residual_variance, feature_offset_std_m: float
) -> np.ndarray:
    """The covariance (K, 6, 6) of the motion ICP estimates from each of ``subsets`` (K, n) bool of the matched
    points with ``jacobians`` (n, 6) (module docstring); ``residual_variance`` [m^2], a number or one per subset."""
    weights = subsets.astype(float)
    normal_matrices = np.swapaxes(weights[:, :, None] * jacobians, 1, 2) @ jacobians
    bread = np.linalg.inv(normal_matrices + PRIOR_INFORMATION * np.eye(6))
    n_cells = int(matches.cells.max(initial=-1)) + 1
    rows, points = np.nonzero(subsets)
    slots = rows * n_cells + matches.cells[points]
    cell_sums = np.stack(
        [np.bincount(slots, jacobians[points, i], minlength=len(subsets) * n_cells) for i in range(6)], axis=-1
    ).reshape(len(subsets), n_cells, 6)
    meat = np.asarray(residual_variance, dtype=float).reshape(-1, 1, 1) * (np.swapaxes(cell_sums, 1, 2) @ cell_sums)
    on_feature = matches.features[points] >= 0
    if feature_offset_std_m > 0 and np.any(on_feature):
        rows, points = rows[on_feature], points[on_feature]
        feature_sums = np.zeros((len(subsets), int(matches.features.max()) + 1, 6, 2))
        spread = jacobians[points, :, None] * matches.normals[points, None, :2]
        np.add.at(feature_sums, (rows, matches.features[points]), spread)
        meat += feature_offset_std_m**2 * np.einsum("kfia,kfja->kij", feature_sums, feature_sums)
    covariance = bread @ (meat + PRIOR_INFORMATION * np.eye(6)) @ bread
    return 0.5 * (covariance + np.swapaxes(covariance, -1, -2))


def planar_covariance(motion_covariance: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``A C A^T`` (..., 3, 3) of motion covariances ``C`` (..., 6, 6), symmetrized."""
    covariance = A @ motion_covariance @ A.T
    return 0.5 * (covariance + np.swapaxes(covariance, -1, -2))


def register_to_map(
    points: np.ndarray,
    prior: PriorMap,
    init: np.ndarray,
    mount_height_m: float,
    feature_offset_std_m: float,
    *,
    max_iterations: int = 50,
    max_correspondence_distance: float = 2.0,
    robust_kernel: str | None = "tukey",
    kernel_scale: float = 0.3,
) -> MapFix | None:
    """Register scan ``points`` (n, 3, sensor frame) to ``prior`` by point-to-plane ICP from ``init``
    (``map_from_sensor``), its features' position error of std ``feature_offset_std_m`` [m]: the ``MapFix``, or
    None if ICP did not converge or fewer than ``MIN_INLIERS`` points matched."""
    if len(points) < MIN_INLIERS:
        return None
    settings = {
        "max_iterations": max_iterations,
        "tolerance": TOLERANCE,
        "max_correspondence_distance": max_correspondence_distance,
        "method": "point_to_plane",
        "robust_kernel": robust_kernel,
        "kernel_scale": kernel_scale,
        "target_normals": prior.normals,
        "target_tree": prior.tree,
    }
    result = icp(points, prior.points, init, **settings)
    matches = match_to_map(_moved(points, result.transform), prior, max_correspondence_distance)
    if not result.converged or np.count_nonzero(matches.inliers) < MIN_INLIERS:
        return None
    variance, iterations = _residual_variance(matches), result.iterations
    transform = result.transform
    jacobians = point_jacobians(_moved(points, transform), matches.normals, transform[:3, 3])
    motion = motion_covariances(jacobians, matches, matches.inliers[None], variance, feature_offset_std_m)[0]
    pose, A = planar_pose_map(transform, mount_height_m)
    inliers = int(np.count_nonzero(matches.inliers))
    return MapFix(transform, pose, planar_covariance(motion, A), inliers, math.sqrt(variance), iterations)


def _moved(points: np.ndarray, transform: np.ndarray) -> np.ndarray:
    return points @ transform[:3, :3].T + transform[:3, 3]


def _residual_variance(matches: Matches) -> float:
    residuals = matches.residuals[matches.inliers]
    return float(residuals @ residuals) / (len(residuals) - 6)
