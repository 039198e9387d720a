"""Surface normals of point clouds and the translations a closest-point alignment cannot see.

A closest-point (point-to-plane) alignment of a surface observes a translation only along the
surface normals: a plane slides freely within itself, a thin cylinder along its axis. The normals'
second-moment matrix ``H = mean(n n^T)`` (trace 1) says how well each direction is seen:
eigenvalues near 1/3 each for a box corner with three faces in view, ``(1, 0, 0)`` for a plane,
``(1/2, 1/2, 0)`` for a cylinder. :func:`sliding_projector` is the (soft) projector onto the
directions whose eigenvalue falls below a threshold.
"""

from __future__ import annotations

import numpy as np

from ._checks import as_array, as_points, check_int, check_number

__all__ = ["estimate_normals", "sliding_projector"]


def estimate_normals(points, neighbours: int = 12) -> np.ndarray:
    """Unit normals of a point cloud by principal components of each point's nearest neighbours.

    Parameters
    ----------
    points : (N, 3) float64
        The points (any frame, metres), ``N >= 3``.
    neighbours : int
        Neighbours per point (the point included), ``>= 3``; at most ``N`` are used.

    Returns
    -------
    (N, 3) float64
        Unit normals in the points' frame; the sign is arbitrary (no viewpoint is assumed).
    """
    from scipy.spatial import cKDTree

    pts = as_points(points, "points", min_points=3)
    k = min(check_int(neighbours, "neighbours", minimum=3), pts.shape[0])
    _, idx = cKDTree(pts).query(pts, k=k)
    nb = pts[idx]  # (N, k, 3)
    centred = nb - nb.mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", centred, centred)
    _, vecs = np.linalg.eigh(cov)
    return vecs[:, :, 0]  # the eigenvector of the smallest eigenvalue


def sliding_projector(normals, threshold: float = 0.1, weights=None) -> np.ndarray:
    """The projector ``(3, 3)`` onto the translations a closest-point alignment of this surface cannot see.

    With ``H = sum(w n n^T) / sum(w)`` and its eigen-decomposition ``H = sum(l_i u_i u_i^T)``, the result is
    ``sum(f(l_i) u_i u_i^T)`` with ``f(l) = max(0, 1 - l / threshold)``: 1 along a direction no normal has a
    component on, 0 along those seen at least ``threshold`` (of the trace 1).

    Parameters
    ----------
    normals : (N, 3) float64
        Unit normals (the sign does not matter).
    threshold : float
        ``> 0`` (the eigenvalues sum to 1; above 1 every direction is partly projected).
    weights : (N,) float64, optional
        Non-negative weights of the normals (default all 1).

    Returns
    -------
    (3, 3) float64
        Symmetric, eigenvalues in ``[0, 1]``, in the normals' frame; the identity for no (or zero-weight) normals.
    """
    n = as_array(normals, "normals", shape=(None, 3))
    threshold = check_number(threshold, "threshold", minimum=0.0, lower_open=True)
    w = np.ones(n.shape[0]) if weights is None else as_array(weights, "weights", shape=(n.shape[0],))
    if np.any(w < 0):
        raise ValueError("weights: must be non-negative")
    if w.sum() <= 0:
        return np.eye(3)
    H = np.einsum("n,ni,nj->ij", w, n, n) / w.sum()
    vals, vecs = np.linalg.eigh(H)
    f = np.clip(1.0 - vals / threshold, 0.0, 1.0)
    return (vecs * f) @ vecs.T
