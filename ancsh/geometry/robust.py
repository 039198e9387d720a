"""Robust kernels (M-estimators) for IRLS, defined once.

For a non-negative residual ``r`` and a kernel scale ``c > 0`` each kernel has a loss
``rho(r)`` (in units of ``r^2``; ``rho(r) = r^2`` for an inlier under Huber) and an IRLS weight
``w(r) = d rho / d(r^2)``, so that minimising ``sum_i w_i r_i^2`` with frozen weights has the
gradient of ``sum_i rho(r_i)``:

=========  =================================================  ==============================
kernel     ``rho(r)``                                         ``w(r)``
=========  =================================================  ==============================
none       ``r^2``                                            ``1``
huber      ``r^2`` if ``r <= c`` else ``2 c r - c^2``         ``min(1, c / r)``
cauchy     ``c^2 log(1 + (r / c)^2)``                         ``1 / (1 + (r / c)^2)``
tukey      ``c^2 / 3 (1 - (1 - (r / c)^2)^3)``, ``c^2 / 3``    ``(1 - (r / c)^2)^2``, ``0`` outside ``c``
=========  =================================================  ==============================
"""

from __future__ import annotations

import numpy as np

from ._checks import as_array, check_positive

__all__ = ["ROBUST_LOSSES", "robust_loss", "robust_weights"]

ROBUST_LOSSES = ("none", "huber", "cauchy", "tukey")
"""Kernel names, for configuration and the command line."""


def _check(residuals, loss: str, scale: float) -> tuple[np.ndarray, float]:
    r = np.abs(as_array(residuals, "residuals", (None,)))
    if loss not in ROBUST_LOSSES:
        raise ValueError(f"loss: expected one of {ROBUST_LOSSES}, got {loss!r}")
    return r, check_positive(scale, "scale")


def robust_weights(residuals, loss: str, scale: float) -> np.ndarray:
    """IRLS weights ``w(r)`` of a robust kernel (see the module table).

    Parameters
    ----------
    residuals : (N,) float64
        Residuals ``r`` (their sign is ignored), in the unit of ``scale``.
    loss : str
        One of :data:`ROBUST_LOSSES`.
    scale : float
        Kernel scale ``c``, positive.

    Returns
    -------
    (N,) float64
    """
    r, c = _check(residuals, loss, scale)
    if loss == "none":
        return np.ones_like(r)
    if loss == "huber":
        return np.minimum(1.0, c / np.maximum(r, 1e-300))
    u = r / c
    if loss == "cauchy":
        return 1.0 / (1.0 + u * u)
    return np.where(u < 1.0, (1.0 - u * u) ** 2, 0.0)


def robust_loss(residuals, loss: str, scale: float) -> np.ndarray:
    """Losses ``rho(r)`` of a robust kernel (see the module table); arguments as :func:`robust_weights`."""
    r, c = _check(residuals, loss, scale)
    if loss == "none":
        return r * r
    if loss == "huber":
        return np.where(r <= c, r * r, 2.0 * c * r - c * c)
    u2 = (r / c) ** 2
    if loss == "cauchy":
        return c * c * np.log1p(u2)
    return np.where(u2 < 1.0, c * c / 3.0 * (1.0 - (1.0 - u2) ** 3), c * c / 3.0)
