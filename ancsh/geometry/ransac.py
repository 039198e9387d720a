"""A generic RANSAC loop (Fischler and Bolles 1981) with stratified minimal samples.

The loop knows nothing about the model: the caller supplies

- ``estimator(indices) -> model | None``: fits a model to the data at ``indices`` (a minimal
  sample, or later all inliers); ``None`` marks a degenerate sample, which is skipped;
- ``residual(model) -> (N,)``: a non-negative residual for every datum; a datum is an
  inlier when its residual is ``<= threshold``;
- optionally ``score(inliers, residuals) -> float`` (higher is better; default: the inlier
  count) and ``groups`` (N,) labels, so that a hypothesis draws ``sample_size`` data from
  *each* group (e.g. 3 correspondences per part for an articulated fit).

The number of iterations adapts to the best hypothesis so far: it stops once a sample free
of outliers has been drawn with probability ``confidence``, given the per-group inlier
ratios. :func:`fit_sim3_ransac` is the per-part Umeyama + RANSAC of NOCS built on it.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any, Callable

import numpy as np

from ._checks import as_points, check_generator, check_int
from .transforms import Sim3
from .umeyama import DegeneratePointsError, umeyama

# Rounds of "refit on all inliers, recompute inliers" after the sampling loop.
_MAX_REFITS = 5


class RansacStatus(str, Enum):
    SUCCESS = "success"
    INSUFFICIENT_DATA = "insufficient_data"  # fewer data (in some group) than sample_size
    NO_VALID_HYPOTHESIS = "no_valid_hypothesis"  # the estimator rejected every sample


@dataclass(frozen=True)
class RansacResult:
    """Outcome of :func:`ransac`.

    Attributes
    ----------
    model : object or None
        The best model (refitted on its inliers when ``refit``); ``None`` on failure.
    inliers : (N,) bool
        Inlier mask of ``model`` (all False on failure).
    num_inliers : int
        ``inliers.sum()``.
    score : float
        Score of ``model``; ``-inf`` on failure.
    residuals : (N,) float64 or None
        Residuals of ``model``; ``None`` on failure.
    num_iterations : int
        Minimal samples drawn (degenerate ones included).
    num_valid_hypotheses : int
        Samples for which the estimator returned a model.
    num_refits : int
        Accepted refits on all inliers.
    status : RansacStatus
    message : str
    """

    model: Any
    inliers: np.ndarray
    num_inliers: int
    score: float
    residuals: np.ndarray | None
    num_iterations: int
    num_valid_hypotheses: int
    num_refits: int
    status: RansacStatus
    message: str

    @property
    def success(self) -> bool:
        return self.status is RansacStatus.SUCCESS


def ransac(
    num_data: int,
    estimator: Callable[[np.ndarray], Any],
    residual: Callable[[Any], np.ndarray],
    sample_size: int,
    threshold: float,
    rng,
    *,
    groups=None,
    score: Callable[[np.ndarray, np.ndarray], float] | None = None,
    max_iterations: int = 1000,
    confidence: float = 0.99,
    refit: bool = True,
) -> RansacResult:
    """Robustly fit a model with RANSAC.

    Parameters
    ----------
    num_data : int
        Number of data ``N``; the callbacks address data by index ``0..N-1``.
    estimator : callable
        ``estimator(indices) -> model | None`` for an int array of indices; ``None`` means
        the sample is degenerate.
    residual : callable
        ``residual(model) -> (N,)`` non-negative residuals of all data.
    sample_size : int
        Minimal sample size (per group when ``groups`` is given).
    threshold : float
        Inlier threshold on the residual (``residual <= threshold``), in the residual's units.
    rng : numpy.random.Generator or int
        Source of randomness.
    groups : (N,) int, optional
        Group labels; every hypothesis draws ``sample_size`` distinct data from each distinct
        label, passed to ``estimator`` group by group in ascending label order.
    score : callable, optional
        ``score(inliers (N,) bool, residuals (N,)) -> float``, higher is better; default the
        inlier count. See :func:`mean_group_inlier_ratio`.
    max_iterations : int
        Upper bound on the number of minimal samples.
    confidence : float
        In ``(0, 1]``: stop once an all-inlier sample has been drawn with this probability
        (estimated from the best hypothesis' inlier ratios); 1 runs ``max_iterations``.
    refit : bool
        Refit the best model on all its inliers (repeated while the inlier set changes),
        keeping a refit only if its score is not lower.

    Returns
    -------
    RansacResult
        With ``status`` ``INSUFFICIENT_DATA`` or ``NO_VALID_HYPOTHESIS`` (and ``model=None``)
        instead of an exception when no model can be found.
    """
    rng = check_generator(rng)
    n = _check_int(num_data, "num_data", 0)
    s = _check_int(sample_size, "sample_size", 1)
    max_iterations = _check_int(max_iterations, "max_iterations", 1)
    threshold = float(threshold)
    if not np.isfinite(threshold) or threshold < 0:
        raise ValueError(f"threshold: expected a finite non-negative number, got {threshold}")
    confidence = float(confidence)
    if not 0.0 < confidence <= 1.0:
        raise ValueError(f"confidence: expected a number in (0, 1], got {confidence}")
    for name, fn in (("estimator", estimator), ("residual", residual), ("score", score)):
        if fn is not None and not callable(fn):
            raise ValueError(f"{name}: expected a callable, got {type(fn).__name__}")
    strata = _strata(groups, n)
    score_fn = score if score is not None else _count_score

    small = [len(m) for m in strata if len(m) < s]
    if small or n == 0:
        return _failure(
            n, 0, 0, RansacStatus.INSUFFICIENT_DATA,
            f"need {s} data per group, a group has {min(small, default=0)}",
        )

    def evaluate(model):
        r = np.asarray(residual(model), dtype=np.float64)
        if r.shape != (n,):
            raise ValueError(f"residual: expected an array of shape ({n},), got {r.shape}")
        inl = r <= threshold
        return inl, r, float(score_fn(inl, r))

    best = None  # (score, model, inliers, residuals)
    needed = max_iterations
    iterations = valid = 0
    while iterations < min(needed, max_iterations):
        iterations += 1
        sample = np.concatenate([rng.choice(m, size=s, replace=False) for m in strata])
        model = estimator(sample)
        if model is None:
            continue
        valid += 1
        inl, r, sc = evaluate(model)
        if best is None or sc > best[0]:
            best = (sc, model, inl, r)
            needed = _iterations_needed(strata, inl, s, confidence, max_iterations)

    if best is None:
        return _failure(
            n, iterations, valid, RansacStatus.NO_VALID_HYPOTHESIS,
            f"the estimator rejected all {iterations} samples as degenerate",
        )

    refits = 0
    if refit:
        for _ in range(_MAX_REFITS):
            if any(np.count_nonzero(best[2][m]) < s for m in strata):
                break  # some group has too few inliers for the estimator
            model = estimator(np.flatnonzero(best[2]))
            if model is None:
                break
            inl, r, sc = evaluate(model)
            if sc < best[0]:
                break
            changed = not np.array_equal(inl, best[2])
            best = (sc, model, inl, r)
            refits += 1
            if not changed:
                break

    sc, model, inl, r = best
    return RansacResult(
        model=model,
        inliers=inl,
        num_inliers=int(inl.sum()),
        score=sc,
        residuals=r,
        num_iterations=iterations,
        num_valid_hypotheses=valid,
        num_refits=refits,
        status=RansacStatus.SUCCESS,
        message=f"{int(inl.sum())}/{n} inliers after {iterations} samples ({valid} valid)",
    )


def mean_group_inlier_ratio(groups) -> Callable[[np.ndarray, np.ndarray], float]:
    """A ``score`` for :func:`ransac`: the inlier ratio averaged over the groups.

    Unlike the inlier count, a large group cannot outvote a small one (e.g. a big base part
    against a thin eyeglasses temple).

    Parameters
    ----------
    groups : (N,) int
        Group label of each datum.
    """
    g = _labels(groups, "groups")
    _, inverse, counts = np.unique(g, return_inverse=True, return_counts=True)

    def score(inliers: np.ndarray, residuals: np.ndarray) -> float:
        if inliers.shape != g.shape:
            raise ValueError(f"inliers: expected shape {g.shape} to match groups, got {inliers.shape}")
        hits = np.bincount(inverse, weights=inliers.astype(np.float64), minlength=len(counts))
        return float(np.mean(hits / counts))

    return score


def fit_sim3_ransac(
    src,
    dst,
    threshold: float,
    rng,
    *,
    with_scale: bool = True,
    max_iterations: int = 1000,
    confidence: float = 0.99,
) -> RansacResult:
    """Umeyama inside RANSAC: a :class:`Sim3` ``T`` with ``dst ~= T @ src`` robust to outliers.

    Parameters
    ----------
    src, dst : (N, 3) float64
        Corresponding points (e.g. NPCS coordinates and camera-frame points in metres).
    threshold : float
        Inlier threshold on ``|T @ src_i - dst_i|``, in ``dst`` units.
    rng : numpy.random.Generator or int
        Source of randomness.
    with_scale, max_iterations, confidence
        As in :func:`umeyama` and :func:`ransac`.

    Returns
    -------
    RansacResult
        ``model`` is the :class:`Sim3` ``T_dst_src`` (refitted on all inliers).
    """
    src = as_points(src, "src")
    dst = as_points(dst, "dst")
    if dst.shape != src.shape:
        raise ValueError(f"dst: expected shape {src.shape} to match src, got {dst.shape}")

    def estimator(idx: np.ndarray) -> Sim3 | None:
        try:
            return umeyama(src[idx], dst[idx], with_scale=with_scale)
        except DegeneratePointsError:
            return None

    def residual(T: Sim3) -> np.ndarray:
        return np.linalg.norm(T.apply(src) - dst, axis=1)

    return ransac(
        len(src), estimator, residual, 3, threshold, rng,
        max_iterations=max_iterations, confidence=confidence,
    )


def _count_score(inliers: np.ndarray, residuals: np.ndarray) -> float:
    return float(np.count_nonzero(inliers))


def _iterations_needed(strata, inliers, s, confidence, max_iterations) -> int:
    """Samples needed to draw one all-inlier sample with probability ``confidence``."""
    if confidence >= 1.0:
        return max_iterations
    p_good = 1.0
    for m in strata:
        p_good *= (np.count_nonzero(inliers[m]) / len(m)) ** s
    if p_good >= 1.0:
        return 1
    if p_good <= 0.0:
        return max_iterations
    return int(min(max_iterations, np.ceil(np.log1p(-confidence) / np.log1p(-p_good))))


def _strata(groups, n: int) -> list[np.ndarray]:
    """Index arrays of the groups (one stratum with all data when ``groups`` is None)."""
    if groups is None:
        return [np.arange(n)]
    g = _labels(groups, "groups")
    if g.shape != (n,):
        raise ValueError(f"groups: expected shape ({n},), got {g.shape}")
    return [np.flatnonzero(g == label) for label in np.unique(g)]


def _labels(groups, name: str) -> np.ndarray:
    g = np.asarray(groups)
    if g.ndim != 1 or not np.issubdtype(g.dtype, np.integer):
        raise ValueError(f"{name}: expected a 1-D integer array, got dtype {g.dtype} and shape {g.shape}")
    return g


def _check_int(value, name: str, minimum: int) -> int:
    return check_int(value, name, minimum=minimum)


def _failure(n: int, iterations: int, valid: int, status: RansacStatus, message: str) -> RansacResult:
    return RansacResult(
        model=None,
        inliers=np.zeros(n, dtype=bool),
        num_inliers=0,
        score=float("-inf"),
        residuals=None,
        num_iterations=iterations,
        num_valid_hypotheses=valid,
        num_refits=0,
        status=status,
        message=message,
    )
