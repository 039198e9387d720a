"""RANSAC: outlier rejection, stratified samples, custom scores, adaptive stopping, failures."""

import numpy as np
import pytest

from ancsh.geometry import (
    RansacStatus,
    Sim3,
    fit_sim3_ransac,
    mean_group_inlier_ratio,
    random_rotation,
    ransac,
    umeyama,
)


def _line_problem(rng, n=200, outlier_fraction=0.4, noise=0.01):
    """2D points on y = a x + b with a fraction replaced by uniform outliers."""
    a, b = 0.7, -0.3
    x = rng.uniform(-1, 1, n)
    y = a * x + b + noise * rng.standard_normal(n)
    outlier = rng.permutation(n) < int(outlier_fraction * n)
    y[outlier] = rng.uniform(-3, 3, outlier.sum())
    return x, y, outlier, (a, b)


def _line_callbacks(x, y):
    def estimator(idx):
        A = np.c_[x[idx], np.ones(len(idx))]
        if np.linalg.matrix_rank(A) < 2:
            return None
        return np.linalg.lstsq(A, y[idx], rcond=None)[0]

    def residual(model):
        return np.abs(model[0] * x + model[1] - y)

    return estimator, residual


def test_recovers_a_line_with_40_percent_outliers(rng):
    x, y, outlier, (a, b) = _line_problem(rng)
    est, res = _line_callbacks(x, y)
    result = ransac(len(x), est, res, 2, 0.04, rng)
    assert result.success and result.status is RansacStatus.SUCCESS
    np.testing.assert_allclose(result.model, [a, b], atol=0.01)
    # Every true inlier is found; the accepted outliers lie within the threshold by chance.
    assert np.all(result.inliers[~outlier])
    assert result.num_inliers == result.inliers.sum()
    assert result.score == result.num_inliers
    assert np.all(result.residuals[result.inliers] <= 0.04)
    assert result.num_refits >= 1


def test_sim3_ransac_recovers_the_pose_with_40_percent_outliers(rng):
    T = Sim3(random_rotation(rng), rng.standard_normal(3), 2.0)
    src = rng.uniform(-0.5, 0.5, (300, 3))
    dst = T @ src
    outlier = rng.permutation(300) < 120
    dst[outlier] += rng.uniform(-1.0, 1.0, (120, 3)) + 0.5
    result = fit_sim3_ransac(src, dst, 1e-6, rng)
    assert result.success
    assert result.model.allclose(T, atol=1e-10)
    np.testing.assert_array_equal(result.inliers, ~outlier)
    assert result.num_iterations < 1000  # adaptive stopping kicked in


def test_adaptive_iterations_follow_the_confidence_formula(rng):
    x, y, outlier, _ = _line_problem(rng, outlier_fraction=0.5, noise=0.0)
    est, res = _line_callbacks(x, y)
    calls, first_clean = [0], []

    def counting_estimator(idx):
        calls[0] += 1
        if not first_clean and not outlier[idx].any():
            first_clean.append(calls[0])
        return est(idx)

    result = ransac(len(x), counting_estimator, res, 2, 1e-9, rng, refit=False, max_iterations=10_000)
    np.testing.assert_array_equal(result.inliers, ~outlier)
    # Until a clean sample, the best line has 2 inliers (needed ~ max_iterations); after it the
    # inlier ratio is w = 1/2 and ceil(log(1 - 0.99) / log(1 - w^2)) samples suffice in total.
    needed = int(np.ceil(np.log(0.01) / np.log(1 - 0.25)))
    assert result.num_iterations == max(needed, first_clean[0])
    long = ransac(len(x), est, res, 2, 1e-9, np.random.default_rng(1), confidence=1.0, max_iterations=300)
    assert long.num_iterations == 300


def test_stratified_samples_draw_sample_size_from_every_group(rng):
    groups = np.repeat([0, 1, 2], [5, 50, 8])
    seen = []

    def estimator(idx):
        seen.append(idx.copy())
        return 0.0

    result = ransac(len(groups), estimator, lambda m: np.zeros(len(groups)), 3, 0.1, rng,
                    groups=groups, max_iterations=40, confidence=1.0, refit=False)
    assert result.num_iterations == 40 and len(seen) == 40
    for idx in seen:
        assert len(np.unique(idx)) == 9
        np.testing.assert_array_equal(np.bincount(groups[idx], minlength=3), [3, 3, 3])


def test_stratified_fit_of_two_independent_lines(rng):
    # One hypothesis = one line per group, as the articulated fit needs a pose per part.
    x1, y1, out1, truth1 = _line_problem(rng, n=300, outlier_fraction=0.3)
    x2, y2, out2, _ = _line_problem(rng, n=30, outlier_fraction=0.3)
    y2 = y2 * -1.0  # second line: y = -0.7 x + 0.3
    x, y = np.r_[x1, x2], np.r_[y1, y2]
    groups = np.repeat([0, 1], [300, 30])
    fits = [_line_callbacks(x[groups == g], y[groups == g]) for g in (0, 1)]
    offsets = [0, 300]

    def estimator(idx):
        models = []
        for g, (est, _) in enumerate(fits):
            m = est(idx[groups[idx] == g] - offsets[g])
            if m is None:
                return None
            models.append(m)
        return models

    def residual(models):
        return np.r_[fits[0][1](models[0]), fits[1][1](models[1])]

    score = mean_group_inlier_ratio(groups)
    result = ransac(len(x), estimator, residual, 2, 0.04, rng, groups=groups, score=score)
    assert result.success
    np.testing.assert_allclose(result.model[0], truth1, atol=0.01)
    np.testing.assert_allclose(result.model[1], [-0.7, 0.3], atol=0.05)
    assert result.score == pytest.approx(score(result.inliers, result.residuals))
    assert np.all(result.inliers[np.r_[~out1, ~out2]])


def test_mean_group_inlier_ratio_weighs_groups_equally():
    groups = np.array([0, 0, 0, 0, 1])
    score = mean_group_inlier_ratio(groups)
    assert score(np.array([True, True, True, True, False]), None) == pytest.approx(0.5)
    assert score(np.array([False, False, False, False, True]), None) == pytest.approx(0.5)
    assert score(np.array([True, True, False, False, True]), None) == pytest.approx(0.75)
    with pytest.raises(ValueError, match=r"inliers: expected shape \(5,\)"):
        score(np.ones(4, dtype=bool), None)
    with pytest.raises(ValueError, match="groups: expected a 1-D integer array"):
        mean_group_inlier_ratio([0.5, 1.0])


def test_degenerate_samples_are_skipped(rng):
    calls = {"n": 0}

    def estimator(idx):
        calls["n"] += 1
        return None if calls["n"] % 2 else float(idx[0])

    result = ransac(10, estimator, lambda m: np.abs(np.arange(10) - m), 1, 0.5, rng,
                    max_iterations=20, confidence=1.0, refit=False)
    assert result.success
    assert result.num_iterations == 20 and result.num_valid_hypotheses == 10


def test_no_valid_hypothesis_is_a_status_not_an_exception(rng):
    result = ransac(10, lambda idx: None, lambda m: np.zeros(10), 3, 0.1, rng, max_iterations=25)
    assert not result.success
    assert result.status is RansacStatus.NO_VALID_HYPOTHESIS
    assert result.model is None and result.residuals is None
    assert result.num_iterations == 25 and result.num_valid_hypotheses == 0
    assert not result.inliers.any() and result.inliers.shape == (10,)
    assert "degenerate" in result.message


def test_too_few_data_is_a_status(rng):
    result = ransac(2, lambda idx: 0.0, lambda m: np.zeros(2), 3, 0.1, rng)
    assert result.status is RansacStatus.INSUFFICIENT_DATA
    groups = np.array([0, 0, 0, 1, 1])
    result = ransac(5, lambda idx: 0.0, lambda m: np.zeros(5), 3, 0.1, rng, groups=groups)
    assert result.status is RansacStatus.INSUFFICIENT_DATA and "has 2" in result.message
    result = fit_sim3_ransac(np.zeros((0, 3)), np.zeros((0, 3)), 0.1, rng)
    assert result.status is RansacStatus.INSUFFICIENT_DATA


def test_all_degenerate_sim3_samples_fail_gracefully(rng):
    line = np.outer(np.linspace(0, 1, 20), [1.0, 2.0, 3.0])
    result = fit_sim3_ransac(line, line + 1.0, 0.01, rng, max_iterations=30)
    assert result.status is RansacStatus.NO_VALID_HYPOTHESIS


def test_refit_is_the_least_squares_fit_on_the_inliers(rng):
    T = Sim3(random_rotation(rng), rng.standard_normal(3), 1.5)
    src = rng.uniform(-0.5, 0.5, (400, 3))
    dst = T @ src + 0.002 * rng.standard_normal((400, 3))
    dst[:40] += 1.0  # outliers
    refit = fit_sim3_ransac(src, dst, 0.01, np.random.default_rng(3))
    assert refit.num_refits >= 1
    # Refitting stops once the inlier set is stable: the model is Umeyama on its own inliers.
    assert refit.model.allclose(umeyama(src[refit.inliers], dst[refit.inliers]), atol=1e-12)
    assert not refit.inliers[:40].any()

    def residual(M):
        return np.linalg.norm(M @ src - dst, axis=1)

    no_refit = ransac(400, lambda i: umeyama(src[i], dst[i]), residual, 3, 0.01,
                      np.random.default_rng(3), refit=False)
    assert no_refit.num_refits == 0
    err = [np.linalg.norm(r.model.translation - T.translation) for r in (refit, no_refit)]
    assert err[0] < err[1]


def test_same_seed_same_result():
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    x, y, _, _ = _line_problem(np.random.default_rng(0))
    est, res = _line_callbacks(x, y)
    r1 = ransac(len(x), est, res, 2, 0.04, rng_a, refit=False)
    r2 = ransac(len(x), est, res, 2, 0.04, rng_b, refit=False)
    np.testing.assert_array_equal(r1.model, r2.model)
    assert r1.num_iterations == r2.num_iterations


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"sample_size": 0}, "sample_size: expected an integer >= 1"),
        ({"num_data": -1}, "num_data: expected an integer >= 0"),
        ({"threshold": -1.0}, "threshold: expected a finite non-negative"),
        ({"confidence": 0.0}, r"confidence: expected a number in \(0, 1\]"),
        ({"max_iterations": 0}, "max_iterations: expected an integer >= 1"),
        ({"groups": np.zeros(3, dtype=int)}, r"groups: expected shape \(10,\)"),
        ({"estimator": 3}, "estimator: expected a callable"),
    ],
)
def test_invalid_arguments(rng, kwargs, match):
    args = dict(num_data=10, estimator=lambda idx: 0.0, residual=lambda m: np.zeros(10),
                sample_size=2, threshold=0.1, rng=rng)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        ransac(**args)


def test_residual_with_wrong_shape_is_reported(rng):
    with pytest.raises(ValueError, match=r"residual: expected an array of shape \(10,\)"):
        ransac(10, lambda idx: 0.0, lambda m: np.zeros(9), 2, 0.1, rng)
