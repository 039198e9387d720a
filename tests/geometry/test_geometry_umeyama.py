"""Umeyama: recovery of seeded Sim3/SE3, weights, reflections, degenerate input."""

import numpy as np
import pytest
from scipy.optimize import minimize

from ancsh.geometry import DegeneratePointsError, Sim3, exp_so3, random_rotation, umeyama


def _random_sim3(rng):
    return Sim3(random_rotation(rng), rng.standard_normal(3) * 3, rng.uniform(0.1, 10.0))


@pytest.mark.parametrize("n", [3, 4, 100])
def test_recovers_a_random_sim3(rng, n):
    for _ in range(10):
        T = _random_sim3(rng)
        src = rng.standard_normal((n, 3))
        est = umeyama(src, T @ src)
        assert est.allclose(T, atol=1e-10)


def test_recovers_a_rigid_transform_without_scale(rng):
    T = Sim3(random_rotation(rng), rng.standard_normal(3))
    src = rng.standard_normal((30, 3))
    est = umeyama(src, T @ src, with_scale=False)
    assert est.scale == 1.0
    assert est.allclose(T, atol=1e-10)


def test_without_scale_ignores_a_scaled_target(rng):
    # Rigid fit to data that is scaled about its centroid: the rotation is still exact.
    T = Sim3(random_rotation(rng), rng.standard_normal(3), 3.0)
    src = rng.standard_normal((30, 3))
    src -= src.mean(axis=0)
    est = umeyama(src, T @ src, with_scale=False)
    np.testing.assert_allclose(est.rotation, T.rotation, atol=1e-10)
    np.testing.assert_allclose(est.translation, T.translation, atol=1e-10)


def test_integer_weights_equal_repeated_points(rng):
    src = rng.standard_normal((12, 3))
    dst = _random_sim3(rng) @ src + 0.3 * rng.standard_normal((12, 3))  # noisy: weights matter
    counts = rng.integers(1, 5, size=12)
    weighted = umeyama(src, dst, weights=counts)
    repeated = umeyama(np.repeat(src, counts, axis=0), np.repeat(dst, counts, axis=0))
    assert weighted.allclose(repeated, atol=1e-10)
    assert not weighted.allclose(umeyama(src, dst), atol=1e-3)


def test_zero_weights_drop_points(rng):
    T = _random_sim3(rng)
    src = rng.standard_normal((10, 3))
    dst = T @ src
    dst[:4] += 100.0  # outliers, removed by zero weight
    w = np.r_[np.zeros(4), np.ones(6)]
    assert umeyama(src, dst, weights=w).allclose(T, atol=1e-10)


def test_minimises_the_weighted_cost(rng):
    # Noisy data: no perturbation of the solution lowers the weighted squared error.
    src = rng.standard_normal((20, 3))
    dst = _random_sim3(rng) @ src + 0.2 * rng.standard_normal((20, 3))
    w = rng.uniform(0.1, 2.0, 20)
    est = umeyama(src, dst, weights=w)

    def cost(x):
        T = Sim3(exp_so3(x[:3]) @ est.rotation, est.translation + x[3:6], est.scale * np.exp(x[6]))
        return float(w @ np.sum((T @ src - dst) ** 2, axis=1))

    res = minimize(cost, np.zeros(7), method="BFGS", options={"gtol": 1e-12})
    assert cost(np.zeros(7)) <= res.fun + 1e-10
    np.testing.assert_allclose(res.x, 0.0, atol=1e-5)


def test_reflected_target_gives_a_proper_rotation(rng):
    # dst is a mirror image of src: the best *rotation* is returned, never the reflection.
    src = rng.standard_normal((50, 3))
    dst = src * np.array([1.0, 1.0, -1.0])
    est = umeyama(src, dst, with_scale=False)
    assert np.linalg.det(est.rotation) == pytest.approx(1.0, abs=1e-12)
    cost = lambda T: float(np.sum((T @ src - dst) ** 2))  # noqa: E731
    # Compare with the best of many random starts of a direct search over rotations.
    best = min(
        minimize(
            lambda x: cost(Sim3(exp_so3(x[:3]), x[3:])), np.r_[rng.standard_normal(3), np.zeros(3)], method="BFGS"
        ).fun
        for _ in range(8)
    )
    assert cost(est) <= best + 1e-8


def test_planar_points_mirrored_in_plane_are_fitted_exactly(rng):
    # For points in z = 0, the in-plane mirror x -> -x equals a half turn about y.
    # The cross-covariance has rank 2, so a naive SVD fit may return a reflection.
    src = np.c_[rng.standard_normal((20, 2)), np.zeros(20)]
    T = _random_sim3(rng)
    dst = T @ (src * np.array([-1.0, 1.0, 1.0]))
    est = umeyama(src, dst)
    assert np.linalg.det(est.rotation) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(est @ src, dst, atol=1e-9)


@pytest.mark.parametrize(
    "src, match",
    [
        (np.zeros((2, 3)), "src: need at least 3 points, got 2"),
        (np.ones((5, 3)) * 7.0, "src: points are coincident"),
        (np.outer(np.arange(5.0), [1.0, 2.0, 3.0]) + 1.0, "src: points are collinear"),
    ],
)
def test_degenerate_source(src, match):
    with pytest.raises(ValueError, match=match):
        umeyama(src, src + 1.0)


def test_degenerate_errors_are_a_dedicated_subclass(rng):
    line = np.outer(np.arange(4.0), [0.0, 0.0, 1.0])
    with pytest.raises(DegeneratePointsError, match="dst: points are collinear"):
        umeyama(rng.standard_normal((4, 3)), line)
    # A collinear set in general position (not only along an axis) is also caught.
    R = random_rotation(rng)
    with pytest.raises(DegeneratePointsError, match="src: points are collinear"):
        umeyama(line @ R.T + rng.standard_normal(3), rng.standard_normal((4, 3)))


def test_weights_can_make_points_degenerate(rng):
    src = rng.standard_normal((6, 3))
    with pytest.raises(ValueError, match="weights: need at least 3 positive weights, got 2"):
        umeyama(src, src, weights=[1, 1, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="weights: need at least 3 positive weights, got 0"):
        umeyama(src, src, weights=np.zeros(6))
    with pytest.raises(ValueError, match="weights: must be non-negative"):
        umeyama(src, src, weights=[1, 1, 1, 1, 1, -1])
    with pytest.raises(ValueError, match=r"weights: expected shape \(6,\)"):
        umeyama(src, src, weights=np.ones(5))
    with pytest.raises(ValueError, match="weights: contains NaN"):
        umeyama(src, src, weights=[1, 1, 1, 1, 1, np.nan])


def test_bad_shapes_and_nan(rng):
    src = rng.standard_normal((6, 3))
    with pytest.raises(ValueError, match=r"dst: expected shape \(6, 3\) to match src, got \(5, 3\)"):
        umeyama(src, src[:5])
    with pytest.raises(ValueError, match=r"src: expected shape \(N, 3\)"):
        umeyama(src[:, :2], src[:, :2])
    bad = src.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="dst: contains NaN"):
        umeyama(src, bad)


def test_rank_one_cross_covariance_is_degenerate():
    # Both sets span a plane, but their correlation only fixes one direction.
    src = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]])
    dst = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, 1, 0]])
    with pytest.raises(DegeneratePointsError, match="cross-covariance with dst has rank < 2"):
        umeyama(src, dst)


def test_batch_matches_umeyama_one_problem_at_a_time(rng):
    from ancsh.geometry.umeyama import umeyama_batch

    src = rng.normal(size=(40, 5, 3))
    dst = rng.normal(size=(40, 5, 3))  # unrelated points: reflections and poor fits included
    R, t, s, valid = umeyama_batch(src, dst)
    assert valid.all()
    for h in range(40):
        assert Sim3(R[h], t[h], s[h]).allclose(umeyama(src[h], dst[h]), atol=1e-10)


def test_batch_weights_and_zero_padding_match_weighted_umeyama(rng):
    from ancsh.geometry.umeyama import umeyama_batch

    sizes = (7, 30, 12)
    src = np.zeros((3, 30, 3))
    dst = np.zeros((3, 30, 3))
    w = np.zeros((3, 30))
    for h, n in enumerate(sizes):
        T = _random_sim3(rng)
        src[h, :n] = rng.standard_normal((n, 3))
        dst[h, :n] = T @ src[h, :n] + 0.01 * rng.standard_normal((n, 3))
        w[h, :n] = rng.uniform(0.1, 2.0, n)
    for with_scale in (True, False):
        R, t, s, valid = umeyama_batch(src, dst, w, with_scale=with_scale)
        assert valid.all()
        for h, n in enumerate(sizes):
            ref = umeyama(src[h, :n], dst[h, :n], weights=w[h, :n], with_scale=with_scale)
            assert Sim3(R[h], t[h], s[h]).allclose(ref, atol=1e-10)


def test_batch_flags_degenerate_problems(rng):
    from ancsh.geometry.umeyama import umeyama_batch

    good = rng.normal(size=(4, 3))
    line = np.outer([0.0, 1.0, 2.0, 3.0], [1.0, 2.0, 3.0])
    same = np.ones((4, 3))
    src = np.stack([good, line, same, good, good])
    dst = np.stack([good @ random_rotation(rng).T, good, good, same, good + 1.0])
    w = np.ones((5, 4))
    w[4, 2:] = 0.0  # only two points carry weight
    _, _, _, valid = umeyama_batch(src, dst, w)
    np.testing.assert_array_equal(valid, [True, False, False, False, False])
