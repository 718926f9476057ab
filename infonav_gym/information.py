"""Entropy, information and mutual information, in nats; bad input raises ``ValueError`` naming the problem.

Section III-A: a Gaussian's entropy ``h = 0.5 ln((2 pi e)^n det P)``, information metric ``im = -h``, an
observation's contribution ``ic = im_post - im_prior`` (Eq. 3, the mutual information). Section IV (Eqs. 4-5):
an image's entropy is its gray-level histogram's.
"""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.compiled import contiguous, inner_kernel, kernel

_LOG_2PI_E = math.log(2.0 * math.pi * math.e)
_SYMMETRY_RTOL = 1e-8


def _finite_array(name: str, value) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.size == 0:
        raise ValueError(f"{name} is empty (shape {array.shape})")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} contains NaN or infinite entries")
    return array


def _square_stack(name: str, value) -> np.ndarray:
    matrix = _finite_array(name, value)
    if matrix.ndim < 2 or matrix.shape[-1] != matrix.shape[-2]:
        raise ValueError(f"{name} must be a square matrix (or a stack of them), got shape {matrix.shape}")
    return matrix


def log_det_spd(matrix, name: str = "matrix", check_input: bool = True) -> float | np.ndarray:
    """``ln det`` of a symmetric positive-definite matrix (n, n) or stack (..., n, n), ``name`` for errors.

    ``check_input`` checks shape, finiteness and symmetry and factors by Cholesky (``ValueError`` for each);
    ``False``, for hot loops, takes the compiled ``log_det_of`` and rejects only a non-positive determinant.
    """
    if not check_input:
        matrix = np.asarray(matrix, dtype=float)
        log_det = stacked_log_dets(contiguous(matrix.reshape(-1, *matrix.shape[-2:]))).reshape(matrix.shape[:-2])
        if np.isnan(log_det).any():
            raise ValueError(f"{name} is not positive definite (determinant <= 0)")
    else:
        matrix = _square_stack(name, matrix)
        asymmetry = np.max(np.abs(matrix - np.swapaxes(matrix, -1, -2)))
        scale = np.max(np.abs(matrix))
        if asymmetry > _SYMMETRY_RTOL * scale:
            raise ValueError(f"{name} is not symmetric (max |M - M^T| = {asymmetry:.3g}, max |M| = {scale:.3g})")
        try:
            cholesky = np.linalg.cholesky(matrix)
        except np.linalg.LinAlgError:
            smallest = np.min(np.linalg.eigvalsh(matrix))
            raise ValueError(f"{name} is not positive definite (smallest eigenvalue {smallest:.3g})") from None
        log_det = 2.0 * np.sum(np.log(np.diagonal(cholesky, axis1=-2, axis2=-1)), axis=-1)
    return float(log_det) if np.ndim(log_det) == 0 else log_det


@inner_kernel
def log_det_of(M) -> float:
    """``ln det`` of a square matrix (n, n), NaN unless its determinant is > 0: cofactors up to 3 x 3, else
    ``slogdet``'s LU with partial pivoting."""
    n = M.shape[0]
    if n <= 3:
        if n == 0:
            determinant = 1.0
        elif n == 1:
            determinant = M[0, 0]
        elif n == 2:
            determinant = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
        else:
            determinant = (
                M[0, 0] * (M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1])
                - M[0, 1] * (M[1, 0] * M[2, 2] - M[1, 2] * M[2, 0])
                + M[0, 2] * (M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0])
            )
        return math.log(determinant) if determinant > 0.0 else math.nan
    A = M.copy()
    sign, log_det = 1.0, 0.0
    for j in range(n):
        pivot = j
        for i in range(j + 1, n):
            if abs(A[i, j]) > abs(A[pivot, j]):
                pivot = i
        if not abs(A[pivot, j]) > 0.0:  # zero or NaN
            return math.nan
        if pivot != j:
            for k in range(n):
                A[j, k], A[pivot, k] = A[pivot, k], A[j, k]
            sign = -sign
        if A[j, j] < 0.0:
            sign = -sign
        log_det += math.log(abs(A[j, j]))
        for i in range(j + 1, n):
            factor = A[i, j] / A[j, j]
            for k in range(j + 1, n):
                A[i, k] -= factor * A[j, k]
    return log_det if sign > 0.0 else math.nan


@kernel
def stacked_log_dets(M):
    """``log_det_of`` each matrix of a stack (N, n, n): (N,), NaN where the determinant is not > 0."""
    log_dets = np.empty(len(M))
    for index in range(len(M)):
        log_dets[index] = log_det_of(M[index])
    return log_dets


def largest_position_std(covariances: np.ndarray) -> np.ndarray:
    """Largest standard deviation of the position part of each (B, >=2, >=2) pose covariance [m]: (B,)."""
    return position_std(covariances[:, 0, 0], covariances[:, 0, 1], covariances[:, 1, 1])


def position_std(a, b, d):
    """The square root of the largest eigenvalue of ``[[a, b], [b, d]]`` in closed form (floats or arrays) [m]."""
    return np.sqrt(0.5 * (a + d) + np.sqrt(0.25 * (a - d) * (a - d) + b * b))


position_std_kernel = inner_kernel(position_std)  # the same formula compiled, for one covariance inside other kernels


def gaussian_entropy(P, check_input: bool = True) -> float:
    """Differential entropy of N(., P): ``0.5 ln((2 pi e)^n det P)`` [nats]."""
    log_det = log_det_spd(P, "covariance P", check_input)
    if np.ndim(log_det) != 0:
        raise ValueError(f"covariance P must be one matrix, got shape {np.shape(P)}")
    return gaussian_entropy_from_log_det(log_det, np.shape(P)[-1])


def gaussian_entropy_from_log_det(log_det: float, dimension: int) -> float:
    """``gaussian_entropy`` of an n-dimensional Gaussian whose ``ln det P`` is already known [nats]."""
    return 0.5 * (dimension * _LOG_2PI_E + log_det)


gaussian_entropy_kernel = inner_kernel(gaussian_entropy_from_log_det)  # the same formula, for floats inside kernels


def information_metric(P) -> float:
    """The paper's information metric ``im = -h``: higher for a more compact Gaussian [nats]."""
    return -gaussian_entropy(P)


def mutual_information_from_log_dets(prior_log_det, posterior_log_det):
    """Eq. 3 on known log-determinants, ``0.5 (ln det P_prior - ln det P_post)`` [nats]: the one MI formula (the
    expected gain ``0.5 (ln det S - ln det R)`` is it too, ``det S / det R = det P_prior / det P_post``)."""
    return 0.5 * (prior_log_det - posterior_log_det)


mutual_information_kernel = inner_kernel(mutual_information_from_log_dets)  # the same formula, inside kernels


def mutual_information(P_prior, P_post, check_input: bool = True) -> float:
    """Information contribution ``ic = 0.5 ln(det P_prior / det P_post)`` of an update (Eq. 3) [nats]."""
    if check_input:
        P_prior, P_post = _square_stack("prior covariance", P_prior), _square_stack("posterior covariance", P_post)
        if P_prior.shape != P_post.shape or P_prior.ndim != 2:
            raise ValueError(
                "prior and posterior covariances must be matrices of the same shape, "
                f"got {P_prior.shape} and {P_post.shape}"
            )
    return mutual_information_from_log_dets(
        log_det_spd(P_prior, "prior covariance", check_input), log_det_spd(P_post, "posterior covariance", check_input)
    )


def expected_information_gain(P, H, R, check_input: bool = True) -> float | np.ndarray:
    """Mutual information an EKF update would bring, before measuring: ``0.5 (ln det(H P H^T + R) - ln det R)``
    [nats], also the realized one (a linearized posterior does not depend on the measured value).

    ``P`` (n, n); ``H`` (..., m, n) and ``R`` (..., m, m) batched over candidates (a float for one);
    ``check_input=False`` for hot loops (``log_det_spd``).
    """
    if check_input:
        P = _square_stack("prior covariance P", P)
        if P.ndim != 2:
            raise ValueError(f"prior covariance P must be one (n, n) matrix, got shape {P.shape}")
        log_det_spd(P, "prior covariance P")
        H = _finite_array("Jacobian H", H)
        R = _square_stack("noise covariance R", R)
        if H.ndim < 2 or H.shape[-1] != P.shape[0]:
            raise ValueError(f"Jacobian H must have shape (..., m, {P.shape[0]}) to match P, got {H.shape}")
        if R.shape[-1] != H.shape[-2]:
            raise ValueError(f"noise covariance R must be ({H.shape[-2]}, {H.shape[-2]}) to match H, got {R.shape}")
    gain = mutual_information_from_log_dets(
        log_det_spd(H @ P @ np.swapaxes(H, -1, -2) + R, "innovation covariance H P H^T + R", check_input),
        log_det_spd(R, "noise covariance R", check_input),
    )
    return float(gain) if np.ndim(gain) == 0 else gain


def information_gain_of_information(prior_root, information):
    """MI [nats] of an observation carrying Fisher ``information`` ``A = sum J^T R^-1 J`` (..., n, n) about
    x ~ N(., L L^T), ``prior_root`` ``L`` (..., n, n): ``0.5 ln det(I + L^T A L)`` (a float for one pair)."""
    whitened = np.swapaxes(prior_root, -1, -2) @ information @ prior_root
    gain = 0.5 * np.linalg.slogdet(np.eye(whitened.shape[-1]) + whitened)[1]
    return float(gain) if gain.ndim == 0 else gain


def histogram_entropy(image, bins: int = 256, value_range=None, base: float = math.e) -> float:
    """Entropy ``-sum p_i log p_i`` of an image's gray-level histogram (Eqs. 4-5) in ``base`` (e: nats, 2: bits).

    ``value_range`` defaults to ``(0, 256)`` for uint8 images (one bin per level), else ``(min, max)``.
    """
    pixels = np.asarray(image)
    if pixels.size == 0:
        raise ValueError(f"image is empty (shape {pixels.shape})")
    if not (np.issubdtype(pixels.dtype, np.integer) or np.issubdtype(pixels.dtype, np.floating)):
        raise ValueError(f"image must hold numbers, got dtype {pixels.dtype}")
    if not np.all(np.isfinite(pixels)):
        raise ValueError("image contains NaN or infinite pixels")
    if int(bins) != bins or bins < 1:
        raise ValueError(f"bins must be a positive integer, got {bins!r}")
    if not base > 0 or base == 1:
        raise ValueError(f"base must be positive and not 1, got {base!r}")
    if pixels.dtype == np.uint8 and bins == 256 and value_range is None:
        counts = np.bincount(pixels.ravel(), minlength=256)
    else:
        if value_range is None:
            value_range = (0, 256) if pixels.dtype == np.uint8 else (float(pixels.min()), float(pixels.max()))
        low, high = value_range
        if not high >= low:
            raise ValueError(f"value_range must be (low, high) with high >= low, got {value_range!r}")
        if high == low:
            return 0.0
        counts, _ = np.histogram(pixels, bins=int(bins), range=(low, high))
        if counts.sum() == 0:
            raise ValueError(f"no pixel lies inside value_range {value_range!r}")
    probabilities = counts[counts > 0] / counts.sum()
    return float(-np.sum(probabilities * np.log(probabilities)) / math.log(base))
