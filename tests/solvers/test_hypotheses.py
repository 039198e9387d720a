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
