"""Errors normalised by the fits' predicted covariances, their coverage, and the fitted inflation maps."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["COVERAGE_TARGETS", "CORRELATION_GRID", "QUANTITIES", "ErrorRecord", "coverage", "error_records",
           "fit_inflation", "fit_quantity_inflation", "fit_sigma_map", "inflated_errors", "normalised_errors",
           "raw_sigmas", "summarize"]


#: Quantities and their degrees of freedom.
QUANTITIES = {"rotation": 3, "translation": 3, "scale": 1, "joint_state": 1, "joint_axis": 2, "joint_pivot": 2}
#: P(|z| <= 1), P(|z| <= 2) of a standard normal.
COVERAGE_TARGETS = (0.6826894921370859, 0.9544997361036416)
_FACTOR_GRID = np.exp(np.linspace(np.log(0.25), np.log(200.0), 1200))


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
    from ...solvers.terms import perpendiculars

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
    from ...solvers.uncertainty import block_sigma

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
    from ...geometry.rotations import log_so3

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
    from ...solvers.uncertainty import SigmaMap

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
    from ...solvers.uncertainty import maps_to_json

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
