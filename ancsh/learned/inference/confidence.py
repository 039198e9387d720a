"""A calibrated estimate of whether a prediction is good: P(every part's rotation error < 10 deg).

Features of a fit (:func:`fit_features`, from :func:`ancsh.learned.inference.predict.part_quality`): the
lowest part inlier ratio, the largest part residual relative to the category's typical size, the
lowest and the mean part segmentation margin, and the log of the point count. A logistic
regression (scikit-learn) maps them to the probability, trained on the fits of a seeded mix of good and bad
cases (rendered held-out frames of a seed stream other than the evaluation's, stress scenes isolated without a
mask, cropped and merged segments, perturbed network outputs, other categories' frames), its reliability
measured on a separate half of them (:mod:`ancsh.studies.confidence_calibration`, ``ancsh calibrate --category
laptop``, which with ``--install`` writes the model beside the shipped weights; a constant model is refused). The fitted model is a few numbers in
``ancsh/weights/<category>_confidence.json``; applying it needs numpy only (:func:`probability_good`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["ALIGN_SHARE", "FEATURES", "GOOD_ROTATION_DEG", "OBJECT_FEATURES", "calibration_path", "fit_features",
           "object_calibration_path", "object_features", "object_model", "probability_good"]

FEATURES = ("inlier_ratio_min", "residual_rel_max", "seg_margin_min", "seg_margin_mean", "log_points")
#: A fit is "good" when every part's rotation error is below this (degrees).
GOOD_ROTATION_DEG = 10.0


def calibration_path(category: str) -> Path:
    """``<category>_confidence.json`` in the category's weights folder (``ancsh/weights/`` for the built-in ones)."""
    from ..network.weights import weights_dir

    return weights_dir(category) / f"{category}_confidence.json"


def fit_features(quality, typical_size: float) -> np.ndarray:
    """``(len(FEATURES),)`` float64 from per-part quality dicts (NaN entries count as worst); ``typical_size``: the
    category's typical box diagonal, metres (:attr:`~ancsh.data.category_types.CategoryConvention.typical_size`)."""
    size = _size(typical_size)
    inl = [q["inlier_ratio"] for q in quality if q["points"]]
    res = [q["residual_m"] / size for q in quality if q["points"]]
    mar = [q["seg_margin"] for q in quality if q["points"]]
    pts = sum(q["points"] for q in quality)

    def clean(values, worst):
        v = np.asarray(values, dtype=np.float64)
        return np.where(np.isfinite(v), v, worst) if v.size else np.array([worst])

    return np.array([clean(inl, 0.0).min(), clean(res, 1.0).max(), clean(mar, 0.0).min(), clean(mar, 0.0).mean(),
                     np.log(max(pts, 1))])


def _size(typical_size) -> float:
    """``typical_size`` checked: a positive number of metres (a category name is refused: resolve it once)."""
    if isinstance(typical_size, (str, bool)) or not isinstance(typical_size, (int, float, np.floating)) \
            or not np.isfinite(typical_size) or typical_size <= 0:
        raise ValueError(f"typical_size: expected a positive number of metres (the category's typical diagonal), "
                         f"got {typical_size!r}")
    return float(typical_size)


def probability_good(calibration: dict, x) -> float:
    """P(good) of one feature vector under a :func:`fit_calibrator` result.

    The logistic function is evaluated without overflow (``scipy.special.expit``): a feature far outside
    the calibration frames' range (e.g. 50 000 points against ~1 000) gives a probability of 0 or 1, not a
    floating-point warning.
    """
    from scipy.special import expit

    z = (np.asarray(x, dtype=np.float64) - calibration["mean"]) / np.asarray(calibration["scale"])
    return float(expit(z @ np.asarray(calibration["coef"]) + calibration["intercept"]))




# --- is it the category's object at all? -------------------------------------------------------------
#: Features of P(the fitted segment is an object of the category) (:mod:`ancsh.studies.object_evidence`):
#: render-and-compare of the fitted category template (:func:`ancsh.solvers.twin.compare_fit`), the model moved along
#: the camera's depth axis onto the segment first (:func:`ancsh.solvers.render_compare.aligned_comparison`, at most
#: :data:`ALIGN_SHARE` of the object's diagonal): the share of the segment's pixels it explains, the share of its own
#: pixels the sensor sees through, the median residual relative to the object's size, and the move relative to it;
#: the fitted object's size against the category's typical one (log ratio, and its absolute value), the fit's lowest
#: part inlier ratio and mean segmentation margin, and the share of the points on one plane (a wall, a table top or a
#: face seen head-on explains itself too well).
OBJECT_FEATURES = ("explained", "see_through", "residual_rel", "shift_rel", "log_size_ratio", "abs_log_size_ratio",
                   "inlier_ratio_min", "seg_margin_mean", "planar_share")
#: The render-and-compare of ``p_object`` moves the model along the depth axis by at most this share of the fitted
#: object's diagonal. A category fit places the boxes' unseen sides by the category's proportions: a right fit of a
#: deep washing machine (stress scene 3 of ``ancsh bench scenes``, 3.7 deg off) stood 12 cm (9 % of its diagonal)
#: before its front, 93 % of its pixels "seen through"; aligned, 20 %.
ALIGN_SHARE = 0.25
#: Points within this share of the object's diagonal (and at least 1 cm) of one plane count for ``planar_share``.
PLANE_TOLERANCE = 0.02


def object_model(calibration: dict, *, segmented: bool) -> dict:
    """The logistic model of a ``p_object`` calibration that judges a fit (:func:`probability_good` applies it): for a
    segment the isolation found without the user's help (``segmented``), the calibration's ``"segments"`` model where
    it has one (fitted on rendered scenes' candidate segments too, :mod:`ancsh.studies.object_evidence`), else its
    main model (fitted on masked renders: what a user's mask shows)."""
    return calibration.get("segments") or calibration if segmented else calibration


def object_calibration_path(category: str) -> Path:
    """``<category>_object.json`` in the category's weights folder (``ancsh/weights/`` for the built-in ones)."""
    from ..network.weights import weights_dir

    return weights_dir(category) / f"{category}_object.json"


def planar_share(points, tolerance: float, rng=0, trials: int = 64) -> float:
    """The largest share of ``points`` (N, 3) within ``tolerance`` metres of one plane (RANSAC over ``trials`` triples)."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) < 3:
        return 1.0
    rng = np.random.default_rng(rng)
    a, b, c = np.moveaxis(p[np.array([rng.choice(len(p), 3, replace=False) for _ in range(trials)])], 1, 0)
    n = np.cross(b - a, c - a)  # (trials, 3) each: every triple's plane at once
    length = np.linalg.norm(n, axis=1)
    ok = length >= 1e-12  # a degenerate triple (collinear points) has no plane
    if not ok.any():
        return 0.0
    n = n[ok] / length[ok, None]
    distances = np.abs(p @ n.T - np.einsum("ij,ij->i", a[ok], n))  # (N, planes)
    return int(np.count_nonzero(distances < tolerance, axis=0).max()) / len(p)


def object_features(comparison, diagonal: float, quality, typical_size: float, points=None) -> np.ndarray:
    """``(len(OBJECT_FEATURES),)`` float64 from a :class:`~ancsh.solvers.render_compare.DepthComparison` (aligned:
    :func:`ancsh.solvers.render_compare.aligned_comparison`; its ``shift_m`` gives ``shift_rel``), the fitted
    object's diagonal (metres), the fit's per-part quality (NaN entries count as worst), the category's typical
    diagonal (metres) and the observed points ``(N, 3)`` (camera frame, metres; without them ``planar_share`` counts
    as 1)."""
    size = _size(typical_size)
    base = fit_features(quality, size)

    def clean(x, worst):
        return float(x) if x is not None and np.isfinite(x) else worst

    ratio = float(np.log(max(diagonal, 1e-6) / size))
    flat = 1.0 if points is None else planar_share(points, max(0.01, PLANE_TOLERANCE * diagonal))
    scale = max(diagonal, 1e-6)
    return np.array([clean(comparison.explained, 0.0), clean(comparison.see_through, 1.0),
                     min(clean(comparison.median_abs_residual_m, size) / scale, 1.0),
                     min(abs(clean(comparison.shift_m, 0.0)) / scale, 1.0), ratio, abs(ratio), base[0], base[3], flat])
