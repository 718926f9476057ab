"""Which logged measurements to use under a budget of k per window: greedy (expected MI), random, nearest."""

from __future__ import annotations

import numpy as np

from infonav_gym.information import expected_information_gain

POLICIES = ("all", "greedy", "random", "nearest")


def select_greedy(P: np.ndarray, H: np.ndarray, R: np.ndarray, k: int) -> list[int]:
    """Greedy max expected mutual information: pick the best candidate, condition ``P`` on it, repeat.

    Args:
        P: prior covariance of the filter's state (n, n).
        H: candidate Jacobians (m, 2, n).
        R: measurement noise covariance (2, 2), shared by the candidates, or each one's (m, 2, 2).
        k: how many to pick.

    Returns:
        Indices of the chosen candidates in the order picked.
    """
    chosen: list[int] = []
    available = np.ones(len(H), dtype=bool)
    P = P.copy()
    R = np.broadcast_to(R, (len(H), *np.shape(R)[-2:]))
    for _ in range(min(k, len(H))):
        gains = np.where(available, expected_information_gain(P, H, R, check_input=False), -np.inf)
        best = int(np.argmax(gains))
        chosen.append(best)
        available[best] = False
        PHT = P @ H[best].T
        P = P - PHT @ np.linalg.solve(H[best] @ PHT + R[best], PHT.T)
        P = 0.5 * (P + P.T)
    return chosen


def select_nearest(predicted_ranges: np.ndarray, k: int) -> list[int]:
    """The ``k`` candidates whose targets are predicted closest (ties: earliest first)."""
    return np.argsort(predicted_ranges, kind="stable")[:k].tolist()


def select_random(n_candidates: int, k: int, rng: np.random.Generator) -> list[int]:
    """``k`` candidates uniformly without replacement."""
    return rng.choice(n_candidates, size=min(k, n_candidates), replace=False).tolist()
