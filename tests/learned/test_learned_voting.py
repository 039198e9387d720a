"""Robust joint voting recovers a known axis and pivot from noisy votes with outliers."""

import numpy as np
import pytest

from ancsh.geometry.rotations import random_rotation
from ancsh.learned.inference.voting import vote_axis, vote_joints, vote_pivot


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _scene(seed, n=400, outliers=0.25, noise=0.02):
    """Points around a revolute axis with per-point 7-D votes, a share of them wild."""
    rng = np.random.default_rng(seed)
    axis = _unit(rng.normal(size=3))
    pivot = rng.uniform(-0.3, 0.3, 3)
    t = rng.uniform(-0.4, 0.4, n)
    perp = _unit(np.cross(axis, rng.normal(size=(n, 3))))
    dist = rng.uniform(0.02, 0.2, n)
    points = pivot + t[:, None] * axis + dist[:, None] * perp
    votes = np.zeros((n, 7))
    votes[:, :3] = _unit(axis + noise * rng.normal(size=(n, 3)))
    votes[:, 3:6] = _unit(-perp + noise * rng.normal(size=(n, 3)))
    votes[:, 6] = dist + noise * rng.normal(size=n)
    # Outliers are biased, like points of a wrongly associated region: a common wrong axis and offset.
    bad = rng.random(n) < outliers
    wrong = _unit(rng.normal(size=3))
    votes[bad, :3] = _unit(wrong + 0.3 * rng.normal(size=(bad.sum(), 3)))
    votes[bad, 3:6] = _unit(wrong + 0.3 * rng.normal(size=(bad.sum(), 3)))
    votes[bad, 6] = rng.uniform(0.3, 0.6, bad.sum())
    return points, votes, axis, pivot, bad


def _line_distance(p, axis, q):
    d = p - q
    return np.linalg.norm(d - (d @ axis) * axis)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_joint_voting_recovers_axis_and_pivot_despite_outliers(seed):
    points, votes, axis, pivot, bad = _scene(seed)
    (vote,) = vote_joints(points, np.ones(len(points), dtype=int), votes, [True])
    angle = np.degrees(np.arccos(np.clip(vote.axis @ axis, -1, 1)))
    assert angle < 1.0  # same sign as the votes, not flipped
    assert _line_distance(vote.pivot, axis, pivot) < 0.01
    # a bare mean of the same votes is clearly worse
    mean_axis = _unit(votes[:, :3].mean(0))
    mean_pivot = (points + votes[:, 6:7] * votes[:, 3:6]).mean(0)
    assert np.degrees(np.arccos(mean_axis @ axis)) > 2 * angle
    assert _line_distance(mean_pivot, axis, pivot) > 2 * _line_distance(vote.pivot, axis, pivot)
    assert vote.axis_inliers < len(points) and vote.num_votes == len(points)


def test_axis_vote_is_sign_invariant_and_follows_the_majority():
    rng = np.random.default_rng(4)
    R = random_rotation(rng)
    a = R[:, 0]
    votes = np.vstack([np.tile(a, (30, 1)), np.tile(-a, (10, 1))]) + 0.01 * rng.normal(size=(40, 3))
    axis, inliers = vote_axis(votes)
    assert axis @ a > 0.999 and inliers.all()
    axis, _ = vote_axis(-votes)
    assert axis @ a < -0.999


def test_pivot_vote_noise_free_is_exact():
    rng = np.random.default_rng(5)
    a = _unit(rng.normal(size=3))
    q = rng.normal(size=3)
    pts = q + rng.uniform(-1, 1, (20, 1)) * a
    pivot, inliers = vote_pivot(pts, a)
    assert _line_distance(pivot, a, q) < 1e-12 and inliers.all()


def test_joints_with_too_few_votes_and_prismatic_joints():
    points, votes, axis, _, _ = _scene(6, outliers=0.0)
    assoc = np.full(len(points), 2)
    assoc[:2] = 1
    res = vote_joints(points, assoc, votes, [True, False])
    assert res[0] is None
    assert res[1].axis @ axis > 0.999
    np.testing.assert_allclose(res[1].pivot, np.median(points[2:], axis=0))


def test_voting_rejects_bad_input():
    with pytest.raises(ValueError, match="votes"):
        vote_axis(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="weights"):
        vote_axis(np.ones((3, 3)), weights=[1, -1, 1])
    with pytest.raises(ValueError, match="association"):
        vote_joints(np.zeros((4, 3)), np.zeros(3, dtype=int), np.zeros((4, 7)), [True])
    with pytest.raises(ValueError, match="joint"):
        vote_joints(np.zeros((4, 3)), np.zeros(4, dtype=int), np.zeros((4, 6)), [True])
