"""Robust kernels for ICP by iteratively reweighted least squares (IRLS).

Each step weighs a residual ``r`` by ``w(r) = rho'(r) / r`` at scale ``c`` (Zhang 1997; Black & Rangarajan 1996):
``"huber"`` 1 within ``c``, else ``c / |r|``; ``"cauchy"`` ``1 / (1 + (r / c)^2)``; ``"tukey"`` ``(1 - (r / c)^2)^2``
within ``c``, else 0.
"""

from __future__ import annotations

import numpy as np

ROBUST_KERNELS = ("huber", "cauchy", "tukey")


def check_robust_kernel(robust_kernel, kernel_scale) -> None:
    """``ValueError`` for a kernel name not in ``ROBUST_KERNELS`` (or None) or a non-positive ``kernel_scale``."""
    if robust_kernel is not None and robust_kernel not in ROBUST_KERNELS:
        expected = ", ".join(ROBUST_KERNELS)
        raise ValueError(f"unknown robust_kernel {robust_kernel!r}; expected None or one of {expected}")
    if isinstance(kernel_scale, bool) or not (isinstance(kernel_scale, (int, float, np.number)) and kernel_scale > 0):
        raise ValueError(f"kernel_scale must be a positive number [length unit], got {kernel_scale!r}")


def robust_weights(residual: np.ndarray, robust_kernel: str, kernel_scale: float) -> np.ndarray:
    """IRLS weights in [0, 1] of ``residual`` (any shape, signed) under ``robust_kernel`` with ``kernel_scale``."""
    ratio_squared = np.square(residual / kernel_scale)
    if robust_kernel == "huber":
        return 1.0 / np.maximum(1.0, np.sqrt(ratio_squared))
    if robust_kernel == "cauchy":
        return 1.0 / (1.0 + ratio_squared)
    return np.square(np.maximum(0.0, 1.0 - ratio_squared))
