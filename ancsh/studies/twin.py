"""``ancsh bench twin``: does the exported model of a fit explain the depth it was fitted to?

For held-out rendered test frames of every shipped category (Kinect-like noise, the input ``ancsh predict`` sees),
the ``exact_reduced`` fit of two providers -- the shipped network (``learned``) and exact ground-truth
correspondences (``oracle``, the fit's own floor) -- becomes its articulated model
(:func:`ancsh.solvers.twin.fitted_model`: the nearest category template reshaped to the fit, with the fitted joint
lines: what ``--urdf`` writes), rendered at the fitted object pose and joint states from the input camera and
compared with the noisy depth on the object's pixels (:func:`ancsh.solvers.render_compare.compare_depth`). The
target of issue 34: a median |residual| within 1 cm.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .report import Provenance, write_json, write_text

__all__ = ["TARGET_M", "measure_twin", "twin_frame", "write_twin_report"]

TARGET_M = 0.01
"""The target median |observed - model depth| on the object's pixels (metres)."""

PROVIDERS = ("learned", "oracle")


def twin_frame(frame, corr, library, *, seed: int = 0, config=None) -> dict:
    """One frame's record for one provider's correspondences: the fit (``config``: its FitConfig), its model rendered,
    the comparison."""
    from ..data.render import ModelRenderer
    from ..model.edit import with_limits
    from ..solvers import Observation, fit
    from ..solvers.render_compare import compare_depth
    from ..solvers.twin import fitted_model

    t0 = time.perf_counter()
    result = fit(Observation(frame.points), corr, "exact_reduced", config=config, rng=seed)
    rec = {"status": result.status.value}
    if not result.ok:
        return rec
    twin = fitted_model(result, corr, library)
    if twin is None:
        rec["status"] = "no_template"
        return rec
    model, q = twin.model, twin.states
    model = with_limits(model, np.minimum(model.lower_limits, q), np.maximum(model.upper_limits, q))  # as exported
    rendered = ModelRenderer(model).render(q, twin.T_cam_B, frame.intrinsics).depth
    cmp = compare_depth(rendered, frame.depth, frame.depth > 0)
    rec.update(cmp.to_dict(), template=twin.template, time_ms=1e3 * (time.perf_counter() - t0))
    return rec


def measure_twin(categories, *, frames: int = 20, seed: int = 0, progress: bool = True, box_extents: str = "max") -> dict:
    """Records of ``frames`` test frames per category and provider (see the module docstring); ``box_extents``: the
    fits' :attr:`~ancsh.solvers.fit.FitConfig.box_extents`."""
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.templates import load_template_library
    from ..learned.inference.provider import LearnedProvider
    from ..solvers import Observation
    from ..solvers.providers.oracle import OracleProvider

    if isinstance(frames, bool) or int(frames) != frames or frames < 1:
        raise ValueError(f"frames: expected a positive integer, got {frames!r}")
    from ..solvers import FitConfig

    config = FitConfig(box_extents=box_extents)
    records = []
    for cat in categories:
        gen = FrameGenerator(GenerationConfig(category=cat, split="test", seed=int(seed)))
        learned = LearnedProvider(cat, seed=int(seed))
        library = load_template_library(cat)
        for i in range(int(frames)):
            fr = gen.frame(i, keep_depth=True)
            for name in PROVIDERS:
                prov = learned if name == "learned" else OracleProvider(fr, "none", rng=int(seed) + i)
                corr = prov.correspond(Observation(fr.points))
                records.append({"category": cat, "frame": i, "provider": name,
                                **twin_frame(fr, corr, library, seed=int(seed) + i, config=config)})
            if progress:
                print(f"twin {cat} frame {i + 1}/{frames}", flush=True)
    return {"records": records, "settings": {"categories": list(categories), "frames": int(frames), "seed": int(seed),
                                             "box_extents": box_extents}}


def summarize(results: dict) -> list[dict]:
    """Per category and provider: frames, failures, median and mean of the per-frame median |residual|, explained,
    see-through, the share of frames within :data:`TARGET_M`."""
    rows = []
    recs = results["records"]
    for cat in results["settings"]["categories"]:
        for name in PROVIDERS:
            sel = [r for r in recs if r["category"] == cat and r["provider"] == name]
            ok = [r for r in sel if "median_abs_residual_m" in r and np.isfinite(r["median_abs_residual_m"])]
            res = np.array([r["median_abs_residual_m"] for r in ok])
            rows.append({
                "category": cat, "provider": name, "frames": len(sel), "failed": len(sel) - len(ok),
                "median_residual_m": float(np.median(res)) if ok else float("nan"),
                "mean_residual_m": float(np.mean(res)) if ok else float("nan"),
                "within_target": float(np.mean(res <= TARGET_M)) if ok else float("nan"),
                "explained": float(np.mean([r["explained"] for r in ok])) if ok else float("nan"),
                "see_through": float(np.mean([r["see_through"] for r in ok])) if ok else float("nan"),
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
        "the shipped network (`learned`) and of exact ground-truth correspondences (`oracle`); each fit's model "
        "(`ancsh.solvers.twin.fitted_model`: the nearest category template reshaped to the fitted part boxes, with the "
        "fitted joint lines, as `ancsh predict --urdf` writes it) rendered at the fitted pose and states from the input "
        "camera and compared with the noisy depth on the object's pixels (`compare_depth`). Residual: per frame the "
        f"median |observed - model| (metres); target: within {100 * TARGET_M:.0f} cm. Explained / see-through as in "
        "`ancsh.solvers.render_compare`. Learned part boxes: `FitConfig.box_extents` "
        f"`{s.get('box_extents', 'max')}` (`docs/results/box_extents.md`).",
        "",
        "| category | provider | frames | failed fits | median residual (mm) | mean of frames (mm) | frames within 1 cm | "
        "explained | see-through |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        md.append(f"| {r['category']} | {r['provider']} | {r['frames']} | {r['failed']} | "
                  f"{1e3 * r['median_residual_m']:.1f} | {1e3 * r['mean_residual_m']:.1f} | {r['within_target']:.0%} | "
                  f"{r['explained']:.2f} | {r['see_through']:.3f} |")
    write_text(path, "\n".join(md) + "\n")
    write_json(path.with_suffix(".json"), {"command": command, "date": prov.date, "machine": prov.machine,
                                           "settings": s, "summary": rows,
                                           "records": results["records"]})
    return path
