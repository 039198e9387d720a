"""The articulated RANSAC initialisation."""

import numpy as np
import pytest

from ancsh.geometry.rotations import random_rotation
from ancsh.geometry.umeyama import umeyama
from ancsh.solvers.hypotheses import articulated_ransac


def test_articulated_ransac_finds_every_part_despite_outliers():
    rng = np.random.default_rng(2)
    poses = [(random_rotation(rng), rng.normal(size=3), rng.uniform(0.2, 2.0)) for _ in range(3)]
    sizes = [300, 40, 120]  # a small part must not be outvoted
    labels = np.repeat(np.arange(3), sizes)
    npcs = rng.uniform(-0.5, 0.5, size=(labels.size, 3))
    pts = np.empty_like(npcs)
    for j, (R, t, s) in enumerate(poses):
        pts[labels == j] = s * npcs[labels == j] @ R.T + t
    bad = rng.random(labels.size) < 0.3
    pts[bad] += rng.normal(size=(bad.sum(), 3))
    res = articulated_ransac(pts, npcs, labels, 3, 1e-6, rng, max_hypotheses=500)
    assert res.success
    for T, (R, t, s) in zip(res.poses, poses):
        np.testing.assert_allclose(T.rotation, R, atol=1e-9)
        np.testing.assert_allclose(T.translation, t, atol=1e-9)
    np.testing.assert_array_equal(res.inliers, ~bad)
    assert res.score == pytest.approx(np.mean([np.mean(~bad[labels == j]) for j in range(3)]))


def _reference_ransac(points, npcs, labels, num_parts, rng, relative_threshold, npcs_scale, max_hypotheses=200,
                      confidence=0.99, batch=8):
    """articulated_ransac written plainly: one unbatched Umeyama per minimal sample and per refit, the same draws."""
    from ancsh.solvers.hypotheses import _hypotheses_needed

    part_idx = [np.flatnonzero(labels == j) for j in range(num_parts)]
    counts = np.array([len(i) for i in part_idx])
    best_ratio, best = np.full(num_parts, -1.0), [None] * num_parts
    drawn, needed, threshold = 0, max_hypotheses, None
    while drawn < min(needed, max_hypotheses):
        h = min(batch, max_hypotheses - drawn)
        drawn += h
        sample = (rng.random((num_parts, h, 3)) * counts[:, None, None]).astype(np.intp)
        fits = []
        for j in range(num_parts):
            fits.append([umeyama(npcs[part_idx[j][s]], points[part_idx[j][s]]) for s in sample[j] if len(set(s)) == 3])
        if threshold is None:
            threshold = relative_threshold * np.median([T.scale / npcs_scale[j] for j in range(num_parts) for T in fits[j]])
        for j in range(num_parts):
            idx = part_idx[j]
            ratios = [np.mean(np.linalg.norm(T.apply(npcs[idx]) - points[idx], axis=1) <= threshold) for T in fits[j]]
            i = int(np.argmax(ratios))
            if ratios[i] > best_ratio[j]:
                best_ratio[j], best[j] = ratios[i], fits[j][i]
        needed = _hypotheses_needed(best_ratio, confidence, max_hypotheses)
    inliers = np.zeros(len(labels), dtype=bool)
    poses = []
    for j, T in enumerate(best):
        idx = part_idx[j]
        inl = np.linalg.norm(T.apply(npcs[idx]) - points[idx], axis=1) <= threshold
        for _ in range(2):
            T_new = umeyama(npcs[idx], points[idx], weights=inl.astype(float))
            inl_new = np.linalg.norm(T_new.apply(npcs[idx]) - points[idx], axis=1) <= threshold
            if inl_new.sum() < inl.sum():
                break
            changed = np.any(inl_new != inl)
            T, inl = T_new, inl_new
            if not changed:
                break
        poses.append(T)
        inliers[idx[inl]] = True
    return poses, inliers, drawn


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_batched_ransac_equals_the_plain_one_on_seeded_inputs(seed):
    """The vectorised RANSAC (batched minimal samples, all parts' refits at once) is the plain loop, draw for draw."""
    rng = np.random.default_rng(seed)
    sizes = [400, 60, 150]
    labels = np.repeat(np.arange(3), sizes)
    npcs = rng.uniform(-0.5, 0.5, size=(labels.size, 3))
    pts = np.empty_like(npcs)
    for j in range(3):
        R, t, s = random_rotation(rng), rng.normal(size=3), rng.uniform(0.3, 1.5)
        pts[labels == j] = s * npcs[labels == j] @ R.T + t + rng.normal(scale=0.005, size=(sizes[j], 3))
    bad = rng.random(labels.size) < 0.35
    pts[bad] += rng.normal(scale=0.3, size=(bad.sum(), 3))
    scale = np.array([1.0, 0.8, 1.2])
    res = articulated_ransac(pts, npcs, labels, 3, None, np.random.default_rng(seed + 10), relative_threshold=0.05,
                             npcs_scale=scale)
    poses, inliers, drawn = _reference_ransac(pts, npcs, labels, 3, np.random.default_rng(seed + 10), 0.05, scale)
    assert res.success and res.num_hypotheses == drawn
    np.testing.assert_array_equal(res.inliers, inliers)
    for T, ref in zip(res.poses, poses):
        np.testing.assert_allclose(T.rotation, ref.rotation, atol=1e-10)
        np.testing.assert_allclose(T.translation, ref.translation, atol=1e-10)
        assert T.scale == pytest.approx(ref.scale, rel=1e-10)
