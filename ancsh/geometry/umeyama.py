"""Least-squares similarity (or rigid) transform between corresponding point sets.

Umeyama (1991), weighted: find ``T = (s, R, t)`` minimising
``sum_i w_i |dst_i - (s R src_i + t)|^2`` with ``R`` a proper rotation (``det R = +1``;
the reflection that an unconstrained SVD fit may return is corrected).
"""

from __future__ import annotations

import numpy as np

from ._checks import as_array, as_points
from .transforms import Sim3

# Relative size below which a spread (length units) or a cross-covariance singular value
# (squared length units) counts as zero.
_SPREAD_TOL = 1e-10
_COV_RANK_TOL = 1e-12


class DegeneratePointsError(ValueError):
    """The points leave the rotation undetermined (coincident, collinear, rank < 2).

    A ``ValueError``; RANSAC estimators catch this one to skip a degenerate minimal sample.
    """


def umeyama(src, dst, weights=None, with_scale: bool = True) -> Sim3:
    """Best similarity transform ``T_dst_src`` with ``dst ~= T_dst_src @ src``.

    Parameters
    ----------
    src : (N, 3) float64
        Points in the source frame, ``N >= 3``.
    dst : (N, 3) float64
        Corresponding points in the destination frame.
    weights : (N,) float64, optional
        Non-negative weights (at least 3 positive); integer weights act like repeated points.
    with_scale : bool
        Estimate the uniform scale; otherwise the scale is 1 (a rigid fit).

    Returns
    -------
    Sim3
        The least-squares transform mapping ``src`` onto ``dst``.

    Raises
    ------
    ValueError
        On fewer than 3 points, mismatched shapes, NaN/inf, negative or all-zero weights.
    DegeneratePointsError
        (a ``ValueError``) On input that leaves the rotation undetermined: coincident or
        collinear source (or destination) points, or a cross-covariance of rank < 2.
    """
    src = as_points(src, "src", min_points=3)
    dst = as_points(dst, "dst")
    if dst.shape != src.shape:
        raise ValueError(f"dst: expected shape {src.shape} to match src, got {dst.shape}")
    n = src.shape[0]
    if weights is None:
        w = np.full(n, 1.0 / n)
    else:
        w = as_array(weights, "weights", (n,))
        if np.any(w < 0):
            raise ValueError("weights: must be non-negative")
        if np.count_nonzero(w) < 3:
            raise ValueError(f"weights: need at least 3 positive weights, got {np.count_nonzero(w)}")
        w = w / w.sum()

    _check_spread(src, src - w @ src, w, "src")
    _check_spread(dst, dst - w @ dst, w, "dst")
    R, t, scale = umeyama_core(src, dst, w, with_scale)
    return Sim3.unchecked(R, t, scale)


def umeyama_core(src: np.ndarray, dst: np.ndarray, w: np.ndarray, with_scale: bool = True):
    """The arithmetic of :func:`umeyama` without input validation, for hot loops (RANSAC refits).

    Parameters
    ----------
    src, dst : (N, 3) float64
        Finite corresponding points (not checked).
    w : (N,) float64
        Non-negative weights summing to 1 (not checked).
    with_scale : bool

    Returns
    -------
    R : (3, 3) float64, t : (3,) float64, s : float
        ``dst ~= s R src + t``.

    Raises
    ------
    DegeneratePointsError
        When the weighted cross-covariance has rank < 2 (coincident or collinear points on
        either side, or too few positive weights): the rotation is undetermined.
    """
    mu_src = w @ src
    mu_dst = w @ dst
    x_src = src - mu_src
    x_dst = dst - mu_dst
    sigma = (x_dst * w[:, None]).T @ x_src  # (3, 3) cross-covariance
    U, d, Vt = np.linalg.svd(sigma)
    if not d[1] > _COV_RANK_TOL * d[0]:
        raise DegeneratePointsError(
            "src: cross-covariance with dst has rank < 2 (singular values "
            f"{d[0]:.3g}, {d[1]:.3g}, {d[2]:.3g}); the rotation is undetermined"
        )
    S = np.ones(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2] = -1.0  # reflection correction
    R = (U * S) @ Vt
    if with_scale:
        var_src = float(w @ np.einsum("ij,ij->i", x_src, x_src))
        scale = float(d @ S) / var_src
    else:
        scale = 1.0
    return R, mu_dst - scale * (R @ mu_src), scale


def _check_spread(points: np.ndarray, centred: np.ndarray, w: np.ndarray, name: str) -> float:
    """Weighted variance of ``points``; raise if they are coincident or collinear."""
    sv = np.linalg.svd(centred * np.sqrt(w)[:, None], compute_uv=False)  # RMS spreads, descending
    magnitude = float(np.abs(points).max())
    if sv[0] <= _SPREAD_TOL * magnitude or sv[0] == 0.0:
        raise DegeneratePointsError(f"{name}: points are coincident; the rotation is undetermined")
    if sv[1] <= _SPREAD_TOL * sv[0]:
        raise DegeneratePointsError(f"{name}: points are collinear; the rotation is undetermined")
    return float(sv @ sv)
