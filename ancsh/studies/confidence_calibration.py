"""``ancsh calibrate``: collect rendered held-out frames, fit the confidence model, measure its reliability, report.

The model itself (features, applying it) is :mod:`ancsh.learned.inference.confidence`; this study makes it: a
logistic regression (scikit-learn) from the fit's evidence to P(good fit), trained on rendered frames of the
held-out instances drawn from a seed stream other than the evaluation's (:func:`collect`), its reliability
measured on a separate half of them (:func:`reliability`, :func:`write_report`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..learned.inference.confidence import FEATURES, GOOD_ROTATION_DEG, fit_features, probability_good
from .report import save_figure, write_text

__all__ = ["choose_calibrator", "collect", "constant_calibrator", "fit_calibrator", "reliability", "standardised_logistic",
           "write_report"]


def collect(category: str, frames: int, *, seed: int = 7, provider=None, progress: bool = True) -> dict:
    """Features and labels of ``frames`` rendered held-out frames (test split, base seed ``seed``), each fitted
    and refined as ``ancsh predict`` does (the provider's ``refine`` option; a provider made here: ``"auto"``).

    Returns ``{"X": (F, D), "good": (F,) bool, "rot_deg": (F,) worst part rotation error (inf when the fit failed)}``.
    """
    from tqdm import tqdm

    from ..data.generate import FrameGenerator, GenerationConfig
    from ..evaluation import evaluate_fit
    from ..learned.inference.predict import infer, part_quality
    from ..learned.inference.provider import LearnedProvider, apply_refinement
    from ..solvers import Observation, fit

    if isinstance(frames, bool) or int(frames) != frames or frames < 4:
        raise ValueError(f"frames: expected an integer >= 4, got {frames!r}")
    provider = provider or LearnedProvider(category, seed=seed, refine="auto")
    gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=seed))
    X, rot = [], []
    for i in tqdm(range(int(frames)), desc=f"calibrate {category}", disable=not progress, dynamic_ncols=True):
        frame = gen.frame(i)
        obs = Observation(frame.points)
        corr, raw = infer(provider, obs)
        refined = apply_refinement(provider, obs, corr, raw, fit(obs, corr, "exact_reduced", rng=i), rng=i)
        result = refined.result
        X.append(fit_features(part_quality(result, frame.points, refined.correspondences, refined.prediction), category))
        rec = evaluate_fit(result, frame.gt)
        rec = rec.to_dict() if hasattr(rec, "to_dict") else rec  # a dict, or a dataclass with to_dict()
        rot.append(max((p["rot_deg"] for p in rec["parts"]), default=np.inf) if rec["ok"] else np.inf)
    rot = np.asarray(rot)
    return {"X": np.asarray(X), "good": rot < GOOD_ROTATION_DEG, "rot_deg": rot}


def standardised_logistic(X, y, *, balanced: bool = False) -> dict:
    """A logistic regression (scikit-learn) of ``y`` on ``X`` standardised per feature, as plain JSON numbers
    ``{"mean", "scale", "coef", "intercept"}`` (:func:`~ancsh.learned.inference.confidence.probability_good` applies
    it); ``balanced`` weighs both outcomes equally."""
    from sklearn.linear_model import LogisticRegression

    X = np.asarray(X, dtype=np.float64)
    mean, scale = X.mean(axis=0), X.std(axis=0)
    scale[scale == 0] = 1.0
    model = LogisticRegression(C=1.0, max_iter=2000, class_weight="balanced" if balanced else None)
    model.fit((X - mean) / scale, np.asarray(y, dtype=bool))
    return {"mean": mean.tolist(), "scale": scale.tolist(), "coef": model.coef_[0].tolist(),
            "intercept": float(model.intercept_[0])}


def fit_calibrator(X, good) -> dict:
    """Standardised logistic regression (scikit-learn) of ``good`` on ``X``, as plain JSON numbers."""
    y = np.asarray(good, dtype=bool)
    if y.all() or not y.any():
        raise ValueError("good: both good and bad fits are needed to calibrate")
    return {"features": list(FEATURES), "good_rotation_deg": GOOD_ROTATION_DEG, **standardised_logistic(X, y),
            "frames": int(len(y)), "good_rate": float(y.mean())}


def constant_calibrator(good) -> dict:
    """The calibration that says only the base rate: ``P(good)`` = the good fits' share of ``good`` for every fit
    (:func:`fit_calibrator`'s format, zero coefficients). Where every fit is good (or every one bad), the
    share is estimated with one pseudo-fit of each kind, ``(k + 1) / (n + 2)`` (Laplace's rule): a finite
    logit, not a certainty that ``n`` frames cannot give."""
    y = np.asarray(good, dtype=bool)
    if y.size == 0:
        raise ValueError("good: no fits to calibrate")
    k, n = int(y.sum()), int(y.size)
    rate = float(y.mean()) if 0 < k < n else (k + 1.0) / (n + 2.0)
    d = len(FEATURES)
    return {"features": list(FEATURES), "good_rotation_deg": GOOD_ROTATION_DEG, "mean": [0.0] * d, "scale": [1.0] * d,
            "coef": [0.0] * d, "intercept": float(np.log(rate / (1.0 - rate))), "frames": int(len(y)),
            "good_rate": rate, "model": "constant"}


#: Fit frames of each outcome (good and bad) a logistic regression needs at least: one per feature.
MIN_FRAMES_PER_OUTCOME = len(FEATURES)


def choose_calibrator(X_fit, good_fit, X_check, good_check) -> tuple[dict, dict]:
    """The logistic regression of ``(X_fit, good_fit)`` where it beats the constant base rate on the check frames,
    else that constant.

    Both are fitted on the fit frames only and compared by their Brier score on the check frames: where the
    fit's evidence does not separate good from bad fits better than the base rate (e.g. 96 % good fits
    leave little to predict), a regression only adds noise to ``p_good``. Fit frames of one outcome only (every
    fit good), or fewer than :data:`MIN_FRAMES_PER_OUTCOME` of one outcome, give the constant directly
    (:func:`constant_calibrator`'s add-one rate): a regression of five features on three frames is noise.

    Returns
    -------
    (dict, dict)
        The calibration (``"model"``: ``"logistic"`` or ``"constant"``; ``"brier_check"``: both candidates'
        Brier scores on the check frames) and its :func:`reliability` on the check frames.
    """
    constant = constant_calibrator(good_fit)
    y = np.asarray(good_fit, dtype=bool)
    if min(int(y.sum()), int((~y).sum())) < MIN_FRAMES_PER_OUTCOME:  # (nearly) one outcome: nothing to separate
        rel = reliability(constant, X_check, good_check)
        return dict(constant, brier_check={"constant": rel["brier"]}), rel
    logistic = dict(fit_calibrator(X_fit, good_fit), model="logistic")
    rel = {"logistic": reliability(logistic, X_check, good_check), "constant": reliability(constant, X_check, good_check)}
    pick = "logistic" if rel["logistic"]["brier"] < rel["constant"]["brier"] else "constant"
    chosen = {"logistic": logistic, "constant": constant}[pick]
    chosen["brier_check"] = {k: r["brier"] for k, r in rel.items()}
    return chosen, rel[pick]


def reliability(calibration: dict, X, good, bins: int = 5) -> dict:
    """Reliability diagram data: per probability bin the mean predicted P and the observed good rate; Brier scores."""
    p = np.array([probability_good(calibration, x) for x in np.asarray(X)])
    y = np.asarray(good, dtype=np.float64)
    edges = np.linspace(0.0, 1.0, bins + 1)
    which = np.clip(np.digitize(p, edges[1:-1]), 0, bins - 1)
    rows = [{"lo": float(edges[b]), "hi": float(edges[b + 1]), "frames": int(np.sum(which == b)),
             "predicted": float(p[which == b].mean()) if np.any(which == b) else float("nan"),
             "observed": float(y[which == b].mean()) if np.any(which == b) else float("nan")} for b in range(bins)]
    return {"bins": rows, "brier": float(np.mean((p - y) ** 2)), "brier_constant": float(np.mean((y.mean() - y) ** 2)),
            "frames": int(len(y)), "good_rate": float(y.mean())}


def write_report(category: str, calibration: dict, rel: dict, out_dir, *, command: str) -> dict:
    """``<category>_confidence.md`` and ``_reliability.png`` in ``out_dir``; returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"md": out / f"{category}_confidence.md", "png": out / f"{category}_reliability.png",
             "json": out / f"{category}_confidence.json"}
    fig, ax = plt.subplots(figsize=(4.5, 4.5))
    pred = [b["predicted"] for b in rel["bins"] if b["frames"]]
    obs = [b["observed"] for b in rel["bins"] if b["frames"]]
    ax.plot([0, 1], [0, 1], "k--", lw=0.8, label="perfectly calibrated")
    ax.plot(pred, obs, "o-", label=f"{category} ({rel['frames']} held-out frames)")
    ax.set_xlabel(f"predicted P(every part's rotation error < {GOOD_ROTATION_DEG:g} deg)")
    ax.set_ylabel("observed fraction")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, paths["png"], dpi=90)
    plt.close(fig)
    write_text(paths["json"], json.dumps(calibration, indent=1) + "\n")
    rows = "\n".join(f"| {b['lo']:.1f}-{b['hi']:.1f} | {b['frames']} | {b['predicted']:.3f} | {b['observed']:.3f} |"
                     for b in rel["bins"])
    write_text(
        paths["md"],
        f"# {category}: how far to trust a prediction\n\nCommand: `{command}`\n\n"
        f"A logistic regression (scikit-learn) of whether every part's rotation error is below "
        f"{GOOD_ROTATION_DEG:g} deg on the fit's own evidence ({', '.join(FEATURES)}), trained on "
        f"{calibration['frames']} rendered frames of the held-out instances (seed stream 7, not the evaluation's), "
        f"measured on {rel['frames']} others. Good fits: {100 * rel['good_rate']:.0f}%.\n\n"
        f"Brier score {rel['brier']:.4f} (a constant {rel['good_rate']:.2f}: {rel['brier_constant']:.4f}).\n\n"
        + _model_sentence(calibration) +
        "| predicted P | frames | mean predicted | observed good |\n|---|---|---|---|\n" + rows + "\n\n"
        f"![reliability diagram]({paths['png'].name})\n")
    return paths


def _model_sentence(calibration: dict) -> str:
    """Which candidate :func:`choose_calibrator` kept, with both check-frame Brier scores."""
    b = calibration.get("brier_check")
    if not b:
        return ""
    if calibration.get("model") == "constant" and "logistic" not in b:
        return (f"Installed: **a constant** {calibration['good_rate']:.3f} for every fit: the fitting frames held one "
                f"outcome only, or fewer than {MIN_FRAMES_PER_OUTCOME} frames of one (no regression can separate them), "
                "so the rate is estimated with one pseudo-fit of each kind, (k + 1) / (n + 2).\n\n")
    if calibration.get("model") == "constant":
        return (f"Installed: **the constant base rate** {calibration['good_rate']:.2f} of the fitting frames for every fit. The "
                f"regression did not beat it on the check frames (Brier {b['logistic']:.4f} vs {b['constant']:.4f}): the fit's "
                "evidence does not tell this network's good fits from its bad ones better than the base rate.\n\n")
    return (f"Installed: the logistic regression (check-frame Brier {b['logistic']:.4f}, against {b['constant']:.4f} for the "
            f"fitting frames' base rate {calibration['good_rate']:.2f} as a constant).\n\n")
