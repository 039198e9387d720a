"""Batched minimal-sample Umeyama and the articulated RANSAC initialisation."""

import numpy as np
import pytest

from ancsh.geometry.rotations import random_rotation
from ancsh.geometry.umeyama import umeyama
from ancsh.solvers.hypotheses import articulated_ransac, batched_umeyama


def test_batched_umeyama_matches_geometry_umeyama():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(40, 5, 3))
    dst = rng.normal(size=(40, 5, 3))  # unrelated points: reflections and poor fits included
    R, t, s, valid = batched_umeyama(src, dst)
    assert valid.all()
    for h in range(40):
        T = umeyama(src[h], dst[h])
        np.testing.assert_allclose(R[h], T.rotation, atol=1e-10)
        np.testing.assert_allclose(t[h], T.translation, atol=1e-10)
        assert abs(s[h] - T.scale) < 1e-10


def test_batched_umeyama_flags_degenerate_samples():
    rng = np.random.default_rng(1)
    good = rng.normal(size=(3, 3))
    line = np.outer([0.0, 1.0, 2.0], [1.0, 2.0, 3.0])
    same = np.ones((3, 3))
    src = np.stack([good, line, same, good])
    dst = np.stack([good @ random_rotation(rng).T, good, good, same])
    _, _, _, valid = batched_umeyama(src, dst)
    np.testing.assert_array_equal(valid, [True, False, False, False])


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
