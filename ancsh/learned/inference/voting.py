"""Robust voting of joint parameters from per-point 7-D joint votes (paper Sec. 4.2).

Each associated point ``g_i`` votes for its joint's axis ``u_i`` and, for a revolute joint,
for a point on the axis ``p_i = g_i + d_i r_i`` (unit direction ``r_i`` to the axis and
distance ``d_i``). Instead of the paper's plain average:

- the axis is the principal eigenvector of the weighted scatter ``sum w_i u_i u_i^T`` of the
  normalised votes (insensitive to sign flips), re-estimated after trimming votes whose angle
  to the estimate exceeds a median + 3 MAD bound; its sign follows the weighted majority;
- the pivot is the weighted least-squares point closest (perpendicular to the axis) to the
  voted axis points ``p_i``, started from their coordinate-wise median and re-estimated after
  trimming by the same residual rule; along the axis it sits at the median of the votes.

The functions work in any frame: NAOCS for ANCSH, the camera frame for direct voting.
numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...geometry._checks import as_array, as_points

__all__ = ["JointVote", "vote_axis", "vote_pivot", "vote_joints"]

_MAD = 1.4826  # MAD -> standard deviation for a Gaussian


@dataclass(frozen=True)
class JointVote:
    """Voted parameters of one joint.

    Attributes
    ----------
    axis : (3,) float64
        Unit axis.
    pivot : (3,) float64
        A point on the axis (revolute) or the robust centre of the voters (prismatic).
    num_votes : int
        Voters used.
    axis_inliers, pivot_inliers : int
        Votes kept after trimming.
    axis_spread : float
        RMS angle (radians) of the kept axis votes around the estimate.
    pivot_spread : float
        RMS perpendicular distance of the kept pivot votes from the axis (frame units).
    """

    axis: np.ndarray
    pivot: np.ndarray
    num_votes: int
    axis_inliers: int
    pivot_inliers: int
    axis_spread: float
    pivot_spread: float


def _weights(weights, n: int) -> np.ndarray:
    if weights is None:
        return np.ones(n)
    w = as_array(weights, "weights", (n,))
    if np.any(w < 0):
        raise ValueError("weights: must be non-negative")
    return w


def _trim(residual: np.ndarray, keep: np.ndarray, min_keep: float, floor: float) -> np.ndarray:
    """Inliers: residual <= max(floor, median + 3 * 1.4826 * MAD) over current inliers, keeping >= min_keep share."""
    r = residual[keep]
    med = np.median(r)
    bound = max(floor, med + 3.0 * _MAD * np.median(np.abs(r - med)))
    new = residual <= bound
    if new.sum() < max(1, int(np.ceil(min_keep * residual.size))):
        k = max(1, int(np.ceil(min_keep * residual.size)))
        new = np.zeros_like(new)
        new[np.argsort(residual, kind="stable")[:k]] = True
    return new


def vote_axis(votes, weights=None, *, iterations: int = 3, min_keep: float = 0.5, floor_rad: float = np.deg2rad(1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Robust unit axis from ``(n, 3)`` direction votes.

    Parameters
    ----------
    votes : (n, 3) float64
        Axis votes (any length; zero-length votes are ignored).
    weights : (n,) float64, optional
        Non-negative vote weights.
    iterations : int
        Trim / re-estimate rounds.
    min_keep : float
        Least share of votes kept by trimming.
    floor_rad : float
        Angles below this are never trimmed.

    Returns
    -------
    axis : (3,) float64
        Unit vector; its sign agrees with the weighted majority of the votes.
    inliers : (n,) bool
    """
    v = as_points(votes, "votes", min_points=1)
    w = _weights(weights, v.shape[0])
    norm = np.linalg.norm(v, axis=1)
    valid = (norm > 1e-9) & (w > 0)
    if not np.any(valid):
        raise ValueError("votes: no non-zero vote with positive weight")
    u = np.zeros_like(v)
    u[valid] = v[valid] / norm[valid, None]
    keep = valid.copy()
    axis = None
    for _ in range(max(1, iterations) + 1):
        S = (u[keep] * w[keep, None]).T @ u[keep]
        axis = np.linalg.eigh(S)[1][:, -1]
        angle = np.arccos(np.clip(np.abs(u @ axis), 0.0, 1.0))
        angle[~valid] = np.inf
        new = _trim(angle, keep, min_keep * valid.mean(), floor_rad) & valid
        if np.array_equal(new, keep):
            break
        keep = new
    if np.sum(w[keep] * (u[keep] @ axis)) < 0:
        axis = -axis
    return axis, keep


def vote_pivot(axis_points, axis, weights=None, *, iterations: int = 3, min_keep: float = 0.5, floor: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """Robust point on a line of direction ``axis`` from ``(n, 3)`` voted axis points.

    Minimises the weighted squared perpendicular distances ``|P (q - p_i)|^2`` with
    ``P = I - a a^T`` over trimmed inliers; the along-axis coordinate of ``q`` is the
    median of the kept votes.

    Parameters
    ----------
    axis_points : (n, 3) float64
        Voted points on the axis.
    axis : (3,) float64
        Unit axis direction.
    weights : (n,) float64, optional
    iterations, min_keep :
        As in :func:`vote_axis`.
    floor : float
        Residuals below this (frame units) are never trimmed.

    Returns
    -------
    pivot : (3,) float64
    inliers : (n,) bool
    """
    p = as_points(axis_points, "axis_points", min_points=1)
    a = as_array(axis, "axis", (3,))
    a = a / np.linalg.norm(a)
    w = _weights(weights, p.shape[0])
    if not np.any(w > 0):
        raise ValueError("weights: all zero")
    P = np.eye(3) - np.outer(a, a)
    perp = p @ P  # P is symmetric
    valid = w > 0
    keep = valid.copy()
    centre = np.median(perp[keep], axis=0)
    for _ in range(max(1, iterations)):
        resid = np.linalg.norm(perp - centre, axis=1)
        resid[~valid] = np.inf
        keep = _trim(resid, keep, min_keep * valid.mean(), floor) & valid
        centre = (perp[keep] * w[keep, None]).sum(0) / w[keep].sum()
    along = float(np.median(p[keep] @ a))
    return centre @ P + along * a, keep


def vote_joints(points, association, joint, revolute, weights=None, *, min_votes: int = 3) -> tuple[JointVote | None, ...]:
    """Vote every joint from per-point predictions.

    Parameters
    ----------
    points : (N, 3) float64
        Voter coordinates in the voting frame (NAOCS for ANCSH).
    association : (N,) int
        0 = none, ``k + 1`` = joint ``k``.
    joint : (N, 7) float64
        Per-point axis (3), unit direction to the axis (3), distance (1).
    revolute : (K,) bool
    weights : (N,) float64, optional
    min_votes : int
        Joints with fewer voters get ``None``.

    Returns
    -------
    tuple of JointVote or None, length K
    """
    g = as_points(points, "points")
    n = g.shape[0]
    assoc = np.asarray(association)
    if assoc.shape != (n,):
        raise ValueError(f"association: expected shape ({n},), got {assoc.shape}")
    v = as_array(joint, "joint", (n, 7))
    w = _weights(weights, n)
    out: list[JointVote | None] = []
    for k, rev in enumerate(np.asarray(revolute, dtype=bool)):
        sel = np.flatnonzero((assoc == k + 1) & (w > 0))
        if sel.size < min_votes:
            out.append(None)
            continue
        axis, ax_in = vote_axis(v[sel, :3], w[sel])
        u = v[sel, :3] / np.maximum(np.linalg.norm(v[sel, :3], axis=1, keepdims=True), 1e-12)
        ax_spread = float(np.sqrt(np.mean(np.arccos(np.clip(np.abs(u[ax_in] @ axis), 0, 1)) ** 2)))
        if rev:
            r = v[sel, 3:6]
            r = r / np.maximum(np.linalg.norm(r, axis=1, keepdims=True), 1e-12)
            votes = g[sel] + np.abs(v[sel, 6:7]) * r
            pivot, pv_in = vote_pivot(votes, axis, w[sel])
            d = votes[pv_in] - pivot
            d = d - np.outer(d @ axis, axis)
            pv_spread = float(np.sqrt(np.mean(np.sum(d * d, axis=1))))
        else:
            pivot, pv_in = np.median(g[sel], axis=0), np.ones(sel.size, dtype=bool)
            pv_spread = 0.0
        out.append(JointVote(axis, pivot, int(sel.size), int(ax_in.sum()), int(pv_in.sum()), ax_spread, pv_spread))
    return tuple(out)
