"""Detections to tracks: a gated assignment problem (:func:`associate`)."""

from __future__ import annotations

import numpy as np

__all__ = ["associate"]


def associate(cost) -> list[tuple[int, int]]:
    """The pairs ``(track, detection)`` of least total cost, each track and detection used at most once.

    Parameters
    ----------
    cost : (T, D) float64
        The cost of each pairing; ``inf`` where the gate forbids it (such pairs are never returned).

    Returns
    -------
    list of (int, int)
        Ordered by track. Solved by :func:`scipy.optimize.linear_sum_assignment` on the finite costs (a forbidden pair
        gets a cost above any sum of allowed ones, and is dropped from the solution).
    """
    from scipy.optimize import linear_sum_assignment

    c = np.asarray(cost, dtype=np.float64)
    if c.ndim != 2:
        raise ValueError(f"cost: expected a (tracks, detections) matrix, got shape {c.shape}")
    if np.any(np.isnan(c)) or np.any(c == -np.inf):
        raise ValueError("cost: NaN or -inf in the costs (use +inf for a forbidden pair)")
    if c.size == 0 or not np.isfinite(c).any():
        return []
    finite = np.isfinite(c)
    big = 1.0 + np.abs(c[finite]).sum() * 2.0
    rows, cols = linear_sum_assignment(np.where(finite, c, big))
    return [(int(r), int(k)) for r, k in zip(rows, cols) if finite[r, k]]
