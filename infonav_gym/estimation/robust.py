"""Huber-weighted Kalman update: heavy-tailed measurement noise without discarding data.

A Kalman update is the least-squares fit of the prior and the measurement; one outlier pulls it as hard as its
squared residual. The Huber M-estimator (Huber 1964) keeps the quadratic loss for a normalized innovation
``d = sqrt(NIS)`` up to a threshold ``c`` and grows linearly beyond it: by iteratively reweighted least squares, a
Kalman update with the noise inflated by ``1 / w``, ``w = min(1, c / d)`` (Karlgaard and Schaub 2007, "Huber-based
divided difference filtering", J. Guidance Control and Dynamics 30(3); Zoubir et al. 2012, IEEE SPM). Inside the
threshold ``w = 1``: the standard EKF update, exactly.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize


def huber_noise(residual, H, P, R, threshold_nis: float) -> tuple[np.ndarray, float, float]:
    """The inflated noise covariance of a Huber-weighted update and its weight ``w``, the fixed point of
    ``w = min(1, c / d(w))`` with ``d(w)^2 = r^T (H P H^T + R / w)^-1 r``: ``w - c / d(w)`` increases with ``w``, so
    the root is unique, in ``[c / d(1), 1]`` (Brent's method).

    Args:
        residual, H, P, R: innovation ``z - h(x)`` (m,), angles wrapped; measurement Jacobian (m, n); prior covariance
            (n, n); nominal measurement noise covariance (m, m).
        threshold_nis: ``c^2``: innovations with NIS up to it get the standard update.

    Returns:
        ``(R / w, w, nis)`` with ``nis`` the normalized innovation squared under the nominal ``R``.
    """
    if not threshold_nis > 0:
        raise ValueError(f"threshold_nis must be positive, got {threshold_nis}")
    HPH = H @ P @ H.T
    nis = float(residual @ np.linalg.solve(HPH + R, residual))
    if nis <= threshold_nis:
        return R, 1.0, nis

    def excess(weight: float) -> float:
        return weight - math.sqrt(threshold_nis / float(residual @ np.linalg.solve(HPH + R / weight, residual)))

    weight = float(optimize.brentq(excess, math.sqrt(threshold_nis / nis), 1.0, xtol=1e-12))
    return R / weight, weight, nis
