"""Compiled kernels of the batched EKF core (``batched``): loops over the copies, the small matrix algebra written out.

Each takes C-contiguous float64 stacks (bool, int64 for masks, indices), copies first, and returns new arrays, unchecked
(``batched`` checks): an undefined result (a determinant <= 0, a landmark on the sensor) is NaN or a flag for the caller
to raise on. States start with R robot poses ``[x, y, heading]``; covariances are symmetric.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import inlined_kernel, inner_kernel, kernel
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.information import log_det_of, mutual_information_kernel

POSE_DIM = 3
COINCIDENT_SQUARED_RANGE = 1e-18  # [m^2] a target this close to the sensor has no defined bearing


@kernel
def predict_poses(x, P, controls, dt, control_covariances):
    """Unicycle prediction of the first R poses of every copy: ``x`` (N, n), ``P`` (N, n, n), ``controls`` (N, R, 2)
    ``[speed, turn_rate]`` with noise ``control_covariances`` (N, R, 2, 2), ``dt`` [s]. ``P`` becomes ``F P F^T + V C
    V^T``, F the identity but for each pose's ``F[0, 2]``, ``F[1, 2]``: F P adds multiples of the heading row to the x
    and y rows, P F^T the same with columns; V C V^T lands on each robot's own 3 x 3 block."""
    n_copies, n = x.shape
    n_robots = controls.shape[1]
    x_new, P_new = x.copy(), P.copy()
    x_from_heading, y_from_heading = np.empty(n_robots), np.empty(n_robots)
    for c in range(n_copies):
        for robot in range(n_robots):
            i = POSE_DIM * robot
            heading, speed, turn_rate = x[c, i + 2], controls[c, robot, 0], controls[c, robot, 1]
            cos_h, sin_h = math.cos(heading), math.sin(heading)
            x_new[c, i] = x[c, i] + speed * dt * cos_h
            x_new[c, i + 1] = x[c, i + 1] + speed * dt * sin_h
            x_new[c, i + 2] = wrap(heading + turn_rate * dt)
            x_from_heading[robot], y_from_heading[robot] = -speed * dt * sin_h, speed * dt * cos_h
            for j in range(n):
                P_new[c, i, j] += x_from_heading[robot] * P_new[c, i + 2, j]
                P_new[c, i + 1, j] += y_from_heading[robot] * P_new[c, i + 2, j]
        for robot in range(n_robots):
            i = POSE_DIM * robot
            for j in range(n):
                P_new[c, j, i] += x_from_heading[robot] * P_new[c, j, i + 2]
                P_new[c, j, i + 1] += y_from_heading[robot] * P_new[c, j, i + 2]
        for robot in range(n_robots):
            i = POSE_DIM * robot
            cos_h, sin_h = math.cos(x[c, i + 2]), math.sin(x[c, i + 2])
            v = (dt * cos_h, dt * sin_h, dt)  # V = [[v[0], 0], [v[1], 0], [0, v[2]]]: row a's entry in column a // 2
            for a in range(POSE_DIM):
                for b in range(POSE_DIM):
                    P_new[c, i + a, i + b] += v[a] * control_covariances[c, robot, a // 2, b // 2] * v[b]
    return x_new, P_new


@kernel
def range_bearing_models(x, positions, mapped):
    """Range-bearing from each copy's pose (states ``x`` (N, n)) to each landmark ``positions`` (N, K, 2) and its
    Jacobian w.r.t. the state, ``(predicted (N, K, 2), H (N, K, 2, n), coincident)``; with ``mapped`` the positions are
    the state's entries ``3 + 2k`` and ``H`` has their columns too. ``coincident``: some landmark lies on its sensor."""
    n_copies, n = x.shape
    n_landmarks = positions.shape[1]
    predicted, H = np.empty((n_copies, n_landmarks, 2)), np.zeros((n_copies, n_landmarks, 2, n))
    coincident = False
    for c in range(n_copies):
        for k in range(n_landmarks):
            dx, dy = positions[c, k, 0] - x[c, 0], positions[c, k, 1] - x[c, 1]
            J = H[c, k]
            if not range_bearing_of_offset(dx, dy, x[c, 2], predicted[c, k], J):
                coincident = True
            elif mapped:
                column = POSE_DIM + 2 * k
                J[0, column], J[0, column + 1] = -J[0, 0], -J[0, 1]
                J[1, column], J[1, column + 1] = -J[1, 0], -J[1, 1]
    return predicted, H, coincident


@inner_kernel
def range_bearing_of_offset(dx, dy, heading, predicted, J) -> bool:
    """Range-bearing of a target at ``(dx, dy)`` from a sensor at ``heading`` into ``predicted[:2]``, its Jacobian
    w.r.t. the sensor's pose into ``J[:2, :3]``; False (and nothing written) if the target is on the sensor."""
    squared_range = dx * dx + dy * dy
    if squared_range < COINCIDENT_SQUARED_RANGE:
        return False
    distance = math.sqrt(squared_range)
    predicted[0], predicted[1] = distance, wrap(math.atan2(dy, dx) - heading)
    J[0, 0], J[0, 1] = -dx / distance, -dy / distance
    J[1, 0], J[1, 1], J[1, 2] = dy / squared_range, -dx / squared_range, -1.0
    return True


@kernel
def relative_pose_models(x, observers, targets):
    """Range, bearing and relative heading of robot ``targets[c, k]`` seen from robot ``observers[c, k]``, with the
    Jacobians w.r.t. the two poses and whether some target lies on its observer: ``(predicted (N, M, 3), H_observer
    (N, M, 3, 3), H_target (N, M, 3, 3), coincident)``."""
    n_copies, n_pairs = observers.shape
    predicted = np.empty((n_copies, n_pairs, POSE_DIM))
    H_observer = np.zeros((n_copies, n_pairs, POSE_DIM, POSE_DIM))
    H_target = np.zeros((n_copies, n_pairs, POSE_DIM, POSE_DIM))
    coincident = False
    for c in range(n_copies):
        for k in range(n_pairs):
            o, t = POSE_DIM * observers[c, k], POSE_DIM * targets[c, k]
            J_o, J_t = H_observer[c, k], H_target[c, k]
            dx, dy = x[c, t] - x[c, o], x[c, t + 1] - x[c, o + 1]
            if not range_bearing_of_offset(dx, dy, x[c, o + 2], predicted[c, k], J_o):
                coincident = True
                continue
            predicted[c, k, 2] = wrap(x[c, t + 2] - x[c, o + 2])
            J_o[2, 2], J_t[2, 2] = -1.0, 1.0
            J_t[0, 0], J_t[0, 1], J_t[1, 0], J_t[1, 1] = -J_o[0, 0], -J_o[0, 1], -J_o[1, 0], -J_o[1, 1]
    return predicted, H_observer, H_target, coincident


@inner_kernel
def invert(S, r, inverse, pivoted, order):
    """The inverse of the leading (r, r) block of ``S`` into ``inverse``: the adjugate over the determinant up to 3 x 3,
    else ``gauss_jordan_inverse`` (``pivoted`` (r, r) and ``order`` (r,) int: its scratch)."""
    if r == 1:
        inverse[0, 0] = 1.0 / S[0, 0]
    elif r == 2:
        determinant = S[0, 0] * S[1, 1] + S[0, 1] * -S[1, 0]
        inverse[0, 0], inverse[0, 1] = S[1, 1] / determinant, -S[0, 1] / determinant
        inverse[1, 0], inverse[1, 1] = -S[1, 0] / determinant, S[0, 0] / determinant
    elif r == 3:
        for i in range(3):
            for j in range(3):  # the cofactor of S[j, i]: the minor without row j and column i, signed
                r0, r1 = (1, 2) if j == 0 else ((0, 2) if j == 1 else (0, 1))
                c0, c1 = (1, 2) if i == 0 else ((0, 2) if i == 1 else (0, 1))
                minor = S[r0, c0] * S[r1, c1] - S[r0, c1] * S[r1, c0]
                inverse[i, j] = minor if (i + j) % 2 == 0 else -minor
        determinant = S[0, 0] * inverse[0, 0] + S[0, 1] * inverse[1, 0] + S[0, 2] * inverse[2, 0]
        for i in range(3):
            for j in range(3):
                inverse[i, j] /= determinant
    else:
        gauss_jordan_inverse(S, r, inverse, pivoted, order)


@inner_kernel
def gauss_jordan_inverse(S, r, inverse, A, order):
    """The inverse of the leading (r, r) block of ``S`` into ``inverse`` by Gauss-Jordan elimination with partial
    pivoting of its copy ``A``, leaving out the columns of ``A`` at and left of the pivot (no later step reads them)
    and the inverse's columns still exact zeros (``order[:j + 1]``, (r,) int scratch, holds the identity columns of
    the rows pivoted so far): adding a zero product changes no number, so the result is the full one's."""
    for i in range(r):
        order[i] = i
        for k in range(r):
            A[i, k] = S[i, k]
            inverse[i, k] = 1.0 if i == k else 0.0
    for j in range(r):
        pivot = j
        for i in range(j + 1, r):
            if abs(A[i, j]) > abs(A[pivot, j]):
                pivot = i
        if pivot != j:
            for k in range(j, r):
                A[j, k], A[pivot, k] = A[pivot, k], A[j, k]
            for k in range(r):
                inverse[j, k], inverse[pivot, k] = inverse[pivot, k], inverse[j, k]
            order[j], order[pivot] = order[pivot], order[j]
        scale = 1.0 / A[j, j]
        for k in range(j + 1, r):
            A[j, k] *= scale
        for t in range(j + 1):
            inverse[j, order[t]] *= scale
        for i in range(r):
            if i != j and A[i, j] != 0.0:
                factor = A[i, j]
                for k in range(j + 1, r):
                    A[i, k] -= factor * A[j, k]
                for t in range(j + 1):
                    inverse[i, order[t]] -= factor * inverse[j, order[t]]


@inner_kernel
def nonzero_columns(rows, columns) -> int:
    """How many columns of ``rows`` (r, n) hold a non-zero entry (the state entries a measurement depends on); their
    indices into ``columns[:count]``."""
    count = 0
    for column in range(rows.shape[1]):
        for i in range(rows.shape[0]):
            if rows[i, column] != 0.0:
                columns[count] = column
                count += 1
                break
    return count


@kernel
def kalman_updates(x, P, residuals, H, R, used, n_headings, cross_covariances):
    """The EKF update of every copy (``x`` (N, n), ``P`` (N, n, n)) with its ``used`` (N, M) measurement slots stacked
    in slot order, the others unchanged: ``residuals`` (N, M, m) measured minus predicted, angles wrapped; ``H`` (N, M,
    m, n), ``R`` (N, M, m, m) each slot's Jacobian and noise. ``K = P H^T S^-1``, ``S = H P H^T + R``; ``x + K y``, the
    first ``n_headings`` headings wrapped; ``P - K (P H^T)^T`` symmetrized, without ``cross_covariances`` only each
    robot's own 3 x 3 blocks kept (``JointEKF``'s option)."""
    n_copies, n_slots, m, n = H.shape
    most = n_slots * m
    x_new, P_new = x.copy(), P.copy()
    rows, y, HP = np.empty((most, n)), np.empty(most), np.empty((most, n))
    supports, support_sizes = np.empty((most, n), dtype=np.int64), np.empty(most, dtype=np.int64)
    S, S_inverse, pivoted = np.empty((most, most)), np.empty((most, most)), np.empty((most, most))
    order, K, correction = np.empty(most, dtype=np.int64), np.empty((n, most)), np.empty(n)
    for c in range(n_copies):
        r = stacked_slots(H[c], residuals[c], used[c], rows, y, supports, support_sizes)
        if r == 0:
            continue
        innovation_covariance(P[c], R[c], used[c], rows, supports, support_sizes, r, HP, S)
        invert(S, r, S_inverse, pivoted, order)
        kalman_gain(HP, S_inverse, r, K)
        for i in range(n):
            total = 0.0
            for j in range(r):
                total += K[i, j] * y[j]
            x_new[c, i] = x[c, i] + total
        for robot in range(n_headings):
            x_new[c, POSE_DIM * robot + 2] = wrap(x_new[c, POSE_DIM * robot + 2])
        corrected_covariance(P[c], K, HP, r, cross_covariances, correction, P_new[c])
    return x_new, P_new


@inner_kernel
def stacked_slots(H, residuals, used, rows, y, supports, support_sizes) -> int:
    """Stack one copy's used slots in slot order, how many rows r: Jacobian rows into ``rows`` (r, n), residuals into
    ``y`` (r,), each row's non-zero columns (all the products visit) into ``supports[row, :support_sizes[row]]``."""
    n_slots, m, n = H.shape
    r = 0
    for slot in range(n_slots):
        if not used[slot]:
            continue
        for i in range(m):
            y[r] = residuals[slot, i]
            size = 0
            for j in range(n):
                rows[r, j] = H[slot, i, j]
                if rows[r, j] != 0.0:
                    supports[r, size] = j
                    size += 1
            support_sizes[r] = size
            r += 1
    return r


@inner_kernel
def innovation_covariance(P, R, used, rows, supports, support_sizes, r, HP, S):
    """``S = H P H^T + R`` of one copy's ``stacked_slots`` (``R`` (M, m, m) of its ``used`` slots on the diagonal),
    and on the way ``HP`` (r, n): ``P H^T`` transposed, row j is ``P`` times the Jacobian's row j."""
    m = R.shape[1]
    rows_times(rows, supports, support_sizes, r, P, P.shape[0], HP)
    rows_times(rows, supports, support_sizes, r, HP, r, S)
    offset = 0
    for slot in range(len(used)):
        if used[slot]:
            for i in range(m):
                for j in range(m):
                    S[offset + i, offset + j] += R[slot, i, j]
            offset += m


@inner_kernel
def rows_times(rows, supports, support_sizes, r, X, n_x, product):
    """``product[a, b] = sum_t rows[a, t] X[b, t]`` for the first r rows and ``n_x`` rows of ``X``: ``rows (X^T)``, each
    sum over its row's support in column order from 0.0 (the numbers of the sum over every column)."""
    for a in range(r):
        for b in range(n_x):
            product[a, b] = 0.0
        for t in range(support_sizes[a]):
            column = supports[a, t]
            h = rows[a, column]
            for b in range(n_x):
                product[a, b] += h * X[b, column]


@inner_kernel
def kalman_gain(HP, S_inverse, r, K):
    """``K = P H^T S^-1`` (n, r) from ``innovation_covariance``'s ``HP`` and ``S^-1`` (r, r). Each entry sums its
    products in order; the loops run the innermost along a row, which the compiler vectorizes."""
    for i in range(HP.shape[1]):
        for j in range(r):
            K[i, j] = 0.0
        for t in range(r):
            a = HP[t, i]
            for j in range(r):
                K[i, j] += a * S_inverse[t, j]


@inner_kernel
def corrected_covariance(P, K, HP, r, cross_covariances, correction, P_new):
    """``P - K (P H^T)^T`` into ``P_new`` (n, n), symmetrized, from ``kalman_gain``'s ``K`` and ``HP``; without
    ``cross_covariances`` only each robot's own 3 x 3 blocks are kept. ``correction`` (n,): scratch of one row."""
    n = P.shape[0]
    for i in range(n):
        for j in range(n):
            correction[j] = 0.0
        for t in range(r):
            a = K[i, t]
            for j in range(n):
                correction[j] += a * HP[t, j]
        for j in range(n):
            P_new[i, j] = P[i, j] - correction[j]
    for i in range(n):
        for j in range(i + 1, n):
            if not cross_covariances and i // POSE_DIM != j // POSE_DIM:
                P_new[i, j] = P_new[j, i] = 0.0
            else:
                P_new[i, j] = P_new[j, i] = 0.5 * (P_new[i, j] + P_new[j, i])


@kernel
def gps_updates(x, P, fixes, R, has_fix, cross_covariances):
    """``kalman_updates`` of each robot's position fix (N, R, 2) where ``has_fix`` (N, R), noise ``R`` (N, R, 2, 2)."""
    n_copies, n = x.shape
    n_robots = n // POSE_DIM
    residuals, H = np.empty((n_copies, n_robots, 2)), np.zeros((n_copies, n_robots, 2, n))
    for c in range(n_copies):
        for robot in range(n_robots):
            for i in range(2):  # the fix minus H x, the robot's position
                residuals[c, robot, i] = fixes[c, robot, i] - x[c, POSE_DIM * robot + i]
                H[c, robot, i, POSE_DIM * robot + i] = 1.0
    return kalman_updates(x, P, residuals, H, R, has_fix, n_robots, cross_covariances)


@inlined_kernel
def chosen_landmark_updates(x, P, measurements, chosen, predicted, H, R, prior_log_det):
    """The EKF update of each copy with its measured ``[range, bearing]`` (N, 2) of its ``chosen`` (N,) candidate
    (-1: none, unchanged), the candidates' ``predicted`` (N, K, 2), ``H`` (N, K, 2, n) and ``R`` (N, K, 2, 2):
    ``(x, P, realized MI (N,))``, MI ``0.5 (prior_log_det - ln det P_post)`` [nats] (0 without a measurement, NaN where
    a posterior determinant is not > 0)."""
    n_copies, n = x.shape
    residuals, rows = np.zeros((n_copies, 1, 2)), np.zeros((n_copies, 1, 2, n))
    noise, used = np.zeros((n_copies, 1, 2, 2)), np.zeros((n_copies, 1), dtype=np.bool_)
    for c in range(n_copies):
        k = chosen[c]
        if k < 0:
            continue
        used[c, 0] = True
        residuals[c, 0, 0] = measurements[c, 0] - predicted[c, k, 0]
        residuals[c, 0, 1] = wrap(measurements[c, 1] - predicted[c, k, 1])
        for i in range(2):  # element by element: a slice assignment compiles numba's shape-error formatting
            for j in range(2):
                noise[c, 0, i, j] = R[c, k, i, j]
            for j in range(n):
                rows[c, 0, i, j] = H[c, k, i, j]
    x_new, P_new = kalman_updates(x, P, residuals, rows, noise, used, 1, True)
    realized = np.zeros(n_copies)
    for c in range(n_copies):
        if used[c, 0]:
            realized[c] = mutual_information_kernel(prior_log_det[c], log_det_of(P_new[c]))
    return x_new, P_new, realized


@kernel
def landmark_gains(P, H, R):
    """``landmark_gain`` of each candidate (N, K) [nats]: ``P`` (N, n, n), ``H`` (N, K, m, n), ``R`` (N, K, m, m)."""
    n_copies, n_candidates, m, n = H.shape
    gains = np.empty((n_copies, n_candidates))
    HP, S, columns = np.empty((m, n)), np.empty((m, m)), np.empty(n, dtype=np.int64)
    for c in range(n_copies):
        for k in range(n_candidates):
            gains[c, k] = landmark_gain(P[c], H[c, k], R[c, k], HP, S, columns)
    return gains


@inner_kernel
def landmark_gain(P, J, R, HP, S, columns) -> float:
    """``0.5 ln(det S / det R)``, ``S = J P J^T + R``, of one candidate [nats], NaN where a determinant is not > 0:
    ``P`` (n, n), ``J`` (m, n), ``R`` (m, m); ``HP`` (m, n), ``S`` (m, m) and ``columns`` (n,) int are scratch."""
    m = J.shape[0]
    n_columns = nonzero_columns(J, columns)
    for i in range(m):
        for t in range(n_columns):
            total = 0.0
            for s in range(n_columns):
                total += J[i, columns[s]] * P[columns[s], columns[t]]
            HP[i, columns[t]] = total
    for i in range(m):
        for j in range(m):
            total = 0.0
            for t in range(n_columns):
                total += HP[i, columns[t]] * J[j, columns[t]]
            S[i, j] = total + R[i, j]
    return mutual_information_kernel(log_det_of(S), log_det_of(R))


@kernel
def relative_pose_gains(P, observers, targets, H_observer, H_target, R, wanted):
    """``batched.relative_pose_information_gains`` of each ``wanted`` candidate pair (N, M) bool, 0 for the others,
    ``(own, joint)`` (N, M) [nats]: ``own = 0.5 ln(det P_oo / det (P_oo - A S^-1 A^T))``, ``A`` the observer's rows of
    ``P H^T``, and ``joint = 0.5 ln(det S / det R)``; NaN where a determinant is not > 0."""
    n_copies, n_pairs, m, _ = H_observer.shape
    own, joint = np.zeros((n_copies, n_pairs)), np.zeros((n_copies, n_pairs))
    A, B = np.empty((POSE_DIM, m)), np.empty((POSE_DIM, m))
    S, S_inverse, A_S_inverse = np.empty((m, m)), np.empty((m, m)), np.empty((POSE_DIM, m))
    pivoted, order = np.empty((m, m)), np.empty(m, dtype=np.int64)  # ``invert``'s scratch
    prior, posterior = np.empty((POSE_DIM, POSE_DIM)), np.empty((POSE_DIM, POSE_DIM))
    for c in range(n_copies):
        for k in range(n_pairs):
            if not wanted[c, k]:
                continue
            o, t = POSE_DIM * observers[c, k], POSE_DIM * targets[c, k]
            H_o, H_t = H_observer[c, k], H_target[c, k]
            for i in range(POSE_DIM):  # A = P_oo H_o^T + P_ot H_t^T, B = P_to H_o^T + P_tt H_t^T
                for j in range(m):
                    a_o = a_t = b_o = b_t = 0.0
                    for s in range(POSE_DIM):
                        a_o += P[c, o + i, o + s] * H_o[j, s]
                        a_t += P[c, o + i, t + s] * H_t[j, s]
                        b_o += P[c, t + i, o + s] * H_o[j, s]
                        b_t += P[c, t + i, t + s] * H_t[j, s]
                    A[i, j], B[i, j] = a_o + a_t, b_o + b_t
            for i in range(m):
                for j in range(m):
                    from_observer = from_target = 0.0
                    for s in range(POSE_DIM):
                        from_observer += H_o[i, s] * A[s, j]
                        from_target += H_t[i, s] * B[s, j]
                    S[i, j] = from_observer + from_target + R[c, k, i, j]
            invert(S, m, S_inverse, pivoted, order)
            for i in range(POSE_DIM):
                for j in range(m):
                    total = 0.0
                    for s in range(m):
                        total += A[i, s] * S_inverse[s, j]
                    A_S_inverse[i, j] = total
            for i in range(POSE_DIM):
                for j in range(POSE_DIM):
                    total = 0.0
                    for s in range(m):
                        total += A_S_inverse[i, s] * A[j, s]
                    posterior[i, j] = P[c, o + i, o + j] - total
            own[c, k] = mutual_information_kernel(pose_block_log_det(P[c], o, prior), log_det_of(posterior))
            joint[c, k] = mutual_information_kernel(log_det_of(S), log_det_of(R[c, k]))
    return own, joint


@kernel
def pose_block_log_dets(P, n_robots):
    """``ln det`` of each of the first ``n_robots`` poses' own 3 x 3 blocks of ``P`` (N, n, n): (N, R), NaN where the
    determinant is not > 0."""
    log_dets = np.empty((len(P), n_robots))
    block = np.empty((POSE_DIM, POSE_DIM))
    for c in range(len(P)):
        for robot in range(n_robots):
            log_dets[c, robot] = pose_block_log_det(P[c], POSE_DIM * robot, block)
    return log_dets


@inner_kernel
def pose_block_log_det(P, i, block):
    """``ln det`` of the 3 x 3 block of ``P`` (n, n) at row and column ``i``, copied into ``block`` (3, 3) first: a
    slice would be another array layout, so another compile of ``log_det_of``."""
    for row in range(POSE_DIM):
        for column in range(POSE_DIM):
            block[row, column] = P[i + row, i + column]
    return log_det_of(block)
