"""The package's one EKF: ``PoseEKF`` / ``JointEKF``'s models and updates on N copies, states ``x (N, n)``,
covariances ``P (N, n, n)`` (envs, planners, MRCLAM replay), run by the compiled ``kernels``, tested against filterpy.

A state starts with R robot poses ``[x, y, heading]``, then static entries (mapped landmarks ``[lx, ly]``). Functions
return new arrays; copies without a measurement come back unchanged. A bad argument (shape, finiteness, SPD noise,
indices) raises ``ValueError`` naming it; ``check_input=False`` skips the checks for known-good inputs.
"""

from __future__ import annotations

import functools

import numpy as np

from infonav_gym.compiled import contiguous, stacked
from infonav_gym.estimation import kernels
from infonav_gym.estimation.state import POSE_DIM, _finite, _noise_covariance, _time_step
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import log_det_spd

COINCIDENT = "a target coincides with the sensor position: its bearing is undefined"

# ---------------------------------------------------------------------------------------------- input checks


def _states(x) -> np.ndarray:
    """``x`` as a finite float stack of states (N, n) with N >= 1 and n >= 3, or ``ValueError``."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[0] < 1 or x.shape[1] < POSE_DIM:
        raise ValueError(f"x must be a stack of states (N, n) with N >= 1 and n >= {POSE_DIM}, got shape {x.shape}")
    return _finite("x", x, x.shape)


def _state(x, P) -> tuple[np.ndarray, np.ndarray]:
    """``_states(x)`` and ``P`` as symmetric positive-definite covariances (N, n, n), or ``ValueError``."""
    x = _states(x)
    return x, _noise_covariance("P", P, (*x.shape, x.shape[1]))


def _covariances(P) -> np.ndarray:
    """``P`` as a stack of symmetric positive-definite covariances (N, n, n), or ``ValueError``."""
    P = np.asarray(P, dtype=float)
    if P.ndim != 3 or P.shape[1] != P.shape[2] or len(P) < 1:
        raise ValueError(f"P must be a stack of covariances (N, n, n) with N >= 1, got shape {P.shape}")
    return _noise_covariance("P", P, P.shape)


def _team_size(n: int) -> int:
    """The number of robots R of joint states of size n = 3R, or ``ValueError``."""
    if n % POSE_DIM:
        raise ValueError(f"joint states must hold only robot poses, 3R entries, got {n}")
    return n // POSE_DIM


def _pairs(observers, targets, n_copies: int, n_robots: int, used=None) -> tuple[np.ndarray, np.ndarray]:
    """Robot index pairs (N, M) in [0, R) with no robot observing itself where ``used``, or ``ValueError``."""
    observers = np.asarray(observers)
    if observers.ndim != 2 or len(observers) != n_copies:
        raise ValueError(f"observers must have shape ({n_copies}, M), got {observers.shape}")
    observers = _indices("observers", observers, observers.shape, n_robots)
    targets = _indices("targets", targets, observers.shape, n_robots)
    same = (observers == targets) if used is None else used & (observers == targets)
    if np.any(same):
        copy, slot = np.argwhere(same)[0].tolist()
        raise ValueError(
            f"a robot cannot observe its own relative pose: observers[{copy}, {slot}] = targets[{copy}, {slot}] "
            f"= {observers[copy, slot]}"
        )
    return observers, targets


def _mask(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a bool array of ``shape``, or ``ValueError`` naming it."""
    mask = np.asarray(value)
    if mask.shape != shape or mask.dtype != bool:
        raise ValueError(f"{name} must be a bool array of shape {shape}, got {mask.dtype} of shape {mask.shape}")
    return mask


def _indices(name: str, value, shape: tuple[int, ...], stop: int) -> np.ndarray:
    """``value`` as an int array of ``shape`` with entries in [0, stop), or ``ValueError`` naming it."""
    indices = np.asarray(value)
    if indices.shape != shape or (indices.size and indices.dtype.kind not in "iu"):
        raise ValueError(f"{name} must be an int array of shape {shape}, got {indices.dtype} of shape {indices.shape}")
    if np.any((indices < 0) | (indices >= stop)):
        raise ValueError(f"{name} must hold indices in [0, {stop - 1}], got {indices.tolist()}")
    return indices.astype(int)


def _noise_stack(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """A symmetric positive-definite noise stack of ``shape``, or one that broadcasts to it (e.g. a single (m, m))."""
    covariance = np.asarray(value, dtype=float)
    _noise_covariance(name, covariance, covariance.shape)
    try:
        return np.broadcast_to(covariance, shape)
    except ValueError:
        raise ValueError(f"{name} must have shape {shape} (or broadcast to it), got {covariance.shape}") from None


# ---------------------------------------------------------------------------------------------- prediction


def predict_pose(x, P, controls, dt: float, control_covariance, *, check_input: bool = True):
    """``PoseEKF.predict`` on every copy: the predicted ``(x, P)``, states (N, n) (the pose first, the rest static) and
    covariances (N, n, n), the pose through the unicycle driven by odometry ``controls`` (N, 2) ``[speed, turn_rate]``
    [m/s, rad/s] for ``dt`` >= 0 [s], with noise ``control_covariance`` (N, 2, 2) or one (2, 2) for all copies."""
    if check_input:
        x, P = _state(x, P)
        controls = _finite("controls", controls, (len(x), 2))
        dt = _time_step(dt)
        control_covariance = _noise_stack("control_covariance", control_covariance, (len(x), 2, 2))
    covariances = stacked(control_covariance, (len(x), 2, 2))[:, None]  # (N, 1, 2, 2): one robot
    return kernels.predict_poses(_floats(x), _floats(P), _floats(controls[:, None]), float(dt), covariances)


def predict_team(x, P, controls, dt: float, control_covariances, *, check_input: bool = True):
    """``JointEKF.predict`` on every copy: the predicted ``(x, P)``, joint states (N, 3R) and covariances (N, 3R, 3R)
    (with or without cross-covariances), each robot's pose through the unicycle driven by its odometry ``controls``
    (N, R, 2) ``[speed, turn_rate]`` [m/s, rad/s] for ``dt`` >= 0 [s], with noise ``control_covariances``
    (N, R, 2, 2) or (R, 2, 2) for all copies."""
    if check_input:
        x, P = _state(x, P)
        n_robots = _team_size(x.shape[1])
        controls = _finite("controls", controls, (len(x), n_robots, 2))
        dt = _time_step(dt)
        control_covariances = _noise_stack("control_covariances", control_covariances, (len(x), n_robots, 2, 2))
    covariances = stacked(control_covariances, (*np.shape(controls), 2))
    return kernels.predict_poses(_floats(x), _floats(P), _floats(controls), float(dt), covariances)


def _floats(array, dtype=float) -> np.ndarray:
    """``array`` as float64 (or ``dtype``) in the layout the kernels are compiled for (``compiled.contiguous``)."""
    return contiguous(np.asarray(array, dtype=dtype))


# ---------------------------------------------------------------------------------------------- measurement models


def landmark_measurement_model(x, landmarks=None, *, check_input: bool = True):
    """``PoseEKF.landmark_measurement_model`` on every copy: ``(predicted (N, K, 2), H (N, K, 2, n))``, range-bearing
    from states ``x`` (N, n), the pose first then any mapped landmarks ``[l1x, l1y, ...]``, to known ``landmarks``
    (K, 2) or (N, K, 2), or (None) the mapped ones (``H`` gets their columns); ``ValueError`` for one on its pose."""
    mapped = landmarks is None
    if check_input:
        x = _states(x)
        if mapped and (x.shape[1] - POSE_DIM) % 2:
            raise ValueError(f"x must be [pose, l1x, l1y, ...], an odd number of entries, got {x.shape[1]}")
    n_copies = len(x)
    if mapped:
        positions = np.asarray(x)[:, POSE_DIM:].reshape(n_copies, -1, 2)
    else:
        positions = np.asarray(landmarks, dtype=float)
        if check_input:
            per_copy = positions.ndim == 3 and len(positions) == n_copies
            if not (positions.ndim == 2 or per_copy) or positions.shape[-1] != 2:
                raise ValueError(f"landmarks must have shape (K, 2) or ({n_copies}, K, 2), got {positions.shape}")
            positions = _finite("landmarks", positions, positions.shape)
        positions = np.broadcast_to(positions, (n_copies, *positions.shape[-2:]))
    predicted, H, coincident = kernels.range_bearing_models(_floats(x), _floats(positions), mapped)
    if coincident:
        raise ValueError(COINCIDENT)
    return predicted, H


def relative_pose_model(x, observers, targets, *, check_input: bool = True):
    """``JointEKF.relative_pose_model`` on every copy: the relative pose of robot ``targets[c, k]`` seen from robot
    ``observers[c, k]`` (both (N, M) indices into states ``x`` (N, 3R)), ``(predicted (N, M, 3), H_observer (N, M, 3,
    3), H_target (N, M, 3, 3))``."""
    if check_input:
        x = _states(x)
        observers, targets = _pairs(observers, targets, len(x), _team_size(x.shape[1]))
    observers, targets = _floats(observers, np.int64), _floats(targets, np.int64)
    *models, coincident = kernels.relative_pose_models(_floats(x), observers, targets)
    if coincident:
        raise ValueError(COINCIDENT)
    return tuple(models)


# ---------------------------------------------------------------------------------------------- updates


def range_bearing_update(x, P, measurements, predicted, H, R, observed=None, *, check_input: bool = True):
    """``PoseEKF.update_range_bearing`` of the ``observed`` (N,) bool copies (None: all): the updated ``(x, P)``,
    states (N, n), the pose first, and covariances (N, n, n), with each copy's measured ``[range, bearing]`` (N, 2),
    noise ``R`` (N, 2, 2), and its prediction at the prior ``predicted`` (N, 2) and Jacobian ``H`` (N, 2, n)
    (``landmark_measurement_model``)."""
    if check_input:
        x, P = _state(x, P)
    n_copies = len(x)
    if observed is None:
        observed = np.ones(n_copies, dtype=bool)
    if check_input:
        observed = _mask("observed", observed, (n_copies,))
        measurements = _finite("measurements", measurements, (n_copies, 2))
        predicted = _finite("predicted", predicted, (n_copies, 2))
        H = _finite("H", H, (n_copies, 2, x.shape[1]))
        R = _noise_covariance("R", R, (n_copies, 2, 2))
    chosen = np.where(observed, 0, -1)
    floats = (_floats(array) for array in (x, P, measurements))
    candidates = (_floats(np.asarray(array)[:, None]) for array in (predicted, H, R))
    return kernels.chosen_landmark_updates(*floats, _floats(chosen, np.int64), *candidates, np.zeros(n_copies))[:2]


def gps_update(x, P, fixes, noise_covariances, has_fix, *, cross_covariances: bool = True, check_input: bool = True):
    """``JointEKF.gps_update`` on every copy: the updated ``(x, P)``, joint states (N, 3R) and covariances (N, 3R, 3R),
    with the robots' position fixes ``[x, y]`` (N, R, 2) where ``has_fix`` (N, R) bool, their noise
    ``noise_covariances`` (N, R, 2, 2) or (R, 2, 2); without ``cross_covariances`` each robot keeps only its own block
    (as ``JointEKF``)."""
    if check_input:
        x, P = _state(x, P)
        n_robots = _team_size(x.shape[1])
        has_fix = _mask("has_fix", has_fix, (len(x), n_robots))
        fixes = _finite("fixes", fixes, (len(x), n_robots, 2))
        noise_covariances = _noise_stack("noise_covariances", noise_covariances, (len(x), n_robots, 2, 2))
    R = stacked(noise_covariances, (*np.shape(fixes), 2))
    return kernels.gps_updates(_floats(x), _floats(P), _floats(fixes), R, _floats(has_fix, bool), cross_covariances)


def relative_pose_update(
    x,
    P,
    observers,
    targets,
    measurements,
    predicted,
    H_observer,
    H_target,
    R,
    observed=None,
    *,
    cross_covariances: bool = True,
    check_input: bool = True,
):
    """``JointEKF.relative_pose_update`` on every copy: the updated ``(x, P)``, a copy's observed slots fused in slot
    order as one stacked update. Slot ``[c, k]`` is ``[range, bearing, relative heading]`` (m = 3) or ``[range,
    bearing]`` (m = 2) of robot ``targets[c, k]`` seen by ``observers[c, k]`` (robot indices (N, M)).

    Args:
        x, P: joint states (N, 3R) and covariances (N, 3R, 3R).
        measurements, predicted: (N, M, m), ``predicted`` and the Jacobians ``H_observer``, ``H_target`` (N, M, m, 3)
            the first m rows of ``relative_pose_model``'s at the prior; ``R`` (N, M, m, m) their noise.
        observed: which slots are measured (N, M) bool; None for all.
        cross_covariances: keep the cross-covariances (False: each robot keeps its own block, as ``JointEKF``).
    """
    if check_input:
        x, P = _state(x, P)
        if observed is not None:
            observed = _mask("observed", observed, np.shape(observers))
        observers, targets = _pairs(observers, targets, len(x), _team_size(x.shape[1]), observed)
    m = np.shape(measurements)[-1] if np.ndim(measurements) == 3 and np.shape(measurements)[-1] == 2 else 3
    jacobians = {"H_observer": (observers, H_observer), "H_target": (targets, H_target)}
    return _slot_update(x, P, measurements, predicted, jacobians, R, observed, m, cross_covariances, check_input)


def team_landmark_update(
    x, P, robots, measurements, predicted, H_pose, R, observed=None, *, cross_covariances=True, check_input=True
):
    """The team's updates with known landmarks on every copy: the updated ``(x, P)``, as ``relative_pose_update`` with
    slot ``[c, k]`` the ``[range, bearing]`` ``measurements`` (N, M, 2) of a known landmark seen by robot
    ``robots[c, k]`` (N, M), ``predicted`` and ``H_pose`` (N, M, 2, 3), the Jacobian w.r.t. that robot's pose, from
    ``landmark_measurement_model`` at the prior, and noise ``R`` (N, M, 2, 2)."""
    if check_input:
        x, P = _state(x, P)
        robots = np.asarray(robots)
        if robots.ndim != 2 or len(robots) != len(x):
            raise ValueError(f"robots must have shape ({len(x)}, M), got {robots.shape}")
        robots = _indices("robots", robots, robots.shape, _team_size(x.shape[1]))
        if observed is not None:
            observed = _mask("observed", observed, robots.shape)
    jacobians = {"H_pose": (robots, H_pose)}
    return _slot_update(x, P, measurements, predicted, jacobians, R, observed, 2, cross_covariances, check_input)


def _slot_update(x, P, measurements, predicted, jacobians, R, observed, m, cross_covariances, check_input):
    """The team updates' common part: ``jacobians`` maps each Jacobian's name to ``(robot indices (N, M), blocks
    (N, M, m, 3))``; the residuals' angles (all entries but the range) are wrapped."""
    shape = np.shape(next(iter(jacobians.values()))[0])
    if observed is None:
        observed = np.ones(shape, dtype=bool)
    if check_input:
        measurements = _finite("measurements", measurements, (*shape, m))
        predicted = _finite("predicted", predicted, (*shape, m))
        jacobians = {name: (robots, _finite(name, H, (*shape, m, POSE_DIM))) for name, (robots, H) in jacobians.items()}
        R = _noise_covariance("R", R, (*shape, m, m))
    n = np.shape(x)[1]
    residual = np.subtract(measurements, predicted)
    residual[..., 1:] = wrap_angle(residual[..., 1:])
    H = functools.reduce(np.add, (_slot_jacobians(robots, blocks, n) for robots, blocks in jacobians.values()))
    return _update(x, P, residual, H, R, observed, n // POSE_DIM, cross_covariances)


def _update(x, P, residuals, H, R, used, n_headings: int, cross_covariances: bool = True):
    """``kernels.kalman_updates`` on arrays in the layout it is compiled for."""
    floats = (_floats(array) for array in (x, P, residuals, H, R))
    return kernels.kalman_updates(*floats, _floats(used, bool), int(n_headings), bool(cross_covariances))


def _slot_jacobians(robots, blocks, n: int) -> np.ndarray:
    """(N, M, m, n) Jacobians: slot ``[c, k]`` holds ``blocks[c, k]`` (m, 3) in robot ``robots[c, k]``'s columns."""
    n_copies, n_slots, m, _ = np.shape(blocks)
    H = np.zeros((n_copies, n_slots, m, n // POSE_DIM, POSE_DIM))
    H[np.arange(n_copies)[:, None], np.arange(n_slots), :, robots, :] = blocks
    return H.reshape(n_copies, n_slots, m, n)


def _jacobians(H, P: np.ndarray, inner: tuple[str, ...]) -> np.ndarray:
    """``H`` as a finite float array (N, *inner, n) for the covariances ``P`` (N, n, n), else ``ValueError``."""
    H = np.asarray(H, dtype=float)
    if H.ndim != 2 + len(inner) or H.shape[0] != len(P) or H.shape[-1] != P.shape[1]:
        raise ValueError(f"H must have shape ({len(P)}, {', '.join(inner)}, {P.shape[1]}), got {H.shape}")
    return _finite("H", H, H.shape)


def posterior_covariance(P, H, R, *, check_input: bool = True) -> np.ndarray:
    """The covariance (N, n, n) after the EKF update of priors ``P`` (N, n, n) with Jacobians ``H`` (N, m, n) and SPD
    noise ``R`` (N, m, m), as the updates compute it; a zero row of ``H`` with its own unit noise changes nothing."""
    if check_input:
        P = _covariances(P)
        H = _jacobians(H, P, ("m",))
        R = _noise_covariance("R", R, (len(P), H.shape[1], H.shape[1]))
    n_copies, m, n = np.shape(H)
    no_state, no_residual = np.zeros((n_copies, n)), np.zeros((n_copies, 1, m))
    every_copy = np.ones((n_copies, 1), dtype=bool)
    return _update(no_state, P, no_residual, np.asarray(H)[:, None], np.asarray(R)[:, None], every_copy, 0)[1]


# ---------------------------------------------------------------------------------------------- information


def landmark_information_gains(P, H, R, *, check_input: bool = True) -> np.ndarray:
    """Expected MI (N, K) [nats] of observing each candidate alone at each copy's prior, ``0.5 ln(det S / det R)``:
    priors ``P`` (N, n, n), the candidates' Jacobians ``H`` (N, K, m, n) and noise ``R`` (N, K, m, m)."""
    if check_input:
        P = _covariances(P)
        H = _jacobians(H, P, ("K", "m"))
        R = _noise_covariance("R", R, (*H.shape[:3], H.shape[2]))
    return _checked_gains(kernels.landmark_gains(_floats(P), _floats(H), _floats(R)), R)


def _checked_gains(gains: np.ndarray, R) -> np.ndarray:
    """``gains``, or ``ValueError`` naming the matrix whose determinant was not > 0 where a gain is NaN."""
    if np.isnan(gains).any():
        log_det_spd(R, "noise covariance R", check_input=False)
        raise ValueError("innovation covariance H P H^T + R is not positive definite (determinant <= 0)")
    return gains


def relative_pose_information_gains(P, observers, targets, H_observer, H_target, R, *, check_input: bool = True):
    """Expected MI ``(own, joint)`` (N, M) [nats] of each candidate pair on the observer's own pose and on the joint
    state: joint covariances ``P`` (N, 3R, 3R), the pairs' robot indices ``observers``, ``targets`` (N, M), their
    Jacobians ``H_observer``, ``H_target`` (N, M, m, 3) and noise ``R`` (N, M, m, m)."""
    if check_input:
        P = _covariances(P)
        observers, targets = _pairs(observers, targets, len(P), _team_size(P.shape[1]))
        m = np.shape(H_observer)[-2] if np.ndim(H_observer) == 4 else 3
        H_observer = _finite("H_observer", H_observer, (*observers.shape, m, POSE_DIM))
        H_target = _finite("H_target", H_target, (*observers.shape, m, POSE_DIM))
        R = _noise_covariance("R", R, (*observers.shape, m, m))
    pairs = (_floats(robots, np.int64) for robots in (observers, targets))
    models = (_floats(array) for array in (H_observer, H_target, R))
    own, joint = kernels.relative_pose_gains(_floats(P), *pairs, *models, np.ones(np.shape(observers), dtype=bool))
    if np.isnan(own).any():
        raise ValueError("an observer's pose covariance, or its posterior, is not positive definite (determinant <= 0)")
    return own, _checked_gains(joint, R)


def pose_blocks(P) -> np.ndarray:
    """Joint covariances (N, 3R, 3R) as (N, R, R, 3, 3) blocks: ``[c, i, j]`` is robot i's pose with robot j's."""
    n_copies, n, _ = np.shape(P)
    n_robots = n // POSE_DIM
    return np.reshape(P, (n_copies, n_robots, POSE_DIM, n_robots, POSE_DIM)).transpose(0, 1, 3, 2, 4)


def pose_log_dets(P, n_robots: int = 1, *, check_input: bool = True) -> np.ndarray:
    """``ln det`` of each robot's own pose covariance block (N, R) of ``P`` (N, n, n) whose state starts with
    ``n_robots`` poses (1 for a ``PoseEKF``)."""
    if check_input:
        P = _covariances(P)
        n, most = P.shape[1], P.shape[1] // POSE_DIM
        if not (isinstance(n_robots, (int, np.integer)) and 1 <= n_robots <= most):
            raise ValueError(f"n_robots must be an int in [1, {most}] for states of size {n}, got {n_robots!r}")
    log_dets = kernels.pose_block_log_dets(_floats(P), int(n_robots))
    if np.isnan(log_dets).any():
        raise ValueError("pose covariance is not positive definite (determinant <= 0)")
    return log_dets
