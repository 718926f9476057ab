"""Which logged measurements to use under a budget of k per window: greedy (expected MI), random, nearest."""

from __future__ import annotations

import numpy as np

from infonav_gym.decisions import argmax_tied, top_k_tied
from infonav_gym.estimation import batched
from infonav_gym.information import expected_information_gain, mutual_information_from_log_dets

POLICIES = ("all", "greedy", "random", "nearest")


def select_greedy(P: np.ndarray, H: np.ndarray, R: np.ndarray, k: int, of: np.ndarray | None = None) -> list[int]:
    """Greedy max expected mutual information: pick the best candidate, condition ``P`` on it, repeat.

    Args:
        P: prior covariance of the filter's state (n, n).
        H: candidate Jacobians (m, 2, n).
        R: measurement noise covariance (2, 2), shared by the candidates, or each one's (m, 2, 2).
        k: how many to pick.
        of: the state entries whose information counts (e.g. the pose beside nuisance biases), the gain
            ``0.5 ln(det P_oo / det P_oo_post)``; None: the whole state (``expected_information_gain``).

    Returns:
        The chosen candidates' indices in the order picked.
    """
    chosen: list[int] = []
    available = np.ones(len(H), dtype=bool)
    P = P.copy()
    R = np.broadcast_to(R, (len(H), *np.shape(R)[-2:]))
    for _ in range(min(k, len(H))):
        gains = expected_information_gain(P, H, R, check_input=False) if of is None else _marginal_gains(P, H, R, of)
        best = argmax_tied(np.where(available, gains, -np.inf))
        chosen.append(best)
        available[best] = False
        P = batched.posterior_covariance(P[None], H[best][None], R[best][None], check_input=False)[0]
    return chosen


def _marginal_gains(P, H, R, of) -> np.ndarray:
    """Expected MI of each candidate update on the state entries ``of`` alone [nats] (m,)."""
    prior = P[np.ix_(of, of)]
    posterior = batched.posterior_covariance(np.broadcast_to(P, (len(H), *P.shape)), H, R, check_input=False)
    posterior = posterior[:, of][:, :, of]
    return mutual_information_from_log_dets(np.linalg.slogdet(prior)[1], np.linalg.slogdet(posterior)[1])


def select_nearest(predicted_ranges: np.ndarray, k: int) -> list[int]:
    """The ``k`` candidates whose targets are predicted closest (near-ties: earliest first)."""
    return top_k_tied(-np.asarray(predicted_ranges, dtype=float), k).tolist()


def select_random(n_candidates: int, k: int, rng: np.random.Generator) -> list[int]:
    """``k`` candidates uniformly without replacement."""
    return rng.choice(n_candidates, size=min(k, n_candidates), replace=False).tolist()
