"""Where a tracked object's pixels are: the surface it stands on (:func:`support_height`), for
:class:`~ancsh.tracking.multi.MultiObjectTracker`'s regions."""

from __future__ import annotations

import numpy as np

__all__ = ["SUPPORT_BAND", "SUPPORT_HYPOTHESES", "SUPPORT_INLIER", "SUPPORT_MAX_TILT_DEG", "SUPPORT_POINTS",
           "support_height"]

#: Support planes: candidate planes drawn, the largest tilt from the object's up axis (degrees), the band about the
#: predicted bottom searched (object diagonals), the inlier distance (object diagonals) and the most points used.
SUPPORT_HYPOTHESES = 64
SUPPORT_MAX_TILT_DEG = 25.0
SUPPORT_BAND = 0.15
SUPPORT_INLIER = 0.01
SUPPORT_POINTS = 1500


def support_height(points, up, bottom: float, diagonal: float, rng, around=None) -> np.ndarray:
    """Height (metres) of each of ``points`` (N, 3, camera frame) above the surface a tracked object stands on.

    The surface is the lowest of the planes with at least half the most points within :data:`SUPPORT_INLIER` object
    diagonals among
    :data:`SUPPORT_HYPOTHESES` planes through three points of the band of :data:`SUPPORT_BAND` object diagonals about the
    predicted ``bottom`` (the lowest box corner along ``up``, metres), tilted at most :data:`SUPPORT_MAX_TILT_DEG` from
    ``up``, its inliers counted among the band's points ``around`` the object (``(N,)`` bool: outside the fitted part
    boxes, so that a flat part -- a laptop's base, a closed lid -- is not taken for the table); where the band holds no
    such plane, the heights are measured from ``bottom`` along ``up``. Fitting the plane
    to the depth, not to the fit, keeps the floor out of a track whose fit is a few degrees off (a tilted bottom would
    let the floor in on one side and cut the object on the other)."""
    up = np.asarray(up, dtype=np.float64)
    h = points @ up - bottom
    near = np.abs(h) < SUPPORT_BAND * diagonal
    band = np.flatnonzero(near if around is None else near & np.asarray(around, dtype=bool))
    if len(band) < 30:
        return h
    if len(band) > SUPPORT_POINTS:
        band = rng.choice(band, SUPPORT_POINTS, replace=False)
    Q = points[band]
    tri = Q[rng.integers(0, len(Q), (SUPPORT_HYPOTHESES, 3))]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1)
    ok = norm > 1e-12
    n = n[ok] / norm[ok, None]
    n *= np.sign(n @ up)[:, None]
    flat = n @ up > np.cos(np.deg2rad(SUPPORT_MAX_TILT_DEG))
    if not flat.any():
        return h
    n, p0 = n[flat], tri[ok][flat, 0]
    e = -np.einsum("ij,ij->i", n, p0)
    counts = np.count_nonzero(np.abs(Q @ n.T + e) < SUPPORT_INLIER * diagonal, axis=0)
    if counts.max() < 0.1 * len(Q):
        return h
    # the lowest of the well-supported planes: a flat part of the object (a laptop's base, a closed lid) lies above
    # the table it stands on
    c = Q.mean(axis=0)
    level = -(e + n @ c)  # each plane's height at the band's centre along its normal (~ up)
    strong = np.flatnonzero(counts >= 0.5 * counts.max())
    best = int(strong[np.argmin(level[strong])])
    inl = Q[np.abs(Q @ n[best] + e[best]) < SUPPORT_INLIER * diagonal]
    c = inl.mean(axis=0)
    normal = np.linalg.svd(inl - c, full_matrices=False)[2][-1]  # the least-squares plane of its inliers
    normal *= np.sign(normal @ up)
    return (points - c) @ normal
