"""The batched EKF core: N filter copies on stacked arrays, states ``x (N, n)``, covariances ``P (N, n, n)``.

The same models and the same floating-point steps as ``PoseEKF`` and ``JointEKF`` (the scalar API and
the tested oracle), one leading batch dimension over env copies. A state starts with the poses of its
R robots ``[x, y, heading]`` (R = 1 for a ``PoseEKF``), followed by any static entries (mapped landmarks
``[lx, ly]``). Functions return new arrays; copies that take no measurement come back unchanged.

Every public function checks its inputs (shapes, finiteness, symmetric positive-definite noise, indices)
and raises ``ValueError`` naming the argument; ``check_input=False`` skips that for hot loops whose
inputs are known good, as the scalar filters do. ``information.log_det_spd`` gives the ``ln det`` of a
whole stack of covariances (N,); ``pose_log_dets`` those of the robots' pose blocks.
"""

from __future__ import annotations

import numpy as np

from infonav_gym.estimation.ekf import POSE_DIM, _finite, _noise_covariance, _time_step
from infonav_gym.estimation.models import GPS_POSE_JACOBIAN, _range_bearing_geometry, relative_pose_linearized
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import information_gain_of_innovation, log_det_spd

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


def _robot_count(n: int, n_robots) -> int:
    """``n_robots`` if states of size ``n`` can hold that many poses first, or ``ValueError``."""
    if not (isinstance(n_robots, (int, np.integer)) and 1 <= n_robots <= n // POSE_DIM):
        raise ValueError(f"n_robots must be an int in [1, {n // POSE_DIM}] for states of size {n}, got {n_robots!r}")
    return int(n_robots)


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
    """``PoseEKF.predict`` on every copy: the pose (first 3 entries) through the unicycle model.

    Args:
        x: states (N, n), the pose first; the other entries (mapped landmarks) are static.
        P: covariances (N, n, n).
        controls: odometry ``[speed, turn_rate]`` of each copy (N, 2) [m/s, rad/s].
        dt: time step [s], finite and >= 0.
        control_covariance: odometry noise (N, 2, 2), or one (2, 2) for all copies.
        check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.

    Returns:
        The predicted ``(x (N, n), P (N, n, n))``.
    """
    if check_input:
        x, P = _state(x, P)
        controls = _finite("controls", controls, (len(x), 2))
        dt = _time_step(dt)
        control_covariance = _noise_stack("control_covariance", control_covariance, (len(x), 2, 2))
    control_covariance = np.asarray(control_covariance)
    if control_covariance.ndim == 3:
        control_covariance = control_covariance[:, None]
    return _predict(x, P, controls[:, None], dt, np.broadcast_to(control_covariance, (len(x), 1, 2, 2)))


def predict_team(x, P, controls, dt: float, control_covariances, *, check_input: bool = True):
    """``JointEKF.predict`` on every copy: each of R robots' poses through the unicycle model.

    Args:
        x: joint states (N, 3R).
        P: their covariances (N, 3R, 3R), with or without cross-covariances.
        controls: odometry ``[speed, turn_rate]`` of each robot (N, R, 2) [m/s, rad/s].
        dt: time step [s], finite and >= 0.
        control_covariances: odometry noise of each robot (N, R, 2, 2), or (R, 2, 2) for all copies.
        check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.

    Returns:
        The predicted ``(x (N, 3R), P (N, 3R, 3R))``.
    """
    if check_input:
        x, P = _state(x, P)
        n_robots = _team_size(x.shape[1])
        controls = _finite("controls", controls, (len(x), n_robots, 2))
        dt = _time_step(dt)
        control_covariances = _noise_stack("control_covariances", control_covariances, (len(x), n_robots, 2, 2))
    return _predict(x, P, controls, dt, np.broadcast_to(control_covariances, (*np.shape(controls), 2)))


def _predict(x, P, controls, dt, control_covariances):
    """Unicycle prediction of the first R poses; ``F P F^T + Q`` with the block-diagonal pose Jacobian F."""
    n_copies, n_robots = controls.shape[:2]
    pose_end = POSE_DIM * n_robots
    poses = x[:, :pose_end].reshape(n_copies, n_robots, POSE_DIM)
    heading, speed, turn_rate = poses[..., 2], controls[..., 0], controls[..., 1]
    cos_h, sin_h = np.cos(heading), np.sin(heading)
    x_new = x.copy()
    predicted = x_new[:, :pose_end].reshape(n_copies, n_robots, POSE_DIM)
    predicted[..., 0] = poses[..., 0] + speed * dt * cos_h
    predicted[..., 1] = poses[..., 1] + speed * dt * sin_h
    predicted[..., 2] = wrap_angle(heading + turn_rate * dt)
    # F is the identity but for F[0, 2] and F[1, 2]: F X adds multiples of row 2 to rows 0 and 1 (exact zeros and
    # ones need no products), and X F^T the same with columns
    x_from_heading, y_from_heading = -speed * dt * sin_h, speed * dt * cos_h
    V = np.zeros((n_copies, n_robots, POSE_DIM, 2))
    V[..., 0, 0] = dt * cos_h
    V[..., 1, 0] = dt * sin_h
    V[..., 2, 1] = dt
    Q = V @ control_covariances @ np.swapaxes(V, -1, -2)
    n = x.shape[1]
    P_new = P.copy()
    rows = P_new[:, :pose_end].reshape(n_copies, n_robots, POSE_DIM, n)
    rows[..., 0, :] += x_from_heading[..., None] * rows[..., 2, :]
    rows[..., 1, :] += y_from_heading[..., None] * rows[..., 2, :]
    columns = P_new[:, :, :pose_end].reshape(n_copies, n, n_robots, POSE_DIM)
    columns[..., 0] += x_from_heading[:, None] * columns[..., 2]
    columns[..., 1] += y_from_heading[:, None] * columns[..., 2]
    robots = np.arange(n_robots)
    blocks = P_new[:, :pose_end, :pose_end].reshape(n_copies, n_robots, POSE_DIM, n_robots, POSE_DIM)
    blocks[:, robots, :, robots, :] += np.swapaxes(Q, 0, 1)
    return x_new, P_new


# ---------------------------------------------------------------------------------------------- measurement models


def landmark_measurement_model(x, landmarks=None, *, check_input: bool = True):
    """``PoseEKF.landmark_measurement_model`` on every copy: range-bearing to each landmark and its Jacobian.

    Args:
        x: states (N, n), the pose first, then (when mapping) the landmark estimates ``[l1x, l1y, ...]``.
        landmarks: known positions (K, 2) or per copy (N, K, 2); None to use the landmarks in the state.
        check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.

    Returns:
        ``(predicted (N, K, 2), H (N, K, 2, n))``; ``H`` has landmark columns only for mapped landmarks.

    Raises:
        ValueError: also if a landmark coincides with a copy's estimated position (its bearing is undefined).
    """
    mapped = landmarks is None
    if check_input:
        x = _states(x)
        if mapped and (x.shape[1] - POSE_DIM) % 2:
            raise ValueError(f"x must be [pose, l1x, l1y, ...], an odd number of entries, got {x.shape[1]}")
    n_copies, n = x.shape
    if mapped:
        positions = x[:, POSE_DIM:].reshape(n_copies, -1, 2)
    else:
        positions = np.asarray(landmarks, dtype=float)
        if check_input:
            per_copy = positions.ndim == 3 and len(positions) == n_copies
            if not (positions.ndim == 2 or per_copy) or positions.shape[-1] != 2:
                raise ValueError(f"landmarks must have shape (K, 2) or ({n_copies}, K, 2), got {positions.shape}")
            positions = _finite("landmarks", positions, positions.shape)
        positions = np.broadcast_to(positions, (n_copies, *positions.shape[-2:]))
    n_landmarks = positions.shape[1]
    dx = positions[..., 0] - x[:, None, 0]
    dy = positions[..., 1] - x[:, None, 1]
    flat_predicted, flat_H_pose = _range_bearing_geometry(dx.ravel(), dy.ravel(), np.repeat(x[:, 2], n_landmarks))
    predicted = flat_predicted.reshape(n_copies, n_landmarks, 2)
    H = np.zeros((n_copies, n_landmarks, 2, n))
    H[..., :POSE_DIM] = flat_H_pose.reshape(n_copies, n_landmarks, 2, POSE_DIM)
    if mapped:
        landmark_columns = H[..., POSE_DIM:].reshape(n_copies, n_landmarks, 2, n_landmarks, 2)
        own = np.arange(n_landmarks)
        landmark_columns[:, own, :, own, :] = -np.swapaxes(H[..., :2], 0, 1)
    return predicted, H


def relative_pose_model(x, observers, targets, *, check_input: bool = True):
    """``JointEKF.relative_pose_model`` on every copy: relative pose of ``targets[c, k]`` seen from ``observers[c, k]``.

    Args:
        x: joint states (N, 3R).
        observers, targets: robot indices (N, M), ``observers != targets``.
        check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.

    Returns:
        ``(predicted (N, M, 3), H_observer (N, M, 3, 3), H_target (N, M, 3, 3))``.
    """
    if check_input:
        x = _states(x)
        observers, targets = _pairs(observers, targets, len(x), _team_size(x.shape[1]))
    n_copies = len(x)
    poses = x.reshape(n_copies, -1, POSE_DIM)
    copies = np.arange(n_copies)[:, None]
    n_pairs = np.shape(observers)[1]
    predicted, H_observer, H_target = relative_pose_linearized(
        poses[copies, observers].reshape(-1, POSE_DIM), poses[copies, targets].reshape(-1, POSE_DIM)
    )
    shape = (n_copies, n_pairs, POSE_DIM)
    return predicted.reshape(shape), H_observer.reshape(*shape, POSE_DIM), H_target.reshape(*shape, POSE_DIM)


def select_candidates(chosen, *candidates) -> tuple[np.ndarray, ...]:
    """Each copy's chosen row of per-candidate arrays, and which copies chose one.

    Args:
        chosen: the chosen candidate of each copy (N,), -1 for none.
        candidates: arrays (N, K, ...) (e.g. the predicted measurements, Jacobians and noise of K landmarks).

    Returns:
        ``(observed (N,) bool, *rows)``, each row (N, ...); a copy with none gets its candidate 0 (unused).
    """
    chosen = np.asarray(chosen)
    observed = chosen >= 0
    copies, rows = np.arange(len(chosen)), np.where(observed, chosen, 0)
    return (observed, *(np.asarray(candidate)[copies, rows] for candidate in candidates))


# ---------------------------------------------------------------------------------------------- updates


def range_bearing_update(x, P, measurements, predicted, H, R, observed=None, *, check_input: bool = True):
    """``PoseEKF.update_range_bearing`` on the copies that observe a landmark; the others unchanged.

    Args:
        x: states (N, n), the pose first.
        P: covariances (N, n, n).
        measurements: the measured ``[range, bearing]`` of each copy (N, 2).
        predicted: the prior's prediction of it (N, 2), from ``landmark_measurement_model``.
        H: its Jacobian w.r.t. the state (N, 2, n).
        R: its noise covariance (N, 2, 2), symmetric positive definite.
        observed: which copies take their measurement (N,) bool; None for all.
        check_input: check shapes, finiteness, ``P`` and ``R`` (``ValueError`` naming a bad argument);
            ``False`` for known-good inputs.

    Returns:
        The updated ``(x, P)``; covariances symmetrized, headings wrapped.
    """
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
    residual = np.subtract(measurements, predicted)
    residual[:, 1] = wrap_angle(residual[:, 1])
    if observed.all():
        return _kalman_update(x, P, residual, H, R, [2])
    x_new, P_new = np.array(x, dtype=float), np.array(P, dtype=float)
    copies = np.flatnonzero(observed)
    if copies.size:
        x_new[copies], P_new[copies] = _kalman_update(x[copies], P[copies], residual[copies], H[copies], R[copies], [2])
    return x_new, P_new


def gps_update(x, P, fixes, noise_covariances, has_fix, *, cross_covariances: bool = True, check_input: bool = True):
    """``JointEKF.gps_update`` on every copy: the position fixes ``[x, y]`` of the robots that have one.

    Args:
        x: joint states (N, 3R).
        P: their covariances (N, 3R, 3R).
        fixes: measured positions of every robot (N, R, 2); only those with ``has_fix`` are used.
        noise_covariances: the fixes' noise (N, R, 2, 2) or (R, 2, 2), symmetric positive definite.
        has_fix: which robots of which copy have a fix (N, R) bool.
        cross_covariances: keep the cross-covariances (False: each robot keeps its own block, as ``JointEKF``).
        check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.

    Returns:
        The updated ``(x, P)``; copies without any fix unchanged.
    """
    if check_input:
        x, P = _state(x, P)
        n_robots = _team_size(x.shape[1])
        has_fix = _mask("has_fix", has_fix, (len(x), n_robots))
        fixes = _finite("fixes", fixes, (len(x), n_robots, 2))
        noise_covariances = _noise_stack("noise_covariances", noise_covariances, (len(x), n_robots, 2, 2))
    noise_covariances = np.broadcast_to(noise_covariances, (*np.shape(fixes), 2))
    jacobians = np.broadcast_to(GPS_POSE_JACOBIAN, (*np.shape(fixes), POSE_DIM))

    def update(x_group, P_group, slot_of):
        robots = slot_of(np.broadcast_to(np.arange(x.shape[1] // POSE_DIM), has_fix.shape))
        H = _stacked_jacobian(robots, slot_of(jacobians), x.shape[1])
        measurement = slot_of(np.asarray(fixes, dtype=float)).reshape(len(x_group), -1)
        residual = measurement - (H @ x_group[:, :, None])[:, :, 0]
        return _kalman_update(x_group, P_group, residual, H, _block_diagonal(slot_of(noise_covariances)), _headings(x))

    return _grouped_update(x, P, has_fix, update, cross_covariances)


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
    """``JointEKF.relative_pose_update`` on every copy: its observed relative poses as one stacked update.

    Slot ``k`` of copy ``c`` is ``[range, bearing, relative heading]`` (m = 3) or ``[range, bearing]``
    (m = 2) of robot ``targets[c, k]`` seen from robot ``observers[c, k]``; the observed slots of a copy
    are fused together in slot order, as ``JointEKF`` fuses the measurements it is given.

    Args:
        x: joint states (N, 3R).
        P: their covariances (N, 3R, 3R).
        observers, targets: robot indices (N, M).
        measurements, predicted: (N, M, m); ``predicted`` from ``relative_pose_model`` at the prior.
        H_observer, H_target: their Jacobians (N, M, m, 3) (the first m rows of ``relative_pose_model``'s).
        R: noise covariances (N, M, m, m), symmetric positive definite.
        observed: which slots are measured (N, M) bool; None for all.
        cross_covariances: keep the cross-covariances (False: each robot keeps its own block, as ``JointEKF``).
        check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.

    Returns:
        The updated ``(x, P)``; copies without any observed slot unchanged.
    """
    if check_input:
        x, P = _state(x, P)
        observers = np.asarray(observers)
        if observed is not None:
            observed = _mask("observed", observed, observers.shape)
        observers, targets = _pairs(observers, targets, len(x), _team_size(x.shape[1]), observed)
    if observed is None:
        observed = np.ones(np.shape(observers), dtype=bool)
    if check_input:
        m = np.shape(measurements)[-1] if np.ndim(measurements) == 3 and np.shape(measurements)[-1] == 2 else 3
        measurements = _finite("measurements", measurements, (*observers.shape, m))
        predicted = _finite("predicted", predicted, (*observers.shape, m))
        H_observer = _finite("H_observer", H_observer, (*observers.shape, m, POSE_DIM))
        H_target = _finite("H_target", H_target, (*observers.shape, m, POSE_DIM))
        R = _noise_covariance("R", R, (*observers.shape, m, m))
    n = x.shape[1]
    residual = np.subtract(measurements, predicted)
    residual[..., 1:] = wrap_angle(residual[..., 1:])

    def update(x_group, P_group, slot_of):
        H = _stacked_jacobian(slot_of(observers), slot_of(H_observer), n)
        H = H + _stacked_jacobian(slot_of(targets), slot_of(H_target), n)
        flat_residual = slot_of(residual).reshape(len(x_group), -1)
        return _kalman_update(x_group, P_group, flat_residual, H, _block_diagonal(slot_of(R)), _headings(x))

    return _grouped_update(x, P, observed, update, cross_covariances)


def team_landmark_update(
    x, P, robots, measurements, predicted, H_pose, R, observed=None, *, cross_covariances=True, check_input=True
):
    """``JointEKF.landmark_update`` on every copy: its robots' range-bearing measurements of known landmarks.

    Slot ``k`` of copy ``c`` is ``[range, bearing]`` of a landmark seen by robot ``robots[c, k]``; the observed
    slots of a copy are fused together in slot order, as one stacked update.

    Args:
        x: joint states (N, 3R).
        P: their covariances (N, 3R, 3R).
        robots: the observers' indices (N, M).
        measurements, predicted: (N, M, 2); ``predicted`` from ``landmark_measurement_model`` at the prior.
        H_pose: its Jacobian w.r.t. the observer's pose (N, M, 2, 3).
        R: noise covariances (N, M, 2, 2), symmetric positive definite.
        observed: which slots are measured (N, M) bool; None for all.
        cross_covariances: keep the cross-covariances (False: each robot keeps its own block, as ``JointEKF``).
        check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.

    Returns:
        The updated ``(x, P)``; copies without any observed slot unchanged.
    """
    if check_input:
        x, P = _state(x, P)
        robots = np.asarray(robots)
        if robots.ndim != 2 or len(robots) != len(x):
            raise ValueError(f"robots must have shape ({len(x)}, M), got {robots.shape}")
        robots = _indices("robots", robots, robots.shape, _team_size(x.shape[1]))
        if observed is not None:
            observed = _mask("observed", observed, robots.shape)
        measurements = _finite("measurements", measurements, (*robots.shape, 2))
        predicted = _finite("predicted", predicted, (*robots.shape, 2))
        H_pose = _finite("H_pose", H_pose, (*robots.shape, 2, POSE_DIM))
        R = _noise_covariance("R", R, (*robots.shape, 2, 2))
    if observed is None:
        observed = np.ones(np.shape(robots), dtype=bool)
    residual = np.subtract(measurements, predicted)
    residual[..., 1] = wrap_angle(residual[..., 1])

    def update(x_group, P_group, slot_of):
        H = _stacked_jacobian(slot_of(robots), slot_of(H_pose), x.shape[1])
        flat_residual = slot_of(residual).reshape(len(x_group), -1)
        return _kalman_update(x_group, P_group, flat_residual, H, _block_diagonal(slot_of(R)), _headings(x))

    return _grouped_update(x, P, observed, update, cross_covariances)


def _headings(x: np.ndarray) -> np.ndarray:
    """The heading entries of joint states (N, 3R)."""
    return np.arange(2, x.shape[1], POSE_DIM)


def _grouped_update(x, P, used: np.ndarray, update, cross_covariances: bool):
    """Run ``update`` on the copies grouped by how many slots they use, so each group stacks alike.

    Args:
        x, P: the joint states and covariances (N, 3R), (N, 3R, 3R).
        used: which slots of each copy carry a measurement (N, M) bool.
        update: ``(x_group, P_group, slot_of) -> (x, P)``; ``slot_of(a)`` picks the group's used slots of an
            (N, M, ...) array, in slot order, as (G, k, ...).
        cross_covariances: False zeroes the cross-robot blocks of the updated copies.
    """
    x_new, P_new = np.array(x, dtype=float), np.array(P, dtype=float)
    counts = used.sum(axis=1)
    for count in np.unique(counts[counts > 0]):
        copies = np.flatnonzero(counts == count)
        slots = np.nonzero(used[copies])[1].reshape(len(copies), count)

        def slot_of(array, copies=copies, slots=slots):
            return np.asarray(array)[copies[:, None], slots]

        x_group, P_group = update(x[copies], P[copies], slot_of)
        if not cross_covariances:
            P_group = P_group * _own_blocks(x.shape[1] // POSE_DIM)
        x_new[copies], P_new[copies] = x_group, P_group
    return x_new, P_new


def _own_blocks(n_robots: int) -> np.ndarray:
    """(3R, 3R) ones on each robot's own 3x3 block, zeros elsewhere."""
    return np.kron(np.eye(n_robots), np.ones((POSE_DIM, POSE_DIM)))


def _stacked_jacobian(robots: np.ndarray, blocks: np.ndarray, n: int) -> np.ndarray:
    """(G, k m, n) Jacobians whose k-th row block holds ``blocks[:, k]`` (m, 3) in robot ``robots[:, k]``'s columns."""
    n_copies, k, m, _ = blocks.shape
    H = np.zeros((n_copies, k, m, n // POSE_DIM, POSE_DIM))
    H[np.arange(n_copies)[:, None], np.arange(k), :, robots, :] = blocks
    return H.reshape(n_copies, k * m, n)


def _block_diagonal(blocks: np.ndarray) -> np.ndarray:
    """(G, k m, k m) block-diagonal matrices of (G, k, m, m) ``blocks``."""
    n_copies, k, m, _ = blocks.shape
    matrix = np.zeros((n_copies, k, m, k, m))
    matrix[:, np.arange(k), :, np.arange(k), :] = np.swapaxes(blocks, 0, 1)
    return matrix.reshape(n_copies, k * m, k * m)


def _inverse(S: np.ndarray) -> np.ndarray:
    """Inverses of small SPD matrices (..., m, m): by cofactors up to 3 x 3 (``_inverse_entries``), else LAPACK.

    On stacks of thousands of them the cofactors are far faster than LAPACK's per-matrix calls.
    """
    if S.shape[-1] > 3:
        return np.linalg.inv(S)
    return np.moveaxis(_inverse_entries(np.moveaxis(S, (-2, -1), (0, 1))), (0, 1), (-2, -1))


def _kalman_update(x, P, residual, H, R, heading_indices):
    """The EKF update of ``PoseEKF`` / ``JointEKF`` on (G,) copies, step for step; covariance symmetrized.

    ``K = P H^T S^-1`` with ``S = H P H^T + R``; ``x + K y`` with headings wrapped; ``P - K (P H^T)^T``.
    """
    K, P_new = _gain_and_posterior(P, H, R)
    x_new = x + (K @ residual[:, :, None])[:, :, 0]
    x_new[:, heading_indices] = wrap_angle(x_new[:, heading_indices])
    return x_new, P_new


def _gain_and_posterior(P, H, R) -> tuple[np.ndarray, np.ndarray]:
    """The Kalman gain ``K`` (G, n, m) and posterior covariance (G, n, n), symmetrized, of an update."""
    PHT = P @ np.swapaxes(H, 1, 2)
    S = H @ PHT + R
    K = PHT @ _inverse(S)
    P_new = P - K @ np.swapaxes(PHT, 1, 2)
    return K, 0.5 * (P_new + np.swapaxes(P_new, 1, 2))


def _jacobians(H, P: np.ndarray, inner: tuple[str, ...]) -> np.ndarray:
    """``H`` as a finite float array (N, *inner, n) for the covariances ``P`` (N, n, n), else ``ValueError``."""
    H = np.asarray(H, dtype=float)
    if H.ndim != 2 + len(inner) or H.shape[0] != len(P) or H.shape[-1] != P.shape[1]:
        raise ValueError(f"H must have shape ({len(P)}, {', '.join(inner)}, {P.shape[1]}), got {H.shape}")
    return _finite("H", H, H.shape)


def posterior_covariance(P, H, R, *, check_input: bool = True) -> np.ndarray:
    """The covariance after an EKF update of each copy (N, n, n): it does not depend on the measured value.

    ``P - K H P`` as ``range_bearing_update`` and the team updates compute it. A zero row of ``H`` with
    its own unit noise (no correlation with the other rows) is no measurement: it leaves ``P`` unchanged.

    Args:
        P: prior covariances (N, n, n).
        H: stacked measurement Jacobians (N, m, n).
        R: their noise covariances (N, m, m), symmetric positive definite.
        check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.
    """
    if check_input:
        P = _covariances(P)
        H = _jacobians(H, P, ("m",))
        R = _noise_covariance("R", R, (len(P), H.shape[1], H.shape[1]))
    return _gain_and_posterior(P, H, R)[1]


# ---------------------------------------------------------------------------------------------- information


def landmark_information_gains(P, H, R, *, check_input: bool = True) -> np.ndarray:
    """Expected MI [nats] of observing each candidate, alone at each copy's prior: ``0.5 ln(det S / det R)``.

    Args:
        P: prior covariances (N, n, n).
        H: candidates' Jacobians (N, K, m, n).
        R: their noise covariances (N, K, m, m).
        check_input: check shapes, finiteness, ``P`` and ``R``; ``False`` for known-good inputs.

    Returns:
        (N, K) gains.
    """
    if check_input:
        P = _covariances(P)
        H = _jacobians(H, P, ("K", "m"))
        R = _noise_covariance("R", R, (*H.shape[:3], H.shape[2]))
    n_copies, n_candidates, m, n = H.shape
    HP = np.matmul(H.reshape(n_copies, n_candidates * m, n), P).reshape(H.shape)  # one product per copy: fast
    HPHT = _product(np.moveaxis(HP, (-2, -1), (0, 1)), np.moveaxis(H, (-2, -1), (1, 0)))  # entries first
    return information_gain_of_innovation(np.moveaxis(HPHT, (0, 1), (-2, -1)) + R, R, check_input=False)


def _product(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``X @ Y`` of small matrices stored components first, (m, k, ...) @ (k, n, ...) -> (m, n, ...).

    Each entry is a contiguous array over the stack, so thousands of 3 x 3 products take a few dozen
    array operations: several times faster than ``matmul``'s per-matrix loop.
    """
    product = np.empty((X.shape[0], Y.shape[1], *np.broadcast_shapes(X.shape[2:], Y.shape[2:])))
    for i in range(X.shape[0]):
        for j in range(Y.shape[1]):
            entry = X[i, 0] * Y[0, j]  # a new array: += below is in place
            for k in range(1, X.shape[1]):
                entry += X[i, k] * Y[k, j]
            product[i, j] = entry
    return product


def _inverse_entries(M: np.ndarray) -> np.ndarray:
    """Inverses of matrices stored entries first (m, m, ...): the adjugate over the determinant, m <= 3."""
    m = len(M)
    if m == 1:
        return 1.0 / M
    if m == 2:
        adjugate = np.array([[M[1, 1], -M[0, 1]], [-M[1, 0], M[0, 0]]])
    else:
        adjugate = np.empty_like(M)
        for i in range(3):
            for j in range(3):
                rows, columns = [r for r in range(3) if r != j], [c for c in range(3) if c != i]
                minor = (
                    M[rows[0], columns[0]] * M[rows[1], columns[1]] - M[rows[0], columns[1]] * M[rows[1], columns[0]]
                )
                adjugate[i, j] = minor if (i + j) % 2 == 0 else -minor
    determinant = sum(M[0, j] * adjugate[j, 0] for j in range(m))  # the first row of M adjugate
    return adjugate / determinant


def relative_pose_information_gains(P, observers, targets, H_observer, H_target, R, *, check_input: bool = True):
    """``JointEKF.relative_pose_information_gains`` on every copy [nats].

    Args:
        P: joint covariances (N, 3R, 3R).
        observers, targets: candidate pairs' robot indices (N, M).
        H_observer, H_target: their Jacobians (N, M, m, 3).
        R: their noise covariances (N, M, m, m).
        check_input: check the arguments (``ValueError`` naming a bad one); ``False`` for known-good inputs.

    Returns:
        ``(own, joint)``, each (N, M): the MI on the observer's own pose and on the joint state.
    """
    n_copies = len(P)
    if check_input:
        P = _covariances(P)
        observers, targets = _pairs(observers, targets, n_copies, _team_size(P.shape[1]))
        m = np.shape(H_observer)[-2] if np.ndim(H_observer) == 4 else 3
        H_observer = _finite("H_observer", H_observer, (*observers.shape, m, POSE_DIM))
        H_target = _finite("H_target", H_target, (*observers.shape, m, POSE_DIM))
        R = _noise_covariance("R", R, (*observers.shape, m, m))
    # matrices as components first: (rows, columns, N, M), each entry a contiguous (N, M) array
    n_robots = P.shape[1] // POSE_DIM
    blocks = np.moveaxis(P.reshape(n_copies, n_robots, POSE_DIM, n_robots, POSE_DIM), (2, 4), (0, 1))
    blocks = blocks.reshape(POSE_DIM * POSE_DIM, -1)  # (9, N R R): the pose blocks' entries, block [c, i, j] last
    first_block = (np.arange(n_copies) * n_robots * n_robots)[:, None]

    def block_entries(rows, columns):
        return blocks.take(first_block + rows * n_robots + columns, axis=1).reshape(POSE_DIM, POSE_DIM, *rows.shape)

    P_oo, P_ot = block_entries(observers, observers), block_entries(observers, targets)
    P_to, P_tt = block_entries(targets, observers), block_entries(targets, targets)
    H_observer, H_target, R = (
        np.ascontiguousarray(np.moveaxis(M, (-2, -1), (0, 1))) for M in (H_observer, H_target, R)
    )
    H_observer_T, H_target_T = H_observer.swapaxes(0, 1), H_target.swapaxes(0, 1)
    A = _product(P_oo, H_observer_T) + _product(P_ot, H_target_T)  # the observer's rows of P H^T
    B = _product(P_to, H_observer_T) + _product(P_tt, H_target_T)  # the target's
    S = _product(H_observer, A) + _product(H_target, B) + R
    posterior = P_oo - _product(_product(A, _inverse_entries(S)), A.swapaxes(0, 1))
    log_dets = [log_det_spd(np.moveaxis(M, (0, 1), (-2, -1)), check_input=False) for M in (P_oo, posterior, S, R)]
    return 0.5 * (log_dets[0] - log_dets[1]), 0.5 * (log_dets[2] - log_dets[3])


def pose_blocks(P) -> np.ndarray:
    """Joint covariances (N, 3R, 3R) as (N, R, R, 3, 3) blocks: ``[c, i, j]`` is robot i's pose with robot j's."""
    n_copies, n, _ = np.shape(P)
    n_robots = n // POSE_DIM
    return np.reshape(P, (n_copies, n_robots, POSE_DIM, n_robots, POSE_DIM)).transpose(0, 1, 3, 2, 4)


def pose_log_dets(P, n_robots: int = 1, *, check_input: bool = True) -> np.ndarray:
    """``ln det`` of each robot's own pose covariance block (N, R): the first ``3 n_robots`` entries of the state.

    Args:
        P: covariances (N, n, n), the R poses first.
        n_robots: how many poses lead the state (1 for a ``PoseEKF``).
        check_input: check ``P`` and ``n_robots``; ``False`` for known-good inputs.
    """
    if check_input:
        P = _covariances(P)
        n_robots = _robot_count(P.shape[1], n_robots)
    pose_end = POSE_DIM * n_robots
    robots = np.arange(n_robots)
    own = pose_blocks(np.asarray(P)[:, :pose_end, :pose_end])[:, robots, robots]
    return log_det_spd(own, "pose covariance", check_input=False)
