"""``ancsh calibrate``: collect good and bad fits, fit the confidence model, measure its reliability, report.

The model itself (features, applying it) is :mod:`ancsh.learned.inference.confidence`; this study makes it: a
logistic regression (scikit-learn) from the fit's evidence to P(good fit) (every part's rotation error below
:data:`~ancsh.learned.inference.confidence.GOOD_ROTATION_DEG`), trained on the fits of a seeded mix of cases
(:func:`collect`), its reliability measured on a separate half of them (:func:`fitting_half`, :func:`reliability`,
:func:`write_report`).

Rendered held-out frames alone are nearly all good fits (96-100 % for most categories): a calibration fitted on them
was the constant 0.99 whatever the fit, and said so for an oven fitted to a frame without one. So the examples
are drawn, frame ``i`` of ``SOURCES[i % len(SOURCES)]``, from test frame ``i`` of the category's held-out instances
(generator seed 7 by default, a stream other than ``ancsh evaluate``'s) and the random stream ``(seed, i, category)``:

- ``plain`` (3 in 8): the noisy rendered frame, the object's pixels as the mask (``ancsh predict --mask``);
- ``scene`` (1 in 8): the frame in a stress scene (:func:`ancsh.data.scenes.render_scene` with the kinds of
  :data:`ancsh.studies.stress_scenes.KINDS` in turn: companions of the category, a translucent one, alone; a floor or
  stairs, a wall, clutter; sensor noise), isolated without a mask as ``ancsh predict`` does: every candidate segment
  it would verify is fitted, and judged against the object holding :data:`SCENE_OBJECT_SHARE` of its pixels (none:
  bad);
- ``crop`` (1 in 8): a :data:`CROP_KEEP` share of the object's pixels, one side of a random line (judged against the
  whole object);
- ``perturbed`` (1 in 8): the frame with the network's output made confidently wrong (one part's NPCS coordinates
  turned by :data:`PERTURB_ROTATION_DEG`, a :data:`PERTURB_SHARE` share of all points' swapped);
- ``merged`` (1 in 8): the frame in a scene, its mask grown over the floor, wall and clutter around it
  (:data:`MERGE_GROW`);
- ``other`` (1 in 8): a held-out frame of another category (in turn), fitted with this category's network: bad.

Each segment is fitted as ``ancsh predict --mask`` does (one hypothesis, ``--refine auto``); only the fits that pass
their checks are examples (``predict`` reports ``p_good`` for those), the others are counted. Whole cycles of the
sources alternate between the fitting and the check half. A constant model (every coefficient 0) is refused
(:func:`check_informative`), and so are fewer than :data:`MIN_FRAMES` frames or fewer than
:data:`MIN_FRAMES_PER_OUTCOME` good or bad fits in a half; where the regression does not beat the fitting half's
base rate on the check half the report says so.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..learned.inference.confidence import FEATURES, GOOD_ROTATION_DEG, fit_features, probability_good
from .report import save_figure, write_text

__all__ = ["MIN_FRAMES", "MIN_FRAMES_PER_OUTCOME", "SOURCES", "auc", "calibrate_and_check", "check_informative", "collect",
           "constant_calibrator", "fit_calibrator", "fitting_half", "reliability", "source_table", "standardised_logistic",
           "write_report"]


#: The examples' sources, in turn over the frames (frame ``i`` is of ``SOURCES[i % len(SOURCES)]``; module docstring).
SOURCES = ("plain", "scene", "crop", "plain", "perturbed", "merged", "other", "plain")
#: Fits of each outcome (good and bad) in each half a logistic regression needs at least: one per feature.
MIN_FRAMES_PER_OUTCOME = len(FEATURES)
#: ``calibrate`` refuses fewer frames than this (with or without ``--install``): four cycles of :data:`SOURCES` in each
#: half (half fit the model, half check it); each half then needs :data:`MIN_FRAMES_PER_OUTCOME` good and bad fits,
#: counted after the fits (a cycle gave 3-6 bad ones at 800 frames: the laptop 3, the box 6).
MIN_FRAMES = 8 * len(SOURCES)
#: A crop keeps this range of shares of the object's pixels (one side of a random line through them).
CROP_KEEP = (0.3, 0.7)
#: A merged segment is the object's pixels plus every measured pixel of the scene in its box grown by this range of
#: factors about its centre (floor, wall, stairs and clutter beside the object).
MERGE_GROW = (1.3, 2.0)
#: A perturbed network output has one part's NPCS coordinates turned by an angle in this range (degrees) ...
PERTURB_ROTATION_DEG = (10.0, 90.0)
#: ... and this range of shares of all its points' NPCS coordinates swapped for other points'.
PERTURB_SHARE = (0.0, 0.3)
#: A scene's candidate segment is judged against the object that holds this share of its pixels (none: no object, a bad
#: fit); a piece of an object is judged against the whole object's pose.
SCENE_OBJECT_SHARE = 0.5
#: Stream tag of the examples' random draws (scenes, crops, perturbations), apart from the frame generator's.
_STREAM = 0xCA1B


def _min_frames_error(frames) -> None:
    """Raise ``ValueError`` naming ``frames`` where it is no integer of at least :data:`MIN_FRAMES`."""
    if isinstance(frames, bool) or int(frames) != frames or frames < MIN_FRAMES:
        raise ValueError(f"frames: expected an integer >= {MIN_FRAMES} (half fit, half check, each half with "
                         f"{MIN_FRAMES_PER_OUTCOME} good and bad fits), got {frames!r}")


class _CorruptedProvider:
    """A provider whose correspondences are confidently wrong (every other attribute is the wrapped provider's): one
    random part's NPCS coordinates turned by a :data:`PERTURB_ROTATION_DEG` angle about a random axis through their
    centroid (a coherent wrong canonical frame), and a :data:`PERTURB_SHARE` share of all points' coordinates swapped
    for other points' (scattered mistakes)."""

    def __init__(self, provider, rng):
        self._provider, self._rng = provider, rng

    def __getattr__(self, name):
        return getattr(self._provider, name)

    def infer(self, observation, **kwargs):
        import dataclasses

        from ..geometry.rotations import axis_angle_matrix

        inference = self._provider.infer(observation, **kwargs)
        corr, rng = inference.correspondences, self._rng
        npcs = np.array(corr.npcs, dtype=np.float64, copy=True)
        labels = np.asarray(corr.part_labels)
        part = rng.choice(np.unique(labels))
        axis = rng.normal(size=3)
        R = axis_angle_matrix(axis / np.linalg.norm(axis), np.radians(rng.uniform(*PERTURB_ROTATION_DEG)))
        sel = labels == part
        centre = npcs[sel].mean(axis=0)
        npcs[sel] = (npcs[sel] - centre) @ R.T + centre
        which = rng.choice(len(npcs), size=int(round(rng.uniform(*PERTURB_SHARE) * len(npcs))), replace=False)
        npcs[which] = npcs[rng.permutation(which)]
        return dataclasses.replace(inference, correspondences=dataclasses.replace(corr, npcs=npcs))


def _crop(mask, rng) -> np.ndarray:
    """The pixels of ``mask`` (H, W) bool on one side of a random line, a :data:`CROP_KEEP` share of them."""
    v, u = np.nonzero(mask)
    angle = rng.uniform(0.0, 2 * np.pi)
    t = u * np.cos(angle) + v * np.sin(angle)
    keep = t <= np.quantile(t, rng.uniform(*CROP_KEEP)) if t.size else np.zeros(0, dtype=bool)
    out = np.zeros_like(mask, dtype=bool)
    out[v[keep], u[keep]] = True
    return out


def _grown(mask, depth, rng) -> np.ndarray:
    """``mask`` plus every measured pixel of ``depth`` in its box grown by a :data:`MERGE_GROW` factor."""
    v, u = np.nonzero(mask)
    if not v.size:
        return mask
    k = rng.uniform(*MERGE_GROW)
    cu, cv, hu, hv = (u.min() + u.max()) / 2, (v.min() + v.max()) / 2, (u.max() - u.min()) / 2, (v.max() - v.min()) / 2
    vv, uu = np.mgrid[:mask.shape[0], :mask.shape[1]]
    box = (np.abs(uu - cu) <= k * hu + 1) & (np.abs(vv - cv) <= k * hv + 1)
    return mask | (box & (depth > 0))


def _worst_rotation(result, gt) -> float:
    """The largest part rotation error (degrees) of a fit that passed its checks, ``inf`` otherwise (or without truth)."""
    from ..evaluation import evaluate_fit

    if gt is None or not result.ok:
        return float("inf")
    ev = evaluate_fit(result, gt)
    return max((p.rot_deg for p in ev.parts), default=float("inf")) if ev.ok else float("inf")


def _fits(depth, intrinsics, mask, category, provider, seed) -> dict | None:
    """``ancsh predict --mask`` on one segment (:func:`~ancsh.learned.inference.candidate.fit_candidate_refinements`,
    one hypothesis, ``--refine auto``, without the ``p_object`` gate): its candidate dict; ``None`` where the segment
    has no measured pixel (an object hidden in its scene, a sensor that lost a thin one: ``predict`` refuses the mask)."""
    from ..learned.inference.candidate import fit_candidate_refinements

    if not np.any(np.asarray(mask, dtype=bool) & (depth > 0)):
        return None

    return fit_candidate_refinements(depth, intrinsics, mask, category, provider, "exact_reduced", 1024, seed, None,
                                     ("auto",), object_gate=False)[0]


def _examples(source, i, loaded, provider, gens, key) -> list:
    """``[(candidate dict or None, truth or None), ...]``: the fits of example frame ``i`` of ``source`` (module
    docstring; ``None``: a segment without a measured pixel, counted as a failed fit); ``loaded``: the category, a
    :class:`~ancsh.learned.inference.category.Category`."""
    from ..data.noise import DepthNoise, apply_noise
    from ..data.procedural import CATEGORIES
    from ..data.scenes import render_scene
    from .stress_scenes import KINDS

    rng = np.random.default_rng(key)
    category = loaded.name
    gen = gens[category]
    turn = i // len(SOURCES) // 2  # the same scene kinds and other categories in the fitting and the check half
    if source in ("plain", "crop", "perturbed"):
        frame = gen.frame(i, keep_depth=True)
        mask = frame.depth > 0
        if source == "crop":
            mask = _crop(mask, rng)
        use = _CorruptedProvider(provider, rng) if source == "perturbed" else provider
        return [(_fits(frame.depth, frame.intrinsics, mask, loaded, use, i), frame.gt)]
    if source == "other":
        others = [c for c in CATEGORIES if c != category]
        other = others[turn % len(others)]
        frame = gens[other].frame(i, keep_depth=True)
        return [(_fits(frame.depth, frame.intrinsics, frame.depth > 0, loaded, provider, i), None)]
    if source == "merged":
        scene = render_scene(gen, i, rng)
        depth = apply_noise(scene.depth, DepthNoise(), rng)
        return [(_fits(depth, scene.intrinsics, _grown(scene.visible & (depth > 0), depth, rng), loaded, provider, i),
                 scene.frame.gt)]
    if source != "scene":
        raise ValueError(f"source: expected one of {SOURCES}, got {source!r}")
    from ..data.isolate import isolate_object
    from ..learned.inference.predict import MAX_VERIFIED

    _, companions, translucent = KINDS[turn % len(KINDS)]
    scene = render_scene(gen, i, rng, companions=companions, translucent=translucent)
    depth = apply_noise(scene.depth, DepthNoise(), rng)
    iso = isolate_object(depth, scene.intrinsics, loaded.size_range, rng=i)
    if iso.chosen is None:
        return []
    chosen = [c for c in iso.order if iso.clusters[c].fits_category][:MAX_VERIFIED] or list(iso.order[:1])
    out = []
    for c in chosen:
        mask = iso.mask_of(c)
        shares = [np.count_nonzero(mask & o.visible) / max(np.count_nonzero(mask), 1) for o in scene.objects]
        best = int(np.argmax(shares)) if shares else None
        gt = scene.objects[best].gt if best is not None and shares[best] >= SCENE_OBJECT_SHARE else None
        out.append((_fits(depth, scene.intrinsics, mask, loaded, provider, i), gt))
    return out


def collect(category: str, frames: int, *, seed: int = 7, provider=None, progress: bool = True) -> dict:
    """Features and labels of the fits of ``frames`` example frames of a seeded mix of good and hard cases, each
    segment fitted as ``ancsh predict --mask`` does (one hypothesis, ``--refine auto``; module docstring).

    Frame ``i`` is of source ``SOURCES[i % len(SOURCES)]``, drawn from test frame ``i`` of the category's held-out
    instances (base seed ``seed``, a stream other than the evaluation's) and the random stream ``(seed, i,
    category)``; a scene gives one fit per candidate segment. Only fits that pass their checks are examples (``ancsh
    predict`` reports ``p_good`` for those); the others are counted in ``failed``.

    Returns
    -------
    dict
        ``{"X": (F, D) features, "good": (F,) bool, "rot_deg": (F,) worst part rotation error (deg; inf without a
        true object), "source": [str] per fit, "frame": (F,) int the example frame of each fit, "failed": {source:
        fits}, "source_frames": {source: frames}}``.
    """
    import zlib

    from tqdm import tqdm

    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.procedural import CATEGORIES
    from ..learned.inference.category import load_category
    from ..learned.inference.provider import LearnedProvider

    _min_frames_error(frames)
    loaded = load_category(category)
    provider = provider or LearnedProvider(loaded.weights_path(), seed=seed, refine="auto", category=loaded)
    gens = {c: FrameGenerator(GenerationConfig(category=c, split="test", seed=seed)) for c in {*CATEGORIES, category}}
    X, rot, src, index, failed, counts = [], [], [], [], {}, {}
    for i in tqdm(range(int(frames)), desc=f"calibrate {category}", disable=not progress, dynamic_ncols=True):
        source = SOURCES[i % len(SOURCES)]
        counts[source] = counts.get(source, 0) + 1
        key = [int(seed), i, zlib.crc32(category.encode()), _STREAM]
        for cand, gt in _examples(source, i, loaded, provider, gens, key):
            if cand is None or not cand["result"].ok:
                failed[source] = failed.get(source, 0) + 1
                continue
            X.append(fit_features(cand["quality"], loaded.typical_size))
            rot.append(_worst_rotation(cand["result"], gt))
            src.append(source)
            index.append(i)
    rot = np.asarray(rot, dtype=np.float64)
    return {"X": np.asarray(X, dtype=np.float64).reshape(-1, len(FEATURES)), "good": rot < GOOD_ROTATION_DEG,
            "rot_deg": rot, "source": src, "frame": np.asarray(index, dtype=np.int64), "failed": failed,
            "source_frames": counts}


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
    """Standardised logistic regression (scikit-learn) of ``good`` on ``X``, as plain JSON numbers (``"model":
    "logistic"``).

    Raises
    ------
    ValueError
        Naming ``good`` where it holds fewer than :data:`MIN_FRAMES_PER_OUTCOME` good or bad fits (one per feature:
        a regression of five coefficients on three bad fits is noise; of one outcome only, nothing to separate), or
        where the fitted model is constant (:func:`check_informative`).
    """
    y = np.asarray(good, dtype=bool)
    if y.all() or not y.any():
        raise ValueError("good: both good and bad fits are needed to calibrate")
    k = min(int(y.sum()), int((~y).sum()))
    if k < MIN_FRAMES_PER_OUTCOME:
        raise ValueError(f"good: {int(y.sum())} good and {int((~y).sum())} bad fits; at least {MIN_FRAMES_PER_OUTCOME} "
                         "of each are needed to calibrate")
    calibration = {"features": list(FEATURES), "good_rotation_deg": GOOD_ROTATION_DEG, **standardised_logistic(X, y),
                   "frames": int(len(y)), "good_rate": float(y.mean()), "model": "logistic"}
    check_informative(calibration)
    return calibration


def check_informative(calibration: dict) -> None:
    """Raise ``ValueError`` where ``calibration`` is a constant model: ``"model": "constant"``, no ``coef`` or every
    coefficient 0 (it says the base rate whatever the fit: not a calibration of the fit's evidence)."""
    coef = np.asarray(calibration.get("coef", ()), dtype=np.float64)
    if calibration.get("model") == "constant" or not coef.size or not np.any(coef != 0.0):
        raise ValueError(f"calibration: a constant model (p_good {calibration.get('good_rate')} for every fit) is not a "
                         "calibration; recalibrate on frames with good and bad fits (ancsh calibrate)")


def constant_calibrator(good) -> dict:
    """The reference a calibration must beat: ``P(good)`` = the good fits' share of ``good`` for every fit
    (:func:`fit_calibrator`'s format, zero coefficients, ``"model": "constant"``; :func:`check_informative` refuses
    it, so it is measured, never installed). Where every fit is good (or every one bad), the share is estimated with
    one pseudo-fit of each kind, ``(k + 1) / (n + 2)`` (Laplace's rule): a finite logit."""
    y = np.asarray(good, dtype=bool)
    if y.size == 0:
        raise ValueError("good: no fits to calibrate")
    k, n = int(y.sum()), int(y.size)
    rate = float(y.mean()) if 0 < k < n else (k + 1.0) / (n + 2.0)
    d = len(FEATURES)
    return {"features": list(FEATURES), "good_rotation_deg": GOOD_ROTATION_DEG, "mean": [0.0] * d, "scale": [1.0] * d,
            "coef": [0.0] * d, "intercept": float(np.log(rate / (1.0 - rate))), "frames": int(len(y)),
            "good_rate": rate, "model": "constant"}


def fitting_half(frame) -> np.ndarray:
    """``(F,)`` bool: the fits of :func:`collect` (their example ``frame`` indices) that fit the model; the others check
    it. Whole cycles of :data:`SOURCES` alternate, so both halves hold every source and a scene's fits stay together."""
    return (np.asarray(frame, dtype=np.int64) // len(SOURCES)) % 2 == 0


def calibrate_and_check(X_fit, good_fit, X_check, good_check) -> tuple[dict, dict]:
    """The logistic regression of ``(X_fit, good_fit)`` and its :func:`reliability` on the check fits, beside the
    fitting fits' base rate as a constant (:func:`constant_calibrator`) measured on the same check fits.

    The regression is the result whether or not it beats the constant: ``"brier_check"`` holds both Brier scores and
    ``"auc_check"`` the regression's area under the ROC curve on the check fits, and the report says which is lower.

    Raises
    ------
    ValueError
        Naming ``good_fit`` / ``good_check`` where a half holds fewer than :data:`MIN_FRAMES_PER_OUTCOME` good or bad
        fits.
    """
    yc = np.asarray(good_check, dtype=bool)
    if min(int(yc.sum()), int((~yc).sum())) < MIN_FRAMES_PER_OUTCOME:
        raise ValueError(f"good_check: {int(yc.sum())} good and {int((~yc).sum())} bad check fits; at least "
                         f"{MIN_FRAMES_PER_OUTCOME} of each are needed to measure a calibration")
    try:
        logistic = fit_calibrator(X_fit, good_fit)
    except ValueError as e:
        raise ValueError(str(e).replace("good:", "good_fit:", 1)) from None
    rel = reliability(logistic, X_check, yc)
    constant = reliability(constant_calibrator(good_fit), X_check, yc)
    p = np.array([probability_good(logistic, x) for x in np.asarray(X_check)])
    logistic["brier_check"] = {"logistic": rel["brier"], "constant": constant["brier"]}
    logistic["auc_check"] = auc(p[yc], p[~yc])
    return logistic, rel


def auc(p_positive, p_negative) -> float:
    """The area under the ROC curve: the chance that a positive's probability exceeds a negative's (ties count
    half), threshold-free; ``nan`` without both."""
    from sklearn.metrics import roc_auc_score

    a, b = np.asarray(p_positive, dtype=np.float64), np.asarray(p_negative, dtype=np.float64)
    if not a.size or not b.size:
        return float("nan")
    return float(roc_auc_score(np.r_[np.ones(a.size), np.zeros(b.size)], np.r_[a, b]))


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


def source_table(calibration: dict, data: dict) -> list[dict]:
    """Per source of :func:`collect`'s ``data`` on its check fits (:func:`fitting_half`): example frames, fits that
    passed their checks (and those that failed them, over both halves), the good share and the mean ``p_good``."""
    check = ~fitting_half(data["frame"])
    src = np.asarray(data["source"], dtype=object)
    p = np.array([probability_good(calibration, x) for x in data["X"]])
    rows = []
    for s in dict.fromkeys(SOURCES):
        sel = check & (src == s)
        rows.append({"source": s, "frames": int(data["source_frames"].get(s, 0)), "fits": int(np.sum(src == s)),
                     "failed": int(data["failed"].get(s, 0)), "check_fits": int(sel.sum()),
                     "good": float(data["good"][sel].mean()) if sel.any() else float("nan"),
                     "p_good": float(p[sel].mean()) if sel.any() else float("nan")})
    return rows


def write_report(category: str, calibration: dict, rel: dict, out_dir, *, command: str, sources=None) -> dict:
    """``<category>_confidence.md``, ``_reliability.png`` and ``.json`` (the calibration) in ``out_dir``; ``sources``:
    :func:`source_table`'s rows (a table of them where given). Returns the paths."""
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
    ax.plot(pred, obs, "o-", label=f"{category} ({rel['frames']} check fits)")
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
    frames = f" ({calibration['example_frames']} example frames in both halves)" if "example_frames" in calibration else ""
    table = ""
    if sources:
        table = ("Per source (module docstring of `ancsh.studies.confidence_calibration`): example frames, fits that "
                 "passed their checks (`ancsh predict` reports `p_good` for those; the failed ones are counted, not "
                 "used), and on the check fits the observed good share and the mean `p_good`:\n\n"
                 "| source | frames | fits | failed checks | check fits | good | mean p_good |\n|---|---|---|---|---|---|---|\n"
                 + "\n".join(f"| {r['source']} | {r['frames']} | {r['fits']} | {r['failed']} | {r['check_fits']} | "
                             f"{r['good']:.2f} | {r['p_good']:.2f} |" for r in sources) + "\n\n")
    write_text(
        paths["md"],
        f"# {category}: how far to trust a prediction\n\nCommand: `{command}`\n\n"
        f"A logistic regression (scikit-learn) of whether every part's rotation error is below "
        f"{GOOD_ROTATION_DEG:g} deg on the fit's own evidence ({', '.join(FEATURES)}), trained on "
        f"{calibration['frames']} fits of a seeded mix of good and bad cases{frames} (rendered held-out frames, stress "
        f"scenes isolated without a mask, cropped and merged segments, perturbed network outputs, other categories' "
        f"frames; seed stream 7, not the evaluation's), measured on {rel['frames']} others. "
        f"Good fits: {100 * rel['good_rate']:.0f}% of the check fits.\n\n"
        + _model_sentence(calibration) + table +
        "| predicted P | fits | mean predicted | observed good |\n|---|---|---|---|\n" + rows + "\n\n"
        f"![reliability diagram]({paths['png'].name})\n")
    return paths


def _model_sentence(calibration: dict) -> str:
    """The check fits' Brier scores of the regression and of the base rate as a constant, and which is lower."""
    b = calibration.get("brier_check")
    if not b:
        return ""
    auc = calibration.get("auc_check")
    auc_text = "" if auc is None or not np.isfinite(auc) else f"; area under the ROC curve {auc:.3f}"
    verdict = ("it beats the constant" if b["logistic"] < b["constant"] else
               "**it does not beat the constant**: on these check fits the fit's evidence does not tell this network's "
               "good fits from its bad ones better than the base rate")
    return (f"Model: the logistic regression (what `--install` ships). Check-fit Brier score {b['logistic']:.4f} against {b['constant']:.4f} "
            f"for the fitting fits' base rate {calibration['good_rate']:.2f} as a constant{auc_text}: {verdict}.\n\n")
