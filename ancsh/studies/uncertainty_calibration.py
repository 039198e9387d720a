"""``ancsh bench uncertainty``: are the fits' standard deviations calibrated? Measure, inflate, report.

For rendered frames of each category, the oracle provider (ground truth corrupted by the
``realistic`` preset, :mod:`ancsh.solvers.providers.oracle`) and the learned provider (the shipped
weights, :class:`~ancsh.learned.inference.provider.LearnedProvider`, with the plausibility checks of
``ancsh predict``) give correspondences; the default fit (``exact_reduced``) reports raw Jacobian
covariances (:mod:`ancsh.solvers.uncertainty`). Each fitted quantity's error against the ground
truth is normalised by its covariance -- a squared Mahalanobis distance ``d^2`` with ``dof``
degrees of freedom:

- ``rotation`` (per part, 3): the camera-frame tangent ``log(R_true R_fit^T)``;
- ``translation`` (per part, 3): ``t_true - t_fit`` of ``T_cam_npcs`` (metres);
- ``scale`` (per part, 1);
- ``joint_state`` (per joint, 1): revolute differences wrapped into ``(-pi, pi]``;
- ``joint_axis`` (per joint, 2): the true unit axis (sign matched) minus the fitted one, in the
  plane perpendicular to the fitted axis;
- ``joint_pivot`` (revolute joints, 2): the true pivot minus the fitted one, perpendicular to the
  fitted axis (the distance of the true axis line, to first order).

The inflation has two measured parts: a within-part residual correlation ``rho`` per provider
and category (:attr:`ancsh.solvers.uncertainty.Inflation.correlation`: a part's ``n`` points count
as ``n / (1 + (n - 1) rho)`` independent ones, since network and warp errors do not average out
over points), chosen from :data:`CORRELATION_GRID`, and per quantity an
:class:`~ancsh.solvers.uncertainty.SigmaMap` of each fit's raw standard deviation (a single factor,
a power about a reference, or a factor with a floor; one map for all parts or joints, or one per
part or joint: :func:`fit_quantity_inflation`, :func:`fit_sigma_map`).

The truth lies "within ``k`` sigma" when ``d^2 <= chi2_dof^-1(P(|z| <= k))`` (68.27 % for ``k = 1``,
95.45 % for ``k = 2``): the one-dimensional ``k``-sigma probability carried to ``dof`` dimensions.
A map with ratio ``f = sigma' / sigma`` divides ``d^2`` by ``f^2``; per provider, category and
quantity the map minimising the larger of the two coverage gaps (and per provider and category
the correlation whose single factors leave the smallest mean gap) is measured on **calibration
frames** (the held-out test instances, frame seed stream ``--calibration-seed``, never the test
frames) and the coverage is then reported on the **test frames** (seed ``--seed``, the frames of
``ancsh evaluate``). Failed fits are counted, not scored; quantities the data left undetermined
(infinite variance) are counted, not scored.

``--install`` writes the maps to ``ancsh/weights/uncertainty_inflation.json``, which
``ancsh predict`` and ``ancsh track`` apply (:func:`ancsh.solvers.uncertainty.inflation_for`).
"""

from __future__ import annotations

import datetime
import json
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..outputs import output_flags

__all__ = ["COVERAGE_TARGETS", "CORRELATION_GRID", "QUANTITIES", "CalibrationConfig", "ErrorRecord", "coverage", "describe_sigma_map", "error_records", "merge_records",
           "fit_inflation", "fit_quantity_inflation", "fit_sigma_map", "inflated_errors", "measure", "normalised_errors",
           "raw_sigmas", "register", "run", "summarize", "write_report"]

#: Quantities and their degrees of freedom.
QUANTITIES = {"rotation": 3, "translation": 3, "scale": 1, "joint_state": 1, "joint_axis": 2, "joint_pivot": 2}
#: P(|z| <= 1), P(|z| <= 2) of a standard normal.
COVERAGE_TARGETS = (0.6826894921370859, 0.9544997361036416)
PROVIDERS = ("oracle-realistic", "learned", "learned-template")
#: What runs without ``--providers``: ``learned-template`` (the learned fits refined by the category
#: template, ICP covariances; about half a second more per frame) only when asked for.
DEFAULT_PROVIDERS = ("oracle-realistic", "learned")
#: Default calibration frames per test frame (:attr:`CalibrationConfig.calibration_frames`).
CALIBRATION_FRAMES_PER_TEST_FRAME = 2
_FACTOR_GRID = np.exp(np.linspace(np.log(0.25), np.log(200.0), 1200))


def _shipped_categories() -> tuple:
    from ..learned.network.weights import shipped_categories

    return tuple(shipped_categories())


@dataclass(frozen=True)
class CalibrationConfig:
    """What the study runs.

    Attributes
    ----------
    categories : tuple of str
        Default: every category with a shipped ANCSH network
        (:func:`ancsh.learned.network.weights.shipped_categories`), since the maps are installed per category.
    providers : tuple of str
        From :data:`PROVIDERS` (default :data:`DEFAULT_PROVIDERS`). ``learned-template``: the learned
        fits refined against the category template (:meth:`~ancsh.learned.inference.provider.LearnedProvider.refine`,
        forced on), only the frames whose refinement was accepted as the ``articulated`` candidate (the
        others keep the learned fit, which the ``learned`` row calibrates, or carry no covariance: counted
        as ``not_refined``); their covariance is the template ICP's, without a
        scale (chosen by the scale search), so they have no ``scale`` row.
    frames : int
        Test frames per category.
    calibration_frames : int or None
        Calibration frames per category; ``None``: :data:`CALIBRATION_FRAMES_PER_TEST_FRAME` times
        ``frames``. A map measured on as few frames as it is tested on carries the calibration
        frames' sampling error into the test coverage on top of the test frames' own (measured:
        laptop / learned / joint state, 150 + 150 frames, one resampled row in 16 missed the target
        by chance; with twice the calibration frames one in 100).
    seed : int
        Base seed of the test frames (``ancsh evaluate``'s stream).
    calibration_seed : int
        Base seed of the calibration frames (another stream of the held-out instances).
    formulation : str
    """

    categories: tuple = field(default_factory=lambda: _shipped_categories())
    providers: tuple = DEFAULT_PROVIDERS
    frames: int = 150
    calibration_frames: int | None = None
    seed: int = 0
    calibration_seed: int = 1001
    formulation: str = "exact_reduced"

    def __post_init__(self):
        unknown = [p for p in self.providers if p not in PROVIDERS]
        if unknown:
            raise ValueError(f"providers: unknown {unknown}; known: {list(PROVIDERS)}")
        for name in ("frames", "calibration_frames"):
            v = getattr(self, name)
            if v is None and name == "calibration_frames":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 4:
                raise ValueError(f"{name}: expected an integer >= 4, got {v!r}")

    @property
    def n_calibration(self) -> int:
        """Calibration frames per category (:attr:`calibration_frames` or its default)."""
        return int(self.calibration_frames if self.calibration_frames is not None
                   else CALIBRATION_FRAMES_PER_TEST_FRAME * self.frames)
        if self.seed == self.calibration_seed:
            raise ValueError("calibration_seed: must differ from seed (calibration frames are never test frames)")


# ------------------------------------------------------------------------------------------------
# errors normalised by the predicted covariance
# ------------------------------------------------------------------------------------------------
def _mahalanobis2(e: np.ndarray, C: np.ndarray) -> float:
    """``e^T C^-1 e``; ``nan`` when ``C`` is not finite or not positive definite."""
    if not (np.all(np.isfinite(C)) and np.all(np.isfinite(e))):
        return float("nan")
    try:
        L = np.linalg.cholesky(0.5 * (C + C.T))
    except np.linalg.LinAlgError:
        return float("nan")
    z = np.linalg.solve(L, e)
    return float(z @ z)


def _perp_basis(a: np.ndarray) -> np.ndarray:
    """``(3, 2)``: an orthonormal basis of the plane perpendicular to the unit ``a``."""
    from ..solvers.terms import perpendiculars

    u, v = perpendiculars(a / np.linalg.norm(a))
    return np.stack([u, v], axis=1)


@dataclass(frozen=True)
class ErrorRecord:
    """One fitted quantity's error against the ground truth, with what its inflation needs.

    Attributes
    ----------
    error : (dof,) float64
        The error in the quantity's coordinates (see the module docstring; radians, metres).
    covariance : (dof, dof) float64
        Its raw covariance, same coordinates.
    correlated : (dof, dof) float64
        The covariance added per unit within-part correlation
        (:attr:`~ancsh.solvers.uncertainty.FitUncertainty.correlated`).
    index : int
        The part (pose quantities) or joint (joint quantities) it belongs to.
    variance, correlated_variance : float
        The squared :func:`~ancsh.solvers.uncertainty.block_sigma` of the quantity's block as the fit
        stores it (raw, and per unit correlation): the raw ``sigma`` that
        :meth:`~ancsh.solvers.uncertainty.FitUncertainty.inflated` maps is
        ``sqrt(variance + rho correlated_variance)``.
    """

    error: np.ndarray
    covariance: np.ndarray
    correlated: np.ndarray
    variance: float
    correlated_variance: float
    index: int = 0


def _record(index, e, C, Cc, block, block_corr) -> ErrorRecord:
    from ..solvers.uncertainty import block_sigma

    return ErrorRecord(np.asarray(e, dtype=np.float64), C, Cc, float(block_sigma(block) ** 2), float(block_sigma(block_corr) ** 2),
                       int(index))


def error_records(result, gt, *, reported: bool = False) -> dict:
    """``{quantity: [ErrorRecord, ...]}`` of one fit against its ground truth: each error vector
    (``dof``,) with its raw covariance and the covariance per unit within-part correlation, in the
    same coordinates, and the block variances the inflation maps.

    Parameters
    ----------
    result : FitResult
        With :attr:`~ancsh.solvers.types.FitResult.uncertainty`.
    gt : AncshGroundTruth
    reported : bool
        Use the covariances as the fit reports them (after any inflation applied to it) instead of the
        raw ones: for checking the coverage of what a user is given.
    """
    from ..geometry.rotations import log_so3

    u = result.uncertainty if reported else result.uncertainty.raw()
    c = u.correlated if u.correlated is not None else u  # none only for "unavailable" (infinite) covariances
    out = {q: [] for q in QUANTITIES}
    for j, (T, G) in enumerate(zip(result.T_cam_npcs, gt.T_cam_npcs)):
        C, Cc = u.part_covariances[j], c.part_covariances[j]
        for q, e, sl in (("rotation", log_so3(G.rotation @ T.rotation.T), slice(0, 3)),
                         ("translation", G.translation - T.translation, slice(3, 6)),
                         ("scale", np.array([G.scale - T.scale]), slice(6, 7))):
            out[q].append(_record(j, e, C[sl, sl], Cc[sl, sl], C[sl, sl], Cc[sl, sl]))
    for k in range(len(result.joint_states)):
        revolute = str(getattr(gt.joint_types[k], "value", gt.joint_types[k])) == "revolute"
        d = float(gt.joint_states[k] - result.joint_states[k])
        if revolute:
            d = (d + np.pi) % (2 * np.pi) - np.pi
        sl = slice(k, k + 1)
        Cs, Css = u.joint_state_covariance[sl, sl], c.joint_state_covariance[sl, sl]
        out["joint_state"].append(_record(k, [d], Cs, Css, Cs, Css))
        a = result.joint_axes_cam[k]
        if not np.all(np.isfinite(a)):
            continue
        P = _perp_basis(a)
        g = np.asarray(gt.joint_axes_cam[k], dtype=np.float64)
        g = g if g @ a >= 0 else -g
        Ca, Cca = u.joint_axis_covariances[k], c.joint_axis_covariances[k]
        out["joint_axis"].append(_record(k, P.T @ (g - a), P.T @ Ca @ P, P.T @ Cca @ P, Ca, Cca))
        if revolute:
            e = np.asarray(gt.joint_pivots_cam[k]) - result.joint_pivots_cam[k]
            Cp, Ccp = u.joint_pivot_covariances[k], c.joint_pivot_covariances[k]
            out["joint_pivot"].append(_record(k, P.T @ e, P.T @ Cp @ P, P.T @ Ccp @ P, Cp, Ccp))
    return out


def normalised_errors(records, correlation: float = 0.0) -> np.ndarray:
    """Squared Mahalanobis distances ``e^T (C + rho C_corr)^-1 e`` of :class:`ErrorRecord` s
    (``nan`` where the covariance is infinite or degenerate)."""
    return np.array([_mahalanobis2(r.error, r.covariance + correlation * r.correlated if correlation > 0 else r.covariance)
                     for r in records])


def raw_sigmas(records, correlation: float = 0.0) -> np.ndarray:
    """The raw ``sigma`` (:func:`~ancsh.solvers.uncertainty.block_sigma`, after the correlation) of each
    :class:`ErrorRecord`: what a :class:`~ancsh.solvers.uncertainty.SigmaMap` maps (the quantity's unit)."""
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.array([r.variance + correlation * r.correlated_variance for r in records], dtype=np.float64))


def _thresholds(quantity: str, probs=COVERAGE_TARGETS) -> np.ndarray:
    from scipy.stats import chi2

    return chi2.ppf(np.asarray(probs), QUANTITIES[quantity])


def coverage(d2, quantity: str, factor: float = 1.0, probs=COVERAGE_TARGETS) -> np.ndarray:
    """Fraction of the finite ``d2`` within each probability's region after inflating the sigmas by ``factor``."""
    d2 = np.asarray(d2, dtype=np.float64)
    d2 = d2[np.isfinite(d2)]
    if not d2.size:
        return np.full(len(probs), np.nan)
    q = _thresholds(quantity, probs)
    return np.mean(d2[:, None] / factor**2 <= q[None, :], axis=0)


def _finite(d2, sigma=None):
    d2 = np.asarray(d2, dtype=np.float64)
    keep = np.isfinite(d2)
    if sigma is None:
        return d2[keep]
    sigma = np.asarray(sigma, dtype=np.float64)
    if sigma.shape != d2.shape:
        raise ValueError(f"sigma: expected the shape of d2 {d2.shape}, got {sigma.shape}")
    keep &= np.isfinite(sigma) & (sigma > 0)
    return d2[keep], sigma[keep]


def _gaps(cov: np.ndarray) -> np.ndarray:
    """``(...)`` the larger gap of ``(..., 2)`` coverages to :data:`COVERAGE_TARGETS`."""
    return np.max(np.abs(cov - np.asarray(COVERAGE_TARGETS)), axis=-1)


def _factor_scan(d2: np.ndarray, quantity: str) -> tuple:
    """``(factor, gap)``: the factor of :data:`_FACTOR_GRID` minimising the larger gap (the smallest such)."""
    q = _thresholds(quantity)
    cov = np.searchsorted(np.sort(d2), q[None, :] * _FACTOR_GRID[:, None] ** 2, side="right") / d2.size  # (F, 2)
    gap = _gaps(cov)
    i = int(np.argmin(gap))
    return float(_FACTOR_GRID[i]), float(gap[i])


def fit_inflation(d2, quantity: str) -> float:
    """The factor (on a log grid, 0.25..200) minimising the larger gap of the 1 and 2 sigma coverages to their targets."""
    d2 = _finite(d2)
    if not d2.size:
        return float("nan")
    return _factor_scan(d2, quantity)[0]


#: Powers ``p`` of :class:`~ancsh.solvers.uncertainty.SigmaMap` tried (1: the single factor).
POWER_GRID = tuple(float(v) for v in np.round(np.linspace(0.0, 3.0, 61), 3))
#: Floors ``b`` tried, as multiples of the reference ``s`` (the calibration frames' median raw sigma).
FLOOR_GRID = tuple(float(v) for v in np.exp(np.linspace(np.log(0.05), np.log(20.0), 41)))
#: A two-parameter map replaces the single factor only where it lowers the larger calibration gap by this much.
MIN_GAIN = 0.02
#: Among two-parameter maps within this much of the best calibration gap, the one nearest the single factor is kept.
GAP_TOLERANCE = 0.01
INFLATION_FORMS = ("factor", "power", "floor")


def fit_sigma_map(d2, sigma, quantity: str, forms=INFLATION_FORMS):
    """The :class:`~ancsh.solvers.uncertainty.SigmaMap` that brings the 1 and 2 sigma coverages of
    calibration errors nearest their targets.

    Each form is fitted on grids: ``"factor"`` (``k`` alone, :func:`fit_inflation`), ``"power"``
    (``p`` of :data:`POWER_GRID` with ``s`` the median raw ``sigma``, then ``k``) and ``"floor"``
    (``b / s`` of :data:`FLOOR_GRID`, then ``k``), each minimising the larger of the two gaps. A
    two-parameter form is kept only when its gap is at least :data:`MIN_GAIN` below the single
    factor's; among its parameters within :data:`GAP_TOLERANCE` of its best gap, the one nearest the
    single factor (``p`` nearest 1, the smallest floor) -- two levels can always be matched on the
    calibration frames, so the extra parameter must earn its place.

    Parameters
    ----------
    d2 : (N,) float64
        Squared Mahalanobis distances of the errors under the raw covariances (after the correlation).
    sigma : (N,) float64
        The fits' raw ``sigma`` (:func:`raw_sigmas`, the quantity's unit).
    quantity : str
        From :data:`QUANTITIES` (its degrees of freedom).
    forms : tuple of str
        From :data:`INFLATION_FORMS`; ``"factor"`` is always tried.

    Returns
    -------
    (SigmaMap, str, dict)
        The map, its form, and ``{form: calibration gap}`` of every form tried; ``(None, None, {})``
        without finite errors.
    """
    from ..solvers.uncertainty import SigmaMap

    unknown = [f for f in forms if f not in INFLATION_FORMS]
    if unknown:
        raise ValueError(f"forms: unknown {unknown}; known: {list(INFLATION_FORMS)}")
    d2, sigma = _finite(d2, sigma)
    if not d2.size:
        return None, None, {}
    k, gap = _factor_scan(d2, quantity)
    best = (SigmaMap(factor=k), "factor", gap)
    gaps = {"factor": gap}
    s = float(np.exp(np.median(np.log(sigma))))
    x2 = (sigma / s) ** 2
    q = _thresholds(quantity)
    if "power" in forms:
        cands = []
        for p in POWER_GRID:
            kp, g = _factor_scan(d2 * x2 ** (1.0 - p), quantity)  # d2 / ratio^2 = d2 x^(2 - 2p) / k^2
            cands.append((g, abs(p - 1.0), SigmaMap(factor=kp, power=p, reference=s)))
        best = _keep(best, cands, "power", gaps)
    if "floor" in forms:
        cands = []
        k2 = _FACTOR_GRID**2
        for beta in FLOOR_GRID:  # d2 / ratio^2 = d2 x^2 / (k^2 x^2 + beta^2) <= q  <=>  d2 / q - beta^2 / x^2 <= k^2
            cov = np.stack([np.searchsorted(np.sort(d2 / ql - beta**2 / x2), k2, side="right") for ql in q], axis=1) / d2.size
            g = _gaps(cov)
            i = int(np.argmin(g))
            cands.append((float(g[i]), beta, SigmaMap(factor=float(_FACTOR_GRID[i]), reference=s, floor=beta * s)))
        best = _keep(best, cands, "floor", gaps)
    return best[0], best[1], gaps


def _keep(best: tuple, cands: list, form: str, gaps: dict) -> tuple:
    """``best`` or the candidate of ``form`` (``(gap, distance from the single factor, map)``) that replaces it."""
    g_min = min(c[0] for c in cands)
    gaps[form] = g_min
    g, _, m = min((c for c in cands if c[0] <= g_min + GAP_TOLERANCE), key=lambda c: (c[1], c[0]))
    if g <= gaps["factor"] - MIN_GAIN and g < best[2]:
        return m, form, g
    return best


def inflated_errors(d2, sigma, sigma_map, index=None) -> np.ndarray:
    """``d2`` under the covariances inflated by ``sigma_map`` (:meth:`SigmaMap.ratio` of each raw ``sigma``);
    a tuple of maps is indexed by each error's part or joint ``index`` (``(N,)`` ints)."""
    d2, sigma = np.asarray(d2, dtype=np.float64), np.asarray(sigma, dtype=np.float64)
    if not isinstance(sigma_map, tuple):
        return d2 / sigma_map.ratio(sigma) ** 2
    index = np.asarray(index, dtype=int)
    ratio = np.ones_like(sigma)
    for i, m in enumerate(sigma_map):
        ratio[index == i] = m.ratio(sigma[index == i])
    return d2 / ratio**2


#: Per-part (per-joint) maps are fitted only where every part (joint) has at least this many calibration errors.
MIN_RECORDS_PER_INDEX = 40


def fit_quantity_inflation(records, quantity: str, correlation: float, forms=INFLATION_FORMS, per_index: str = "auto"):
    """The inflation of one quantity from calibration :class:`ErrorRecord` s: one :class:`SigmaMap`
    for all parts (joints), or one per part (joint).

    The parts of an object can be calibrated very differently (the learned translations of a washing
    machine's door are about eight times more over-confident than its body's), and pooling them makes
    the normalised errors a mixture of scales that no single map fits at both levels. With
    ``per_index="auto"`` a map per part (joint), each from :func:`fit_sigma_map`, replaces the pooled
    one when every part has :data:`MIN_RECORDS_PER_INDEX` errors and the pooled calibration gap
    drops by :data:`MIN_GAIN`; ``"always"`` / ``"never"`` force the choice (where possible).

    Returns
    -------
    (SigmaMap or tuple of SigmaMap, str, dict)
        The map(s) (``None`` without finite errors), the form(s) (``"power"``, ``"per part: factor, floor"``, ...)
        and ``{"pooled": gap, "per_index": gap, form: gap, ...}`` on the calibration frames.
    """
    if per_index not in ("auto", "always", "never"):
        raise ValueError(f"per_index: expected 'auto', 'always' or 'never', got {per_index!r}")
    d2, sigma = normalised_errors(records, correlation), raw_sigmas(records, correlation)
    index = np.array([r.index for r in records], dtype=int)
    m, form, gaps = fit_sigma_map(d2, sigma, quantity, forms)
    if m is None:
        return None, None, {}
    pooled = _gaps(coverage(inflated_errors(d2, sigma, m), quantity))
    gaps = {**gaps, "pooled": float(pooled)}
    count = int(index.max()) + 1 if index.size else 0
    enough = count > 1 and all(np.sum(np.isfinite(d2[index == i])) >= MIN_RECORDS_PER_INDEX for i in range(count))
    if per_index == "never" or not enough:
        return m, form, gaps
    fits = [fit_sigma_map(d2[index == i], sigma[index == i], quantity, forms) for i in range(count)]
    maps = tuple(f[0] for f in fits)
    split = float(_gaps(coverage(inflated_errors(d2, sigma, maps, index), quantity)))
    gaps["per_index"] = split
    if per_index == "always" or split <= pooled - MIN_GAIN:
        label = "per joint" if quantity.startswith("joint") else "per part"
        return maps, f"{label}: " + ", ".join(f[1] for f in fits), gaps
    return m, form, gaps


# ------------------------------------------------------------------------------------------------
# measuring
# ------------------------------------------------------------------------------------------------
def measure(config: CalibrationConfig, *, progress=None) -> dict:
    """Normalised errors of every (category, provider, split) and the fits' costs.

    Returns
    -------
    dict
        ``{"records": {category: {provider: {split: {quantity: [(e, C, C_corr), ...]}}}}, "counts": ...,
        "timing": {provider: {"fit_ms": [...], "fit_ms_without": [...], "covariance_ms": [...]}}}``.
    """
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..solvers import FitConfig, Observation, fit
    from .fit import _limits  # joint limits relative to rest, as the fit benchmark passes them
    from ..solvers.providers.oracle import OracleProvider

    records, counts = {}, {}
    timing = {p: {"fit_ms": [], "fit_ms_without": [], "covariance_ms": []} for p in config.providers}
    no_uncertainty = FitConfig(uncertainty=False)
    for cat in config.categories:
        learned = None
        if {"learned", "learned-template"} & set(config.providers):
            from ..learned.inference.provider import LearnedProvider

            learned = LearnedProvider(cat, seed=config.seed, num_threads=1)
        records[cat] = {p: {} for p in config.providers}
        counts[cat] = {p: {} for p in config.providers}
        for split, seed, n_frames in (("calibration", config.calibration_seed, config.n_calibration),
                                      ("test", config.seed, config.frames)):
            gen = FrameGenerator(GenerationConfig(category=cat, split="test", seed=seed))
            for p in config.providers:
                records[cat][p][split] = {q: [] for q in QUANTITIES}
                counts[cat][p][split] = {"frames": 0, "failed": 0, "singular": 0}
                if p == "learned-template":
                    counts[cat][p][split]["not_refined"] = 0
            t0 = time.perf_counter()
            for i in range(n_frames):
                frame = gen.frame(i)
                model, _ = gen.instance(frame.instance_index)
                obs = Observation(frame.points)
                inferred = None  # the network's output, shared by the learned providers of this frame
                for p in config.providers:
                    rng = np.random.default_rng([seed, i, 17])
                    if p.startswith("learned"):
                        from ..learned.inference.predict import check_plausibility, infer, part_quality

                        inferred = infer(learned, obs) if inferred is None else inferred
                        corr, raw = inferred
                    else:
                        corr = OracleProvider(frame.gt, p.split("-", 1)[1], rng, joint_limits=_limits(model)).correspond(obs)
                    result = fit(obs, corr, config.formulation, rng=i)
                    if p == "learned-template" and result.ok:
                        refined = learned.refine(obs, corr, result, refine="template", rng=i)
                        if not refined.accepted or refined.result.uncertainty is None:  # kept the input, or base
                            counts[cat][p][split]["not_refined"] += 1
                            continue
                        result = refined.result
                    if p.startswith("learned"):
                        result = check_plausibility(result, corr.part_labels, cat, part_quality(result, frame.points, corr, raw))
                    if split == "test":
                        ref = fit(obs, corr, config.formulation, config=no_uncertainty, rng=i)
                        timing[p]["fit_ms"].append(1e3 * result.time_s)
                        timing[p]["fit_ms_without"].append(1e3 * ref.time_s)
                        if result.uncertainty is not None:
                            timing[p]["covariance_ms"].append(1e3 * result.uncertainty.time_s)
                    c = counts[cat][p][split]
                    c["frames"] += 1
                    if not result.ok or result.uncertainty is None:
                        c["failed"] += 1
                        continue
                    if result.uncertainty.status != "ok":
                        c["singular"] += 1
                    with np.errstate(invalid="ignore"):  # an unbounded (inf) variance makes nan records, left out
                        per_quantity = error_records(result, frame.gt)
                    for q, v in per_quantity.items():
                        if p == "learned-template" and q == "scale":
                            continue  # not estimated: chosen by the scale search (variance nan)
                        records[cat][p][split][q] += v
            if progress is not None:
                progress(f"{cat} {split}: {n_frames} frames in {time.perf_counter() - t0:.0f} s")
    return {"records": records, "counts": counts, "timing": timing}


_RECORD_FIELDS = ("error", "covariance", "correlated", "variance", "correlated_variance", "index")


def save_records(measured: dict, path) -> Path:
    """Write :func:`measure`'s output to ``path`` (``.npz``: per category, provider, split and quantity the
    arrays of its :class:`ErrorRecord` fields; counts and timing as JSON), so that inflation maps can be
    compared without fitting the frames again (:func:`load_records`)."""
    arrays = {"meta": np.array(json.dumps({"counts": measured["counts"], "timing": measured["timing"],
                                           "source": measured.get("source")}))}
    for cat, per in measured["records"].items():
        for p, splits in per.items():
            for split, qs in splits.items():
                for q, recs in qs.items():
                    dof = QUANTITIES[q]
                    for f in _RECORD_FIELDS:
                        shape = {"error": (0, dof), "covariance": (0, dof, dof), "correlated": (0, dof, dof)}.get(f, (0,))
                        v = np.array([getattr(r, f) for r in recs]) if recs else np.zeros(shape)
                        arrays[f"{cat}/{p}/{split}/{q}/{f}"] = v
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)
    return path


def load_records(path) -> dict:
    """:func:`measure`'s output from :func:`save_records`' file.

    Raises
    ------
    ValueError
        When ``path`` is missing or not such a file (naming it).
    """
    try:
        data = np.load(Path(path), allow_pickle=False)
        meta = json.loads(str(data["meta"]))
    except (OSError, KeyError, ValueError) as exc:
        raise ValueError(f"{path}: not a records file of ancsh bench uncertainty --save-records ({exc})") from exc
    records = {}
    for key in data.files:
        if key == "meta" or not key.endswith("/index"):
            continue
        cat, p, split, q, _ = key.split("/")
        cols = [data[f"{cat}/{p}/{split}/{q}/{f}"] for f in _RECORD_FIELDS]
        recs = [ErrorRecord(cols[0][i], cols[1][i], cols[2][i], float(cols[3][i]), float(cols[4][i]), int(cols[5][i]))
                for i in range(len(cols[5]))]
        records.setdefault(cat, {}).setdefault(p, {}).setdefault(split, {})[q] = recs
    out = {"records": records, "counts": meta["counts"], "timing": meta["timing"]}
    if meta.get("source"):
        out["source"] = meta["source"]  # the command that fitted the frames, and its time
    return out



def merge_records(parts: list) -> dict:
    """One :func:`measure` output from several (:func:`load_records` of files measured separately).

    Categories are independent in the study (their own frames, correlation and maps), so the runs of
    different categories combine; a category held by several parts is taken from the last one (a
    category re-measured, e.g. for new weights). Counts follow the records; the fit timings (per
    provider, not per category) are pooled over every part's frames, a replaced category's included.
    ``source`` lists each part's command.
    """
    if not parts:
        raise ValueError("parts: expected at least one measured set")
    records, counts, timing, sources = {}, {}, {}, []
    for m in parts:
        records.update(m["records"])
        counts.update(m["counts"])
        for prov, t in m["timing"].items():
            for key, v in t.items():
                timing.setdefault(prov, {}).setdefault(key, []).extend(v)
        src = m.get("source")
        sources += src if isinstance(src, list) else [src] if src else []
    out = {"records": records, "counts": counts, "timing": timing}
    if sources:
        out["source"] = sources[0] if len(sources) == 1 else sources
    return out

#: Within-part residual correlations tried (per provider and category).
CORRELATION_GRID = (0.0, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)
#: The quantities whose coverage chooses the correlation.
MAIN_QUANTITIES = ("rotation", "translation", "joint_state")


def summarize(measured: dict, forms=INFLATION_FORMS, per_index: str = "auto") -> dict:
    """Per provider and category the within-part correlation and per quantity the inflation map, both
    from the calibration frames, and the test coverage before (raw) and after them.

    The correlation is the one of :data:`CORRELATION_GRID` whose single factors leave the smallest
    mean coverage gap over :data:`MAIN_QUANTITIES` on the calibration frames; then per quantity
    :func:`fit_quantity_inflation` chooses the map(s) among ``forms`` (``per_index`` as there).

    Returns
    -------
    dict
        ``{"rows": [{category, provider, quantity, n_calibration, n_test, correlation, form, sigma_map,
        calibration_gaps, raw (2,), inflated (2,), calibration_inflated (2,)}], "factors": {provider:
        {category: {quantity: SigmaMap.to_json() or a list of them per part / joint, "correlation": rho}}},
        "d2": {category: {provider: {quantity: (raw test d2, inflated test d2)}}}}``.
    """
    from ..solvers.uncertainty import maps_to_json

    rows, factors, d2_out = [], {}, {}
    for cat, per_provider in measured["records"].items():
        for p, splits in per_provider.items():
            cal, test = splits["calibration"], splits["test"]
            present = [q for q in QUANTITIES if cal.get(q) and test.get(q)]
            best = None
            for rho in CORRELATION_GRID:
                gaps = [_factor_scan(d2, q)[1] for q in MAIN_QUANTITIES if q in present
                        for d2 in [_finite(normalised_errors(cal[q], rho))] if d2.size]
                score = float(np.mean(gaps)) if gaps else 0.0
                if best is None or score < best[0] - 1e-12:
                    best = (score, rho)
            rho = best[1]
            entry = factors.setdefault(p, {}).setdefault(cat, {"correlation": rho})
            for q in present:
                m, form, cal_gaps = fit_quantity_inflation(cal[q], q, rho, forms, per_index)
                if m is None:
                    continue
                entry[q] = maps_to_json(m)
                d2_cal, d2_test = normalised_errors(cal[q], rho), normalised_errors(test[q], rho)
                raw_test = normalised_errors(test[q], 0.0)
                inflated_test = inflated_errors(d2_test, raw_sigmas(test[q], rho), m, [r.index for r in test[q]])
                inflated_cal = inflated_errors(d2_cal, raw_sigmas(cal[q], rho), m, [r.index for r in cal[q]])
                d2_out.setdefault(cat, {}).setdefault(p, {})[q] = (raw_test, inflated_test)
                rows.append({
                    "category": cat, "provider": p, "quantity": q, "n_calibration": int(np.isfinite(d2_cal).sum()),
                    "n_test": int(np.isfinite(d2_test).sum()), "correlation": rho, "form": form,
                    "sigma_map": entry[q], "calibration_gaps": cal_gaps,
                    "raw": coverage(raw_test, q).tolist(), "inflated": coverage(inflated_test, q).tolist(),
                    "calibration_inflated": coverage(inflated_cal, q).tolist(),
                })
    return {"rows": rows, "factors": factors, "d2": d2_out}


# ------------------------------------------------------------------------------------------------
# report
# ------------------------------------------------------------------------------------------------
def _within(cov, tol=0.10) -> bool:
    return bool(np.all(np.abs(np.asarray(cov) - np.asarray(COVERAGE_TARGETS)) <= tol))


def reliability_plot(measured: dict, summary: dict, path) -> Path:
    """Observed vs nominal coverage on the test frames (rows: providers; columns: rotation,
    translation, joint state), raw (dashed) and inflated (solid), one colour per category."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    probs = np.linspace(0.02, 0.99, 40)
    providers = sorted({r["provider"] for r in summary["rows"]}, key=PROVIDERS.index)
    qs = ("rotation", "translation", "joint_state")
    fig, axes = plt.subplots(len(providers), len(qs), figsize=(4.2 * len(qs), 3.8 * len(providers)), squeeze=False)
    cats = list(measured["records"])
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for a, p in enumerate(providers):
        for b, q in enumerate(qs):
            ax = axes[a][b]
            ax.plot([0, 1], [0, 1], color="0.6", lw=0.8)
            for c, cat in enumerate(cats):
                pair = summary["d2"].get(cat, {}).get(p, {}).get(q)
                if pair is None:
                    continue
                raw, inflated = pair
                ent = summary["factors"][p][cat]
                col = colours[c % len(colours)]
                ax.plot(probs, coverage(raw, q, 1.0, probs), "--", color=col, lw=1)
                ax.plot(probs, coverage(inflated, q, 1.0, probs), "-", color=col, lw=1.5,
                        label=f"{cat} (rho {ent['correlation']:g}, {describe_sigma_map(ent[q])})"[:60])
            for t in COVERAGE_TARGETS:
                ax.axvline(t, color="0.85", lw=0.8)
            ax.set_title(f"{p}: {q.replace('_', ' ')}")
            ax.set_xlabel("nominal coverage")
            ax.set_ylabel("observed coverage (test frames)")
            ax.set_xlim(0, 1)
            ax.set_ylim(0, 1)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("Reliability of the fits' covariances (test frames): dashed raw, solid with the calibrated "
                 "correlation and inflation map")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def describe_sigma_map(stored, per: str = "per part") -> str:
    """A stored map (:meth:`SigmaMap.to_json`, or a list of them ``per`` part / joint) in a few characters."""
    if isinstance(stored, list):
        return f"{per}: " + "; ".join(describe_sigma_map(v) for v in stored)
    if not isinstance(stored, dict):
        return f"×{stored:.3g}"
    out = f"×{stored['factor']:.3g}"
    if stored["power"] != 1.0:
        out += f", p {stored['power']:g} (s {stored['reference']:.2g})"
    if stored["floor"] > 0.0:
        out += f", floor {stored['floor']:.2g}"
    return out


def _misses(rows) -> list:
    """Lines naming the rows that miss the target and whether the calibration frames met it."""
    miss = [r for r in rows if not _within(r["inflated"])]
    if not miss:
        return []
    out = ["Rows that miss it (calibration-frame coverage after the same inflation beside the test-frame one):", ""]
    for r in miss:
        cal = r["calibration_inflated"]
        why = ("the calibration frames met the target, the test frames differ from them" if _within(cal) else
               "no map form fits the calibration frames at both levels either")
        se = [np.sqrt(t * (1 - t) / max(r["n_test"], 1)) for t in COVERAGE_TARGETS]  # binomial, at the targets
        out.append(f"- {r['category']} / {r['provider']} / {r['quantity']}: test {_pct(r['inflated'][0])} / "
                   f"{_pct(r['inflated'][1])} %, calibration {_pct(cal[0])} / {_pct(cal[1])} % ({why}; standard error "
                   f"of a test coverage at the targets over {r['n_test']} errors: {_pct(se[0])} / {_pct(se[1])} points).")
    return out + [""]


def _frames_note(config: CalibrationConfig) -> str:
    """Why the calibration frames outnumber the test frames (when they do)."""
    if config.n_calibration <= config.frames:
        return ""
    return (f"The calibration frames are {config.n_calibration / config.frames:g} times the test frames: a map measured on "
            "as few frames as it is tested on adds its own sampling error to the test frames' (over 150 frames a "
            "coverage near 68 % has a standard error of about 4 points, near 95 % about 2, more where frames of one "
            "instance err alike); measured once by resampling 1200 laptop / learned frames, one joint-state row in 16 missed the "
            "target by chance with 150 + 150 frames, one in 100 with 300 + 150.")


def _source_note(measured: dict, command: str) -> str:
    """Where the errors came from when they were read from a records file (``--records``)."""
    src = measured.get("source")
    if isinstance(src, list):  # several records files (merge_records)
        return "; the frames were fitted by " + " and ".join(
            f"`{x['command']}` ({x['elapsed_s'] / 60:.0f} min; its categories {', '.join(x.get('categories', []))})"
            if x.get("categories") else f"`{x['command']}` ({x['elapsed_s'] / 60:.0f} min)" for x in src)
    if not src or src.get("command") == command:
        return ""
    return f"; the frames were fitted by `{src['command']}` ({src['elapsed_s'] / 60:.0f} min)"


def _pct(v) -> str:
    return "-" if v is None or not np.isfinite(v) else f"{100 * v:.0f}"


def write_report(measured: dict, summary: dict, config: CalibrationConfig, out_md, *, command: str, elapsed_s: float) -> dict:
    """Write the markdown table, the JSON records and the reliability plot beside it; returns the headline."""
    out_md = Path(out_md)
    out_md.parent.mkdir(parents=True, exist_ok=True)
    png = reliability_plot(measured, summary, out_md.with_suffix(".png"))
    rows = summary["rows"]
    target_q = ("rotation", "translation", "joint_state")
    main = [r for r in rows if r["quantity"] in target_q]
    ok_main = sum(_within(r["inflated"]) for r in main)
    ok_all = sum(_within(r["inflated"]) for r in rows)
    t = measured["timing"]
    lines = [
        "# Calibration of the fits' uncertainties",
        "",
        f"Command: `{command}` ({elapsed_s / 60:.0f} min on {platform.machine()} / {platform.python_version()}, "
        f"{datetime.date.today().isoformat()})" + _source_note(measured, command) + ".",
        "",
        f"Frames: per category {config.n_calibration} calibration frames (held-out test instances, frame seed stream "
        f"{config.calibration_seed}) and {config.frames} test frames (seed {config.seed}, the frames of `ancsh evaluate`); "
        f"formulation `{config.formulation}` with the default `FitConfig`. {_frames_note(config)} Providers: `oracle-realistic` (ground truth "
        "corrupted by the `realistic` preset) and `learned` (shipped weights, with the plausibility checks of "
        "`ancsh predict`). Each error is normalised by its predicted covariance (squared Mahalanobis distance, "
        "see `ancsh/studies/uncertainty_calibration.py`); `1σ` / `2σ`: the share of test errors inside the region of "
        "probability 68.3 % / 95.4 % (chi-square with the quantity's degrees of freedom). The inflation has two "
        "parts, both measured on the calibration frames only, then applied to the test frames: a within-part "
        "residual correlation `rho` per provider and category (a part's `n` points count as `n / (1 + (n - 1) rho)` "
        "independent ones: network and warp errors do not average out over points), and per quantity a map of each "
        "fit's raw standard deviation `σ` (the RMS per coordinate of the quantity's covariance block) to the reported "
        "one, `σ' = sqrt((k σ^p s^(1-p))² + b²)` (`ancsh.solvers.uncertainty.SigmaMap`; the block keeps its shape). "
        "Three forms are fitted, each minimising the larger of the two coverage gaps: a single factor `k` (`×k`); "
        "a power `p` about the calibration frames' median raw `σ`, `s` (`p > 1`: the fits' errors differ more than "
        "their raw `σ` say); a floor `b` (the quantity's unit). A two-parameter form replaces the factor only where "
        f"it lowers the larger calibration gap by {100 * MIN_GAIN:g} points (of its parameters within "
        f"{100 * GAP_TOLERANCE:g} point of its best, the one nearest the plain factor). Maps per part (per joint) "
        f"replace the pooled one where every part has ≥ {MIN_RECORDS_PER_INDEX} calibration errors and they lower the "
        f"pooled calibration gap by {100 * MIN_GAIN:g} points: parts of one object can be calibrated very differently, "
        "and pooled they give a mixture of scales that no single map fits at both levels.",
        "",
        f"**Target (issue 15): after inflation, 1σ / 2σ coverage within 10 points of 68 / 95 %.** Rotation, translation "
        f"and joint state: {ok_main} of {len(main)} category × provider rows meet it; all quantities: {ok_all} of {len(rows)}.",
        "",
        *_misses(rows),
        "| category | provider | quantity | n cal / test | raw 1σ / 2σ (%) | rho | inflation | inflated 1σ / 2σ (%) | within 10 pts |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['category']} | {r['provider']} | {r['quantity']} | {r['n_calibration']} / {r['n_test']} | "
            f"{_pct(r['raw'][0])} / {_pct(r['raw'][1])} | {r['correlation']:g} | "
            f"{describe_sigma_map(r['sigma_map'], 'per joint' if r['quantity'].startswith('joint') else 'per part')} | "
            f"{_pct(r['inflated'][0])} / {_pct(r['inflated'][1])} | {'yes' if _within(r['inflated']) else '**no**'} |")
    lines += ["", "Fits per split (failed: no estimate or a failed plausibility check, not scored; singular: some "
              "quantity undetermined, its errors not scored; not refined: learned-template frames whose template "
              "refinement kept the learned fit or chose the base candidate, which carries no covariance):", "",
              "| category | provider | calibration frames / failed / singular | test frames / failed / singular |",
              "|---|---|---|---|"]
    for cat, per in measured["counts"].items():
        for p, c in per.items():
            a, b = c["calibration"], c["test"]
            def frames(x):  # learned-template: the frames left to the learned fit (or without a covariance) beside
                return f"{x['frames']}" + (f" (+{x['not_refined']} not refined)" if "not_refined" in x else "")

            lines.append(f"| {cat} | {p} | {frames(a)} / {a['failed']} / {a['singular']} | "
                         f"{frames(b)} / {b['failed']} / {b['singular']} |")
    lines += ["", "## Cost of the covariance", "",
              "Mean over the test frames, the same fit run with and without `FitConfig(uncertainty=...)` in one process:", "",
              "| provider | fit with covariance (ms) | without (ms) | covariance alone (ms) |", "|---|---|---|---|"]
    for p, v in t.items():
        lines.append(f"| {p} | {np.mean(v['fit_ms']):.1f} | {np.mean(v['fit_ms_without']):.1f} | "
                     f"{np.mean(v['covariance_ms']):.2f} |")
    lines += ["", "## Inflation maps", "",
              "Stored in `ancsh/weights/uncertainty_inflation.json` (written by this command with `--install`); "
              "`ancsh predict` and `ancsh track` apply the `learned` ones to the shipped weights' fits "
              "(`ancsh.solvers.uncertainty.inflation_for`). Per quantity: a number is the single factor `k`; "
              "`{factor, power, reference, floor}` is `k, p, s, b` of the map above; a list holds one map per part "
              "(pose quantities, in the category's part order; the object pose takes the root part's) or per joint.", "",
              "```json", json.dumps(summary["factors"], indent=1, sort_keys=True), "```", "",
              f"Reliability plot: [{png.name}]({png.name})", "", f"![reliability]({png.name})", ""]
    out_md.write_text("\n".join(lines))
    payload = {"command": command, "config": {k: getattr(config, k) for k in config.__dataclass_fields__},
               "summary": {k: v for k, v in summary.items() if k != "d2"}, "counts": measured["counts"],
               "timing_ms": {p: {k: float(np.mean(v)) for k, v in d.items() if v} for p, d in t.items()}}
    out_md.with_suffix(".json").write_text(json.dumps(payload, indent=1, default=_json_default))
    return {"rows_within_main": ok_main, "rows_main": len(main), "rows_within_all": ok_all, "rows_all": len(rows)}


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    return str(o)


def install(summary: dict, config: CalibrationConfig, command: str, path=None) -> Path:
    """Write the measured maps (merged per provider and category into an existing table)."""
    from ..solvers.uncertainty import INFLATION_PATH, load_inflation_table

    path = INFLATION_PATH if path is None else Path(path)
    table = load_inflation_table(path)
    for p, per_cat in summary["factors"].items():
        if p.startswith("learned"):  # the factors hold for the network they were measured with
            from ..learned.network.weights import weights_path
            from ..outputs import file_sha256

            per_cat = {c: {**f, "weights_sha256": file_sha256(weights_path(c))} for c, f in per_cat.items()}
        table["providers"].setdefault(p, {}).update(per_cat)
        table.setdefault("commands", {})[p] = command  # what measured each provider's maps (the last run per provider)
    table["formulation"] = config.formulation
    table["command"] = command
    table["date"] = datetime.date.today().isoformat()
    table["meaning"] = ("maps of the raw Jacobian standard deviations of ancsh.solvers.uncertainty (SigmaMap: a number is "
                        "a single factor; a list holds one map per part or joint), per provider, category and quantity, "
                        "measured on calibration frames by ancsh bench uncertainty (providers *-tracked-<source>: warm tracked "
                        "frames, by ancsh bench tracking --calibration-sequences)")
    path.write_text(json.dumps(table, indent=1, sort_keys=True) + "\n")
    return path


# ------------------------------------------------------------------------------------------------
# command line
# ------------------------------------------------------------------------------------------------
def register(sub) -> None:
    """Add ``uncertainty`` to the ``ancsh bench`` sub-commands."""
    p = sub.add_parser("uncertainty", help="coverage of the fits' standard deviations; measured inflation factors")
    p.add_argument("--frames", type=int, default=150, help="test frames per category (default 150)")
    p.add_argument("--calibration-frames", type=int, default=None,
                   help=f"calibration frames per category (default {CALIBRATION_FRAMES_PER_TEST_FRAME} x --frames)")
    p.add_argument("--categories", default=None, help="comma-separated (default: every category with shipped weights)")
    p.add_argument("--providers", default=None, help=f"comma-separated from {','.join(PROVIDERS)} (default: {','.join(DEFAULT_PROVIDERS)})")
    p.add_argument("--seed", type=int, default=0, help="test frame seed (default 0, as ancsh evaluate)")
    p.add_argument("--calibration-seed", type=int, default=1001)
    p.add_argument("--out", default=None, help="markdown path (default: a fresh ancsh_results/bench-uncertainty-<time>/)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/uncertainty_calibration.md")
    p.add_argument("--install", action="store_true", help="write the maps to ancsh/weights/uncertainty_inflation.json")
    p.add_argument("--save-records", default=None, metavar="NPZ",
                   help="also write every frame's errors and raw covariances (to compare inflation maps offline)")
    p.add_argument("--records", default=None, metavar="NPZ", nargs="+",
                   help="reuse the errors of --save-records instead of fitting the frames (the same --frames, "
                        "--calibration-frames and seeds); several files combine their categories, a category in "
                        "several taken from the last")
    p.set_defaults(func=run)


def _command(args) -> str:
    parts = ["ancsh bench uncertainty", f"--frames {args.frames}"]
    if getattr(args, "calibration_frames", None) is not None:
        parts.append(f"--calibration-frames {args.calibration_frames}")
    for flag in ("categories", "providers"):
        if getattr(args, flag):
            parts.append(f"--{flag} {getattr(args, flag)}")
    if args.seed:
        parts.append(f"--seed {args.seed}")
    if args.calibration_seed != 1001:
        parts.append(f"--calibration-seed {args.calibration_seed}")
    parts += output_flags(args.out, update_docs=args.update_docs)
    if args.install:
        parts.append("--install")
    if getattr(args, "save_records", None):
        parts.append(f"--save-records {args.save_records}")
    if getattr(args, "records", None):
        parts.append("--records " + " ".join(str(r) for r in args.records))
    return " ".join(parts)


def run(args) -> int:
    from ..outputs import report_path

    kw = {"frames": args.frames, "calibration_frames": getattr(args, "calibration_frames", None), "seed": args.seed,
          "calibration_seed": args.calibration_seed}
    if args.categories:
        kw["categories"] = tuple(c.strip() for c in args.categories.split(",") if c.strip())
    if args.providers:
        kw["providers"] = tuple(c.strip() for c in args.providers.split(",") if c.strip())
    config = CalibrationConfig(**kw)
    command = _command(args)
    t0 = time.perf_counter()
    if getattr(args, "records", None):
        parts = []
        for path in args.records:
            m = load_records(path)
            held = sorted({(c[s]["frames"] + c[s].get("not_refined", 0), s)  # learned-template: refined + not
                           for per in m["counts"].values() for c in per.values() for s in c})
            want = sorted({(config.n_calibration, "calibration"), (config.frames, "test")})
            if held != want:
                raise ValueError(f"--records: {path} holds {held} frames per split, not {want} "
                                 "(pass the --frames / --calibration-frames it was measured with)")
            parts.append(m)
        taken = set()  # each file's source names the categories taken from it (the last file holding them)
        for m in reversed(parts):
            if isinstance(m.get("source"), dict):
                m["source"] = dict(m["source"], categories=sorted(set(m["records"]) - taken))
            taken |= set(m["records"])
        measured = merge_records(parts)
        if len(parts) == 1 and isinstance(measured.get("source"), dict):
            measured["source"].pop("categories", None)
        if sorted(measured["records"]) != sorted(config.categories):
            raise ValueError(f"--records: {' '.join(map(str, args.records))} hold categories "
                             f"{sorted(measured['records'])}, not {sorted(config.categories)}")
    else:
        measured = measure(config, progress=lambda s: print(s, flush=True))
        measured["source"] = {"command": command, "elapsed_s": time.perf_counter() - t0}
    if getattr(args, "save_records", None):
        print(f"wrote {save_records(measured, args.save_records)}")
    summary = summarize(measured)
    out_md = report_path(args.out, update_docs=args.update_docs, docs_name="uncertainty_calibration.md",
                         command="bench-uncertainty")
    head = write_report(measured, summary, config, out_md, command=command, elapsed_s=time.perf_counter() - t0)
    print(f"wrote {out_md}; rotation/translation/state rows within 10 points after inflation: "
          f"{head['rows_within_main']} of {head['rows_main']} (all quantities {head['rows_within_all']} of {head['rows_all']})")
    if args.install:
        print(f"installed the maps in {install(summary, config, command)}")
    return 0
