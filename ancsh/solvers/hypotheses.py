"""RANSAC initialisation of an articulated fit, vectorised over hypotheses.

A hypothesis draws a minimal sample of 3 correspondences from *every* part and fits each
part by Umeyama (with scale); it is scored on all parts jointly by the mean per-part inlier
ratio, so a large base part cannot outvote a thin part. That score is a sum of per-part
terms of independent per-part fits, so the best hypothesis is the combination of each
part's best sample: hypotheses are drawn in batches, every part keeps its best, and the
loop stops once every part has drawn an all-inlier sample with probability ``confidence``.
The winner is refitted on its inliers (the weighted, batched
:func:`ancsh.geometry.umeyama.umeyama_batch`) until the inlier set stops changing.

The minimal-sample fits are a batched closed-form Umeyama (many 3-point fits in one numpy
call); the test suite checks it against :func:`ancsh.geometry.umeyama.umeyama`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.transforms import Sim3
from ..geometry.umeyama import umeyama_batch

__all__ = ["ArticulatedRansacResult", "articulated_ransac"]

_MAX_REFITS = 2
SAMPLE_SIZE = 3


@dataclass(frozen=True)
class ArticulatedRansacResult:
    """Outcome of :func:`articulated_ransac`.

    Attributes
    ----------
    poses : list of Sim3 or None
        Per-part ``T_cam_npcs`` refitted on the inliers; ``None`` on failure.
    inliers : (n,) bool
        Inliers of ``poses`` over the input points.
    inlier_ratios : (M,) float64
        Per-part inlier ratio.
    num_hypotheses : int
        Hypotheses drawn (each with one minimal sample per part).
    message : str
    """

    poses: list | None
    inliers: np.ndarray
    inlier_ratios: np.ndarray
    num_hypotheses: int
    message: str

    @property
    def success(self) -> bool:
        return self.poses is not None

    @property
    def score(self) -> float:
        """Mean per-part inlier ratio."""
        return float(np.mean(self.inlier_ratios))


def articulated_ransac(
    points, npcs, labels, num_parts: int, threshold: float | None, rng, *, relative_threshold: float | None = None,
    npcs_scale=None, weights=None, max_hypotheses: int = 200, confidence: float = 0.99, batch: int = 8,
) -> ArticulatedRansacResult:
    """Per-part Umeyama hypotheses from 3-point samples of every part, scored jointly.

    Parameters
    ----------
    points : (n, 3) float64
        Camera-frame points (metres).
    npcs : (n, 3) float64
        NPCS coordinates of the points.
    labels : (n,) int
        Part of each point; every part ``0..num_parts-1`` needs >= 3 points.
    num_parts : int
    threshold : float or None
        Inlier distance ``|s R c + t - p|`` in metres; ``None`` to use ``relative_threshold``.
    rng : numpy.random.Generator
    relative_threshold : float, optional
        Inlier distance in object diagonals (NAOCS units) when ``threshold`` is None; the
        object size in metres is the median of ``s / npcs_scale[j]`` over the first batch's
        valid minimal-sample fits of all parts (robust to outliers: most samples are clean).
    npcs_scale : (M,) float64, optional
        NPCS -> NAOCS scales, needed with ``relative_threshold``.
    weights : (n,) float64, optional
        Weights of the final refits (samples are drawn uniformly).
    max_hypotheses, confidence, batch
        Stopping rule: at most ``max_hypotheses``; stop earlier once every part has drawn an
        all-inlier sample with probability ``confidence`` (estimated from its best ratio).
    """
    if threshold is None and (relative_threshold is None or npcs_scale is None):
        raise ValueError("threshold: give a threshold in metres, or relative_threshold and npcs_scale")
    part_idx = [np.flatnonzero(labels == j) for j in range(num_parts)]
    counts = np.array([len(idx) for idx in part_idx])
    if np.any(counts == 0):
        raise ValueError(f"labels: part(s) {np.flatnonzero(counts == 0).tolist()} have no points")
    C, P, pad = _padded(part_idx, npcs, points)  # (M, n_max, 3) NPCS and points of each part
    best_ratio = np.full(num_parts, -1.0)
    best = [None] * num_parts
    drawn, needed = 0, max_hypotheses
    while drawn < min(needed, max_hypotheses):
        h = min(batch, max_hypotheses - drawn)
        drawn += h
        # One minimal sample per part and hypothesis, all parts fitted in one batched call.
        sample = (rng.random((num_parts, h, SAMPLE_SIZE)) * counts[:, None, None]).astype(np.intp)
        distinct = (sample[..., 0] != sample[..., 1]) & (sample[..., 0] != sample[..., 2]) & (sample[..., 1] != sample[..., 2])
        part = np.arange(num_parts)[:, None, None]
        R, t, s, valid = umeyama_batch(C[part, sample].reshape(-1, SAMPLE_SIZE, 3), P[part, sample].reshape(-1, SAMPLE_SIZE, 3))
        valid = (valid & distinct.ravel()).reshape(num_parts, h)
        R, t, s = R.reshape(num_parts, h, 3, 3), t.reshape(num_parts, h, 3), s.reshape(num_parts, h)
        fits = [(R[j][valid[j]], t[j][valid[j]], s[j][valid[j]]) for j in range(num_parts)]
        if threshold is None:
            sizes = np.concatenate([f[2] / npcs_scale[j] for j, f in enumerate(fits)])
            if sizes.size == 0:
                continue
            threshold = float(relative_threshold * np.median(sizes))
        for j, (n, (R, t, s)) in enumerate(zip(counts, fits)):
            if s.size == 0:
                continue
            diff = (s[:, None, None] * R) @ C[j, :n].T + t[:, :, None] - P[j, :n].T  # (h, 3, n)
            dist2 = np.sum(diff * diff, axis=1)
            ratio = np.count_nonzero(dist2 <= threshold**2, axis=1) / n
            i = int(np.argmax(ratio))
            if ratio[i] > best_ratio[j]:
                best_ratio[j] = ratio[i]
                best[j] = (R[i], t[i], s[i])
        if np.all(best_ratio > 0):
            needed = _hypotheses_needed(best_ratio, confidence, max_hypotheses)
    n_all = len(labels)
    if threshold is None or any(b is None for b in best):
        missing = [j for j, b in enumerate(best) if b is None]
        return ArticulatedRansacResult(
            None, np.zeros(n_all, dtype=bool), np.maximum(best_ratio, 0.0), drawn,
            f"no valid minimal sample for part(s) {missing} in {drawn} hypotheses (degenerate points)",
        )
    poses, inliers, ratios = _refit(best, C, P, pad, part_idx, threshold, weights, n_all)
    return ArticulatedRansacResult(
        poses, inliers, ratios, drawn, f"mean inlier ratio {ratios.mean():.3f} after {drawn} hypotheses",
    )


def _padded(part_idx, npcs, points):
    """Each part's NPCS and points, ``(M, n_max, 3)`` padded with zeros, and the ``(M, n_max)`` mask of real entries."""
    counts = [len(idx) for idx in part_idx]
    pad = np.arange(max(counts))[None, :] < np.array(counts)[:, None]
    C = np.zeros(pad.shape + (3,))
    P = np.zeros(pad.shape + (3,))
    for j, idx in enumerate(part_idx):
        C[j, : counts[j]], P[j, : counts[j]] = npcs[idx], points[idx]
    return C, P, pad


def _refit(best, C, P, pad, part_idx, threshold, weights, n_all):
    """Refit every part's winner on its inliers (all parts at once, padded with zero weights)."""
    M = len(part_idx)
    counts = pad.sum(axis=1)
    W = pad.astype(float)
    if weights is not None:
        for j, idx in enumerate(part_idx):
            W[j, : counts[j]] = weights[idx]
    R = np.stack([b[0] for b in best])
    t = np.stack([b[1] for b in best])
    s = np.array([b[2] for b in best], dtype=float)

    def inliers_of(R, t, s):
        d = s[:, None, None] * (C @ R.transpose(0, 2, 1)) + t[:, None, :] - P
        return (np.einsum("mki,mki->mk", d, d) <= threshold**2) & pad

    inl = inliers_of(R, t, s)
    active = np.ones(M, dtype=bool)
    for _ in range(_MAX_REFITS):
        R_new, t_new, s_new, valid = umeyama_batch(C, P, W * inl)
        inl_new = inliers_of(R_new, t_new, s_new)
        n_old, n_new = inl.sum(axis=1), inl_new.sum(axis=1)
        accept = active & valid & (n_new >= n_old)
        changed = np.any(inl_new != inl, axis=1)
        R[accept], t[accept], s[accept], inl[accept] = R_new[accept], t_new[accept], s_new[accept], inl_new[accept]
        active = accept & changed
        if not active.any():
            break
    inliers = np.zeros(n_all, dtype=bool)
    for j, idx in enumerate(part_idx):
        inliers[idx[inl[j, : counts[j]]]] = True
    poses = [Sim3.unchecked(R[j], t[j], s[j]) for j in range(M)]
    return poses, inliers, inl.sum(axis=1) / counts


def _hypotheses_needed(ratios: np.ndarray, confidence: float, cap: int) -> int:
    if confidence >= 1.0:
        return cap
    p_good = np.clip(ratios, 1e-12, 1.0) ** SAMPLE_SIZE
    if np.all(p_good >= 1.0):
        return 0
    p_good = np.minimum(p_good, 1.0 - 1e-12)
    return int(min(cap, np.max(np.ceil(np.log(1.0 - confidence) / np.log(1.0 - p_good)))))
