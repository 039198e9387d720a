"""The fit's translation error by cause: the exact fit against the official scheme with the NAOCS prior, the scale
estimator and the NAOCS noise varied one at a time (``docs/results/fit_translation.md``).

:func:`measure` fits the ``ancsh bench fit`` frames (test instances, the oracle's corruption drawn with the
benchmark's seeds) with every method of a variant and keeps, per part, the errors and the decomposition of the
translation error (error at the observed points' centroid, signed scale error, the lever from the points to the NPCS
origin); :func:`tables` turns the records into the page's markdown tables. The variants:

- ``"causes"``: the official scheme, per-part fits, and the exact fit with the NAOCS prior weight, the scale
  estimator and scale optimisation varied, at ``realistic`` and ``realistic`` without NAOCS noise;
- ``"reverse"``: the symmetric against the reverse scale estimator at ``low``, ``realistic`` and ``high``;
- ``"coupling"`` (issue 35, item 7: where the joints cost the exact fit translation against per-part fits): the
  default exact fit, per-part fits, the official scheme and the exact fit with NPCS biases
  (``FitConfig.npcs_bias_weight``) at ``realistic``, ``realistic`` without the per-part NPCS warp, ``realistic``
  with exact joint parameters (no axis, pivot or NAOCS noise), and without the warp: exact NAOCS parameters, exact
  joint parameters (the official scheme and the bias weight 0.1 at ``realistic`` only);
- ``"sources"`` (issue 35, item 7): per-part fits, the default exact fit and the exact fit with NPCS biases (weight
  0.01; rotations, and rotations and scales: ``FitConfig.npcs_scale_bias``) at ``realistic`` and at ``realistic`` with one corruption switched off at a time (label flips, outliers, the
  NPCS warp, the joint parameters' noise, the per-point NPCS noise).

Rows labelled with the old default pin ``scale_estimator="symmetric"`` (the default when the page was measured), so
the numbers do not move with the default. The command is ``python -m ancsh.cli.bench.fit_translation``.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

__all__ = ["LEVEL_INDEX", "VARIANTS", "measure", "npcs_anchor", "tables"]

VARIANTS = ("causes", "reverse", "coupling", "sources", "stretch")
# The corruption presets' index in the full fit benchmark (levels none, low, realistic, high): its seed stream.
LEVEL_INDEX = {"low": 1, "realistic": 2, "high": 3, "realistic_exact_naocs": 2, "realistic_no_warp": 2,
               "realistic_exact_joints": 2, "no_warp_exact_naocs": 2, "no_warp_exact_joints": 2, "realistic_no_flips": 2,
               "realistic_no_outliers": 2, "realistic_no_npcs_noise": 2}
# Methods measured at the first level of a variant only (the slow official scheme, the extra settings).
_FIRST_LEVEL_ONLY = ("per_part(sym)", "per_part(umeyama)", "official", "exact npcs_bias 0.1")


def _methods(variant: str) -> dict:
    """Method name -> ``f(observation, correspondences, rng, clean) -> FitResult`` of a variant."""
    from ..solvers.fit import FitConfig, fit
    from ..solvers.official import OfficialSettings, fit_official

    # The page was measured before issue 63: its "default" is FitConfig.previous() (NAOCS prior 0.1, no NPCS biases).
    def exact(**kw):
        kw.setdefault("scale_estimator", "symmetric")  # the default when this ran
        c = FitConfig.previous(**kw)
        return lambda obs, corr, rng, clean: fit(obs, corr, "exact_reduced", "lm", config=c, rng=rng)

    def per_part(**kw):
        kw.setdefault("scale_estimator", "symmetric")
        c = FitConfig(**kw)
        return lambda obs, corr, rng, clean: fit(obs, corr, "per_part", config=c, rng=rng)

    def gt_refit(scale_estimator):
        c = FitConfig.previous(ransac=False, scale_estimator=scale_estimator)
        return lambda obs, corr, rng, clean: fit(obs, corr.with_weights(clean.astype(float)), "exact_reduced", "lm",
                                                 config=c, rng=rng)

    official = OfficialSettings()
    if variant == "stretch":
        scaled = dict(scale_estimator="reverse", npcs_scale_bias=True)
        return {"per_part": per_part(scale_estimator="reverse"), "exact (default)": exact(scale_estimator="reverse"),
                "exact npcs_bias+scale 0.01": exact(npcs_bias_weight=0.01, **scaled),
                **{f"exact npcs_bias+scale+stretch {w:g}": exact(npcs_bias_weight=w, npcs_stretch_bias=True, **scaled)
                   for w in (0.1, 0.03, 0.01, 0.003)}}
    if variant == "sources":
        return {"per_part": per_part(scale_estimator="reverse"), "exact (default)": exact(scale_estimator="reverse"),
                "exact npcs_bias 0.01": exact(scale_estimator="reverse", npcs_bias_weight=0.01),
                "exact npcs_bias+scale 0.01": exact(scale_estimator="reverse", npcs_bias_weight=0.01, npcs_scale_bias=True)}
    if variant == "coupling":
        return {
            "official": lambda obs, corr, rng, clean: fit_official(obs, corr, settings=official, rng=rng),
            "per_part": per_part(scale_estimator="reverse"),
            "exact (default)": exact(scale_estimator="reverse"),
            "exact npcs_bias 0.1": exact(scale_estimator="reverse", npcs_bias_weight=0.1),
            "exact npcs_bias 0.01": exact(scale_estimator="reverse", npcs_bias_weight=0.01),
        }
    if variant == "causes":
        return {
            "official": lambda obs, corr, rng, clean: fit_official(obs, corr, settings=official, rng=rng),
            "per_part(sym)": per_part(scale_estimator="symmetric"),
            "per_part(umeyama)": per_part(scale_estimator="umeyama"),
            "exact(default: sym, prior 0.1)": exact(scale_estimator="symmetric"),
            "exact prior 0": exact(naocs_prior_weight=0.0),
            "exact prior 1": exact(naocs_prior_weight=1.0),
            "exact prior 10": exact(naocs_prior_weight=10.0),
            "exact umeyama scale": exact(scale_estimator="umeyama"),
            "exact paper (umeyama, prior 0)": exact(scale_estimator="umeyama", naocs_prior_weight=0.0,
                                                    max_iterations=1000),
            "exact optimize_scale": exact(optimize_scale=True),
            "gt_refit": gt_refit("symmetric"),
        }
    return {
        "exact(default: sym, prior 0.1)": exact(scale_estimator="symmetric"),
        "exact reverse scale": exact(scale_estimator="reverse"),
        "per_part reverse": per_part(scale_estimator="reverse"),
        "gt_refit": gt_refit("symmetric"),
        "gt_refit reverse": gt_refit("reverse"),
    }


def _levels(variant: str) -> dict:
    from ..solvers.providers.oracle import CORRUPTION_PRESETS

    real = CORRUPTION_PRESETS["realistic"]
    if variant == "stretch":
        return {"realistic": real, "realistic_no_npcs_noise": replace(real, npcs_sigma=0.0)}
    if variant == "sources":
        return {"realistic": real, "realistic_no_flips": replace(real, flip_fraction=0.0),
                "realistic_no_outliers": replace(real, outlier_fraction=0.0), "realistic_no_warp": replace(real, npcs_warp=0.0),
                "realistic_exact_joints": replace(real, axis_sigma_deg=0.0, pivot_sigma=0.0, naocs_sigma=0.0),
                "realistic_no_npcs_noise": replace(real, npcs_sigma=0.0)}
    if variant == "coupling":
        no_warp = replace(real, npcs_warp=0.0)
        return {"realistic": real, "realistic_no_warp": no_warp,
                "realistic_exact_joints": replace(real, axis_sigma_deg=0.0, pivot_sigma=0.0, naocs_sigma=0.0),
                "no_warp_exact_naocs": replace(no_warp, naocs_sigma=0.0),
                "no_warp_exact_joints": replace(no_warp, axis_sigma_deg=0.0, pivot_sigma=0.0, naocs_sigma=0.0)}
    if variant == "causes":
        return {"realistic": real, "realistic_exact_naocs": replace(real, naocs_sigma=0.0)}
    return {"low": CORRUPTION_PRESETS["low"], "realistic": real, "high": CORRUPTION_PRESETS["high"]}


def measure(frames_per_category: int, categories=(), *, variant: str = "causes", progress=print) -> list[dict]:
    """Per (frame, level, method) records: ``{"cat", "frame", "level", "method", "ok", "parts": [...]}``, each part
    with ``rot`` (deg), ``trans``, ``scale_rel``, ``signed_scale``, ``centroid_trans`` and ``lever`` (object units).

    Parameters
    ----------
    frames_per_category : int
        Rendered test frames per category (the fit benchmark's frames and seeds).
    categories : sequence of str
        Categories (empty: the paper's five).
    variant : {"causes", "reverse", "coupling", "sources"}
        The methods and corruption levels compared (module docstring).
    progress : callable
        Receives one line per frame.
    """
    from ..solvers.providers.oracle import corrupt_ground_truth
    from ..solvers.types import Observation
    from .fit import BenchConfig, evaluate_fit, load_frames

    if variant not in VARIANTS:
        raise ValueError(f"variant: expected one of {', '.join(VARIANTS)}, got {variant!r}")
    frames = load_frames(BenchConfig(categories=tuple(categories), frames_per_category=int(frames_per_category),
                                     levels=("realistic",)))
    methods, levels = _methods(variant), _levels(variant)
    recs, t0 = [], time.time()
    for f_i, fr in enumerate(frames):
        obs, L, gt = Observation(fr.points), fr.object_scale, fr.gt
        for lname, corr_def in levels.items():
            # as bench fit; "causes" and "coupling" draw their levels from one stream: only the named knobs differ
            seed = [0, f_i, LEVEL_INDEX[lname]]
            s = corrupt_ground_truth(gt, fr.points, corr_def, np.random.default_rng(seed), joint_limits=fr.joint_limits)
            for name, method in methods.items():
                if lname != "realistic" and name in _FIRST_LEVEL_ONLY and (variant != "causes" or "per_part" in name):
                    continue
                res = method(obs, s.correspondences, np.random.default_rng(seed + [7]), s.clean)
                ev = evaluate_fit(res, fr)
                if not ev.ok:
                    recs.append(dict(cat=fr.category, frame=f_i, level=lname, method=name, ok=False))
                    continue
                parts = []
                for j, (T, Tg) in enumerate(zip(res.T_cam_npcs, gt.T_cam_npcs)):
                    cbar = gt.npcs[gt.part_labels == j].mean(0)  # true NPCS centroid of the visible points
                    cen_err = np.linalg.norm(T.apply(cbar[None])[0] - Tg.apply(cbar[None])[0]) / L
                    parts.append(dict(name=fr.part_names[j], rot=ev.parts[j].rot_deg, trans=ev.parts[j].trans,
                                      scale_rel=ev.parts[j].scale_rel, signed_scale=T.scale / Tg.scale - 1,
                                      centroid_trans=cen_err, lever=float(np.linalg.norm(cbar) * Tg.scale / L)))
                recs.append(dict(cat=fr.category, frame=f_i, level=lname, method=name, ok=True, parts=parts))
        progress(f"{fr.category} #{fr.index} {time.time() - t0:.0f}s")
    return recs


def tables(recs: list[dict]) -> list[str]:
    """The page's markdown tables of :func:`measure` records: all-part means per level and method, then per category
    the translation, centroid translation, rotation and signed scale error per part."""
    methods = list(dict.fromkeys(r["method"] for r in recs))
    levels = list(dict.fromkeys(r["level"] for r in recs))
    cats = list(dict.fromkeys(r["cat"] for r in recs))

    def agg(sel, key):
        v = [p[key] for r in sel if r["ok"] for p in r["parts"]]
        return np.mean(v) if v else np.nan

    out = []
    for lv in levels:
        out += [f"\n## {lv}: all parts mean",
                "| method | rot | trans | centroid trans | |scale err| | signed scale err |"]
        for m in methods:
            sel = [r for r in recs if r["method"] == m and r["level"] == lv]
            if sel:
                out.append(f"| {m} | {agg(sel, 'rot'):.2f} | {agg(sel, 'trans'):.4f} | "
                           f"{agg(sel, 'centroid_trans'):.4f} | {agg(sel, 'scale_rel'):.4f} | "
                           f"{agg(sel, 'signed_scale'):+.4f} |")
        out.append(f"\n## {lv}: per category, translation per part (rot per part)")
        for c in cats:
            for m in methods:
                sel = [r for r in recs if r["method"] == m and r["level"] == lv and r["cat"] == c and r["ok"]]
                if not sel:
                    continue
                n = len(sel[0]["parts"])

                def per_part(key):
                    return [np.mean([r["parts"][j][key] for r in sel]) for j in range(n)]

                out.append(f"| {c} | {m} | " + ", ".join(f"{x:.4f}" for x in per_part("trans")) + " | "
                           + ", ".join(f"{x:.4f}" for x in per_part("centroid_trans")) + " | "
                           + ", ".join(f"{x:.2f}" for x in per_part("rot")) + " | "
                           + ", ".join(f"{x:+.4f}" for x in per_part("signed_scale")) + " |")
    return out


def npcs_anchor(category: str, frames: int, *, seed: int = 0) -> list[dict]:
    """Where a network's NPCS error is smallest: per test frame and part (true labels, >= 20 points), a similarity
    ``S`` fitted from the true onto the shipped network's predicted NPCS, and how far it moves the NPCS origin
    (``origin``, ``|S(0)|``) and the visible points' true NPCS centroid (``centroid``, ``|S(cbar) - cbar|``), NPCS units;
    ``lever`` is ``|cbar|``. A per-part similarity fit absorbs an error whose fixed point is the origin."""
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..geometry import umeyama
    from ..learned.inference.provider import LearnedProvider
    from ..learned.network.weights import weights_path
    from ..solvers.types import Observation

    gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=int(seed)))
    provider = LearnedProvider(str(weights_path(category)), seed=int(seed), num_threads=1)
    out = []
    for i in range(int(frames)):
        fr = gen.frame(i)
        npcs = provider.infer(Observation(fr.points)).prediction.npcs
        for j, name in enumerate(fr.part_names):
            on = fr.gt.part_labels == j
            if on.sum() < 20:
                continue
            true = fr.gt.npcs[on]
            S = umeyama(true, npcs[on, j])
            cbar = true.mean(0)
            out.append(dict(frame=i, part=name, origin=float(np.linalg.norm(S.translation)),
                            centroid=float(np.linalg.norm(S.apply(cbar[None])[0] - cbar)),
                            lever=float(np.linalg.norm(cbar))))
    return out
