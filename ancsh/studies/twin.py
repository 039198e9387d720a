"""``ancsh bench twin``: does the exported model of a fit explain the depth it was fitted to?

For held-out rendered test frames of every shipped category (Kinect-like noise, the input ``ancsh predict`` sees),
the ``exact_reduced`` fit of two providers -- the shipped network (``learned``) and exact ground-truth
correspondences (``oracle``, the fit's own floor) -- becomes its articulated model
(:func:`ancsh.solvers.twin.fitted_model`: the nearest category template reshaped to the fit, with the fitted joint
lines: what ``--urdf`` writes), rendered at the fitted object pose and joint states from the input camera and
compared with the noisy depth on the object's pixels (:func:`ancsh.solvers.render_compare.compare_depth`). The
target of issue 34: a median |residual| within 1 cm. With ``candidates`` > 1 each fit's model is also chosen by
render-and-compare among that many nearest templates (``fitted_model(..., observed=..., candidates=K)``), and with
``align`` > 0 the best ``align`` of them are also moved onto the depth by articulated ICP
(:func:`ancsh.solvers.twin.align_model`; what ``ancsh predict --urdf`` does); the choices are reported side by side on
the same fits.
"""

from __future__ import annotations

import time
from functools import partial
from pathlib import Path

import numpy as np

from .report import Provenance, write_json, write_text

__all__ = ["INSTANCE", "TARGET_M", "instance_floor", "measure_twin", "selection_name", "summarize", "twin_frame", "write_twin_report"]

TARGET_M = 0.01
"""The target median |observed - model depth| on the object's pixels (metres)."""

PROVIDERS = ("learned", "learned+network", "learned+template", "oracle")
#: The metric's floor: the instance's own model at its true pose and states against the noisy depth (sensor noise).
INSTANCE = "instance"
"""``learned``: the shipped network's correspondences, fitted; ``learned+network``: that fit refined by the category's
shipped refinement network (``refine="network"``, what ``ancsh predict --refine network`` does; only categories that ship
one); ``learned+template``: that fit refined against the category template (``LearnedProvider.refine(..., refine="template")``: articulated ICP of the nearest template, kept where its
score says so; what ``ancsh predict --refine template`` does); ``oracle``: exact ground-truth correspondences."""


def selection_name(candidates: int, align: int = 0) -> str:
    """The report's name of a template choice: ``"nearest"`` (1), ``"best of K"``, ``"best of K, A aligned"``."""
    name = "nearest" if candidates == 1 else f"best of {candidates}"
    return f"{name}, {align} aligned" if align else name


def twin_frame(frame, corr, library, *, seed: int = 0, config=None, candidates=(1,), refine=None) -> list[dict]:
    """One frame's records for one provider's correspondences, one per template choice in ``candidates`` (``K`` or
    ``(K, A)``; K = 1: the nearest template; K > 1: the best of the K nearest by render-and-compare; A > 0: the best A
    of them aligned to the depth, :func:`ancsh.solvers.twin.fitted_model`'s ``align``): the fit (``config``: its
    FitConfig, made once; ``refine(observation, corr, fit)``, optional: a refinement outcome whose ``.result``
    replaces it and whose ``.accepted`` is recorded), its model rendered, the comparison."""
    from ..data.render import ModelRenderer
    from ..model.edit import with_limits
    from ..solvers import Observation, fit
    from ..solvers.render_compare import compare_depth
    from ..solvers.twin import EXPORT_BOX_EXTENTS, ObservedDepth, fitted_model

    choices = [(int(c), 0) if np.isscalar(c) else (int(c[0]), int(c[1])) for c in candidates]
    t0 = time.perf_counter()
    obs = Observation(frame.points)
    result = fit(obs, corr, "exact_reduced", config=config, rng=seed)
    extra = {}
    if refine is not None and result.ok:
        outcome = refine(obs, corr, result)
        result, extra = outcome.result, {"refined": bool(outcome.accepted)}
    fit_ms = 1e3 * (time.perf_counter() - t0)
    if not result.ok:
        return [{"selection": selection_name(k, a), "status": result.status.value, **extra} for k, a in choices]
    mask = frame.depth > 0
    observed = ObservedDepth(frame.depth, frame.intrinsics, mask)
    out = []
    for k, a in choices:
        rec = {"selection": selection_name(k, a), "status": result.status.value, **extra}
        t1 = time.perf_counter()
        twin = fitted_model(result, corr, library, observed=observed if k > 1 or a else None, candidates=k, align=a,
                            box_extents=EXPORT_BOX_EXTENTS, rng=seed)
        if twin is None:
            rec["status"] = "no_template"
            out.append(rec)
            continue
        model, q = twin.model, twin.states
        model = with_limits(model, np.minimum(model.lower_limits, q), np.maximum(model.upper_limits, q))  # as exported
        rendered = ModelRenderer(model).render(q, twin.T_cam_B, frame.intrinsics).depth
        cmp = compare_depth(rendered, frame.depth, mask)
        rec.update(cmp.to_dict(), template=twin.template, time_ms=fit_ms + 1e3 * (time.perf_counter() - t1))
        if a:
            rec["aligned"] = bool(twin.aligned)
        out.append(rec)
    return out


def instance_floor(gen, frame) -> dict:
    """The record of the frame's own instance: its model rendered noise-free at the true pose and states against the
    noisy depth (what the sensor noise alone leaves of the metric)."""
    from ..solvers.render_compare import compare_depth

    _, renderer = gen.instance(frame.instance_index)
    clean = renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth
    return {"status": "success", **compare_depth(clean, frame.depth, frame.depth > 0).to_dict()}


def _refinement(provider, observation, corr, result, *, refine, rng, config):
    """``provider``'s fit refined against the category template or by its refinement network
    (:meth:`LearnedProvider.refine` with ``refine`` ``"template"`` or ``"network"``; the network's fits with ``config``)."""
    return provider.refine(observation, corr, result, refine=refine, rng=rng, config=config)


#: The refinement each refined provider runs (:meth:`LearnedProvider.refine`'s ``refine``).
_REFINES = {"learned+network": "network", "learned+template": "template"}


def measure_twin(categories, *, frames: int = 20, seed: int = 0, progress: bool = True, box_extents: str = "max",
                 candidates: int = 1, align: int = 0) -> dict:
    """Records of ``frames`` test frames per category, provider and template choice (see the module docstring);
    ``box_extents``: the fits' :attr:`~ancsh.solvers.fit.FitConfig.box_extents`; ``candidates`` > 1 adds the choice
    among that many nearest templates by render-and-compare beside the nearest one, ``align`` > 0 that choice with
    the best ``align`` of them aligned to the depth."""
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.templates import load_template_library
    from ..learned.inference.provider import LearnedProvider
    from ..learned.network.weights import weights_path
    from ..solvers import Observation
    from ..solvers.providers.oracle import OracleProvider

    if isinstance(frames, bool) or int(frames) != frames or frames < 1:
        raise ValueError(f"frames: expected a positive integer, got {frames!r}")
    if isinstance(candidates, bool) or int(candidates) != candidates or candidates < 1:
        raise ValueError(f"candidates: expected a positive integer, got {candidates!r}")
    if isinstance(align, bool) or int(align) != align or align < 0:
        raise ValueError(f"align: expected a non-negative integer, got {align!r}")
    choices = [(1, 0)] + ([(int(candidates), 0)] if candidates > 1 else []) + ([(int(candidates), int(align))] if align else [])
    from ..solvers import FitConfig

    oracle_config = FitConfig(box_extents=box_extents)  # the learned fits: the network's objective (fit_config)
    records = []
    for cat in categories:
        gen = FrameGenerator(GenerationConfig(category=cat, split="test", seed=int(seed)))
        learned = LearnedProvider(cat, seed=int(seed))
        learned_config = learned.fit_config(box_extents=box_extents)
        library = load_template_library(cat)
        providers = [n for n in PROVIDERS if n != "learned+network" or weights_path(cat, "refine").is_file()]
        for i in range(int(frames)):
            fr = gen.frame(i, keep_depth=True)
            records.append({"category": cat, "frame": i, "provider": INSTANCE, "selection": INSTANCE,
                            **instance_floor(gen, fr)})
            learned_corr = learned.correspond(Observation(fr.points))
            for name in providers:
                if name == "oracle":
                    corr = OracleProvider(fr, "none", rng=int(seed) + i).correspond(Observation(fr.points))
                    config = oracle_config
                else:
                    corr, config = learned_corr, learned_config
                refine = (partial(_refinement, learned, refine=_REFINES[name], rng=int(seed) + i, config=config)
                          if name in _REFINES else None)
                for rec in twin_frame(fr, corr, library, seed=int(seed) + i, config=config, candidates=choices,
                                      refine=refine):
                    records.append({"category": cat, "frame": i, "provider": name, **rec})
            if progress:
                print(f"twin {cat} frame {i + 1}/{frames}", flush=True)
    return {"records": records, "settings": {"categories": list(categories), "frames": int(frames), "seed": int(seed),
                                             "box_extents": box_extents, "candidates": int(candidates),
                                             "align": int(align)}}


def summarize(results: dict) -> list[dict]:
    """Per category, provider and template choice: frames, failures, median and mean of the per-frame median
    |residual|, explained, see-through, the share of frames within :data:`TARGET_M`."""
    rows = []
    recs = results["records"]
    k, a = int(results["settings"].get("candidates", 1)), int(results["settings"].get("align", 0))
    selections = [selection_name(1)] + ([selection_name(k)] if k > 1 else []) + ([selection_name(k, a)] if a else [])
    for cat in results["settings"]["categories"]:
        for name, selection in [(INSTANCE, INSTANCE)] + [(n, c) for n in PROVIDERS for c in selections]:
            sel = [r for r in recs if r["category"] == cat and r["provider"] == name
                   and r.get("selection", selection_name(1)) == selection]
            if not sel and name == "learned+network":  # the category ships no refinement network
                continue
            ok = [r for r in sel if "median_abs_residual_m" in r and np.isfinite(r["median_abs_residual_m"])]
            res = np.array([r["median_abs_residual_m"] for r in ok])
            rows.append({
                "category": cat, "provider": name, "selection": selection, "frames": len(sel), "failed": len(sel) - len(ok),
                "median_residual_m": float(np.median(res)) if ok else float("nan"),
                "mean_residual_m": float(np.mean(res)) if ok else float("nan"),
                "within_target": float(np.mean(res <= TARGET_M)) if ok else float("nan"),
                "explained": float(np.mean([r["explained"] for r in ok])) if ok else float("nan"),
                "see_through": float(np.mean([r["see_through"] for r in ok])) if ok else float("nan"),
                "refined": float(np.mean([r["refined"] for r in sel])) if sel and "refined" in sel[0] else None,
                "aligned": float(np.mean([r["aligned"] for r in ok])) if ok and "aligned" in ok[0] else None,
            })
    return rows


def write_twin_report(results: dict, path, *, command: str) -> Path:
    """The markdown table (and a JSON of the records beside it)."""
    path = Path(path)
    prov = Provenance(command)
    rows = summarize(results)
    s = results["settings"]
    md = [
        "# The exported model of a fit against the depth it was fitted to",
        "",
        f"Command: `{command}`  ",
        f"Date: {prov.date}; machine: {prov.machine_text}  ",
        "",
        f"{s['frames']} held-out test frames per category (Kinect-like noise, seed {s['seed']}); `exact_reduced` fits of "
        "the shipped network (`learned`), the same fits refined by the category's shipped refinement network "
        "(`learned+network`, as `ancsh predict --refine network`; only where one is shipped; 'refined' = the share of "
        "frames where a pass succeeded), or against the category template (`learned+template`: "
        "articulated ICP of the nearest template, kept where its score says so, as `ancsh predict --refine template`; "
        "'refined' = the share of frames where it was kept) and fits of exact ground-truth correspondences (`oracle`); "
        "first, the metric's floor: the frame's own instance rendered noise-free at its true pose and states "
        "(`instance`: what the sensor noise alone leaves). "
        "each fit's model "
        "(`ancsh.solvers.twin.fitted_model`: the nearest category template reshaped to the fitted part boxes -- their "
        "NPCS sides scaled to the unit diagonal, `EXPORT_BOX_EXTENTS` -- with the "
        "fitted joint lines, as `ancsh predict --urdf` writes it) rendered at the fitted pose and states from the input "
        "camera and compared with the noisy depth on the object's pixels (`compare_depth`). Residual: per frame the "
        f"median |observed - model| (metres); target: within {100 * TARGET_M:.0f} cm. Explained / see-through as in "
        "`ancsh.solvers.render_compare`. The fits' `FitConfig.box_extents`: "
        f"`{s.get('box_extents', 'max')}` (`docs/results/box_extents.md`; the refinements' fits use it). Template: `nearest` = the template nearest "
        "to the fitted part boxes; `best of K` = of the K nearest, the one whose render has the lowest median "
        "|residual| against the input depth (`fitted_model(..., observed=..., candidates=K)`), the same fits; "
        "`best of K, A aligned` = the A of those with the lowest residuals each moved onto the observed points by "
        "articulated ICP (object pose and joint states; the model also scaled by each of `ALIGN_SCALES`, "
        "`ancsh.solvers.twin.align_model`), then the other K - A ranked "
        "again at the aligned pose and the best A of them aligned too, the lowest residual of all kept, as `ancsh "
        "predict --urdf` exports it ('aligned' = the share of frames where an aligned model won).",
        "",
        "| category | provider | template | frames | failed fits | refined | aligned | median residual (mm) | "
        "mean of frames (mm) | frames within 1 cm | explained | see-through |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        refined = "-" if r["refined"] is None else f"{r['refined']:.0%}"
        aligned = "-" if r["aligned"] is None else f"{r['aligned']:.0%}"
        md.append(f"| {r['category']} | {r['provider']} | {r['selection']} | {r['frames']} | {r['failed']} | {refined} | "
                  f"{aligned} | "
                  f"{1e3 * r['median_residual_m']:.1f} | {1e3 * r['mean_residual_m']:.1f} | {r['within_target']:.0%} | "
                  f"{r['explained']:.2f} | {r['see_through']:.3f} |")
    write_text(path, "\n".join(md) + "\n")
    write_json(path.with_suffix(".json"), {"command": command, "date": prov.date, "machine": prov.machine,
                                           "settings": s, "summary": rows,
                                           "records": results["records"]})
    return path
