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
    R, t, scale, valid = umeyama_batch(src[None], dst[None], w[None], with_scale=with_scale, rank_tol=_COV_RANK_TOL)
    if not valid[0]:
        raise DegeneratePointsError("src: cross-covariance with dst has rank < 2; the rotation is undetermined")
    return Sim3.unchecked(R[0], t[0], scale[0])


def umeyama_batch(src, dst, weights=None, *, with_scale: bool = True, rank_tol: float = 1e-8):
    """Many weighted Umeyama fits at once, without input validation (for hot loops).

    The arithmetic of :func:`umeyama` (which calls it), vectorised over ``H`` problems: RANSAC
    minimal samples, or every part's inliers padded to a common length with zero weights.

    Parameters
    ----------
    src, dst : (H, k, 3) float64
        Finite corresponding points (not checked).
    weights : (H, k) float64, optional
        Non-negative weights (not checked), normalised per problem; default uniform.
    with_scale : bool
        Estimate the scale; otherwise it is 1.
    rank_tol : float
        A problem is degenerate when the cross-covariance's second singular value is at most
        ``rank_tol`` times the first (coincident or collinear points on either side: its rank is
        at most that of either centred point set).

    Returns
    -------
    R : (H, 3, 3), t : (H, 3), s : (H,), valid : (H,) bool
        ``dst ~= s R src + t``; ``valid`` is False for degenerate problems, fewer than 3 positive
        weights, and non-finite or non-positive scales (their ``R, t, s`` are meaningless).
    """
    H, k = src.shape[:2]
    if weights is None:
        w = np.full((H, k), 1.0 / k)
        enough = np.full(H, k >= 3)
    else:
        total = weights.sum(axis=1)
        enough = np.count_nonzero(weights, axis=1) >= 3
        w = weights / np.where(total > 0, total, 1.0)[:, None]
    wr = w[:, None, :]  # (H, 1, k): the weighted sums as batched products (cheaper than einsum at these sizes)
    mu_s = (wr @ src)[:, 0]
    mu_d = (wr @ dst)[:, 0]
    xs = src - mu_s[:, None, :]
    xd = dst - mu_d[:, None, :]
    sigma = (xd * w[:, :, None]).transpose(0, 2, 1) @ xs  # (H, 3, 3) cross-covariances
    U, d, Vt = np.linalg.svd(sigma)
    S = np.ones((H, 3))
    S[np.linalg.det(U) * np.linalg.det(Vt) < 0, 2] = -1.0  # reflection correction
    R = (U * S[:, None, :]) @ Vt
    if with_scale:
        var_s = (wr @ np.einsum("hki,hki->hk", xs, xs)[:, :, None])[:, 0, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.sum(d * S, axis=1) / var_s
    else:
        s = np.ones(H)
    t = mu_d - s[:, None] * (R @ mu_s[:, :, None])[:, :, 0]
    valid = enough & (d[:, 1] > rank_tol * d[:, 0]) & np.isfinite(s) & (s > 0)
    return R, t, s, valid


def _check_spread(points: np.ndarray, centred: np.ndarray, w: np.ndarray, name: str) -> float:
    """Weighted variance of ``points``; raise if they are coincident or collinear."""
    sv = np.linalg.svd(centred * np.sqrt(w)[:, None], compute_uv=False)  # RMS spreads, descending
    magnitude = float(np.abs(points).max())
    if sv[0] <= _SPREAD_TOL * magnitude or sv[0] == 0.0:
        raise DegeneratePointsError(f"{name}: points are coincident; the rotation is undetermined")
    if sv[1] <= _SPREAD_TOL * sv[0]:
        raise DegeneratePointsError(f"{name}: points are collinear; the rotation is undetermined")
    return float(sv @ sv)
