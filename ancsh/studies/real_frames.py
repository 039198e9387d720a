"""Real sensor frames: what ``ancsh predict`` does on them, judged against measured truth (``ancsh bench real-frames``).

For every object of a real frame (:mod:`ancsh.data.real_frames`) the learned pipeline runs three
times, as a user would run ``ancsh predict``: with the object's mask (``mask``), without one
(``auto``: the object is isolated automatically) and with a ``--pixel`` hint at the mask's centre
(``pixel``). On a frame with no object of any category (a negative frame) every category with
shipped weights runs without a mask: each must fail. Each run records the status and the exit
code ``ancsh predict`` would give, ``p_good``, the isolated mask's IoU with the true mask, the
joint-state error against the measured opening, the fitted part sizes and the time of each stage.
One picture per frame shows every run: the colour image, the true mask (green), the isolated mask
(red) and the fitted boxes and joint axes projected.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..outputs import json_safe
from .report import Provenance, save_figure, write_json, write_text

__all__ = ["MODES", "hint_pixel", "measure_real_frames", "write_real_frames_report"]

MODES = ("mask", "auto", "pixel")


def hint_pixel(mask: np.ndarray) -> tuple:
    """``(u, v)`` at the mask's centre: its centroid, or the mask pixel nearest it when the centroid is off the mask."""
    vs, us = np.nonzero(mask)
    u, v = float(us.mean()), float(vs.mean())
    if not mask[int(round(v)), int(round(u))]:
        k = int(np.argmin((us - u) ** 2 + (vs - v) ** 2))
        u, v = float(us[k]), float(vs[k])
    return (round(u), round(v))


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else float("nan")


def _run(frame, category, mode, provider, truth, *, seed, num_points):
    """One ``ancsh predict`` run: the record and the prediction (``None`` when it could not run)."""
    from ..data.isolate import ObjectHint
    from ..learned.inference.predict import predict_depth

    rec = {"frame": frame.name, "category": category, "mode": mode, "truth_category": None if truth is None else truth.category}
    mask = truth.mask if (truth is not None and mode == "mask") else None
    hint = ObjectHint(pixel=hint_pixel(truth.mask)) if (truth is not None and mode == "pixel") else None
    rec["hint_pixel"] = None if hint is None else list(hint.pixel)
    if provider is None:
        rec.update(status="no_weights", ok=False, exit_code=2, message=f"no shipped weights for {category!r}")
        return rec, None
    pred = predict_depth(frame.depth, frame.intrinsics, category, mask=mask, provider=provider, num_points=num_points,
                         seed=seed, hint=hint)
    r = pred.result
    rec.update(status=r.status.value, ok=bool(r.ok), exit_code=0 if r.ok else 1, message=r.message,
               p_good=pred.p_good, p_object=pred.p_object, points=int(pred.points_cam.shape[0]), notes=list(pred.notes),
               render_compare=None if pred.render_compare is None else pred.render_compare.to_dict(),
               timings_ms={k: float(v) for k, v in pred.timings_ms.items()})
    iso = pred.isolation
    rec["mask_iou"] = None if (iso is None or truth is None) else _iou(iso.mask, truth.mask)
    rec["isolated_pixels"] = None if iso is None else int(np.count_nonzero(iso.mask))
    rec["part_sizes_m"] = [sorted((float(x) for x in b.extents), reverse=True) for b in r.boxes_cam] if r.ok else None
    states = []
    for k, jt in enumerate(pred.joint_types):
        rest = pred.joint_rest[k] if k < len(pred.joint_rest) else float("nan")
        value = float(r.joint_states[k]) + rest if k < len(r.joint_states) else float("nan")
        states.append(math.degrees(value) if jt == "revolute" else value)
    rec["joint_state"] = states
    rec["joint_state_error_deg"] = None
    if truth is not None and truth.joint_state_deg is not None and category == truth.category and states:
        rec["joint_state_error_deg"] = abs(states[0] - truth.joint_state_deg) if np.isfinite(states[0]) else None
    return rec, pred


def measure_real_frames(folders, *, categories=None, seed: int = 0, num_points: int = 1024, progress: bool = True,
                        weights=None, refine=None, seeds=()) -> dict:
    """Run the real-frame benchmark (module docstring) on ``folders``.

    Parameters
    ----------
    folders : sequence of Path
        Real-frame folders (:func:`ancsh.data.real_frames.load_real_frame`).
    categories : sequence of str, optional
        The categories tried on negative frames (default: every one with shipped weights).
    seed : int
        Sampling and RANSAC seed of every run.
    num_points : int
        Points per run.
    weights : dict, optional
        ``{category: weights file}`` instead of the shipped networks (a network under test; its calibrations of
        ``p_good`` / ``p_object`` apply only where they were made with it).
    refine : dict, optional
        ``{category: "template" | "network" | "none"}`` instead of ``"auto"`` (what ``ancsh predict`` does; the
        calibrations were measured on its fits).
    seeds : sequence of int
        Every run again at each of these seeds: ``"agreement"`` holds per run the statuses and joint states (the
        seed agreement of the status and the spread of the states; none by default).

    Returns
    -------
    dict
        ``{"records": [...], "frames": [...], "predictions": {(frame, category, mode): DepthPrediction},
        "weights": {category: {"file": str, "sha256": str}}}``; ``predictions`` is for the pictures and is not JSON.
    """
    from ..data.real_frames import load_real_frame
    from ..learned.inference.provider import LearnedProvider
    from ..learned.network.weights import shipped_categories, weights_path

    weights, refine = dict(weights or {}), dict(refine or {})
    frames = [load_real_frame(f) for f in folders]
    negatives = list(categories) if categories else list(shipped_categories())
    providers = {}

    def provider(category):
        if category not in providers:
            source = weights.get(category, category)
            providers[category] = (LearnedProvider(source, seed=seed, refine=refine.get(category, "auto"))
                                   if category in weights or weights_path(category).is_file() else None)
        return providers[category]

    records, predictions, summaries, agreement = [], {}, [], []
    for frame in frames:
        runs = ([(o.category, mode, o) for o in frame.objects for mode in MODES] if frame.objects
                else [(c, "auto", None) for c in negatives])
        summaries.append({"frame": frame.name, "folder": str(frame.folder), "size": [frame.intrinsics.width, frame.intrinsics.height],
                          "objects": [{"category": o.category, "mask": o.mask_file, "mask_pixels": int(o.mask.sum()),
                                       "joint_state_deg": o.joint_state_deg, "uncertainty_deg": o.uncertainty_deg}
                                      for o in frame.objects]})
        for category, mode, truth in runs:
            if progress:
                print(f"  {frame.name}: {category} ({mode})", flush=True)
            rec, pred = _run(frame, category, mode, provider(category), truth, seed=seed, num_points=num_points)
            records.append(rec)
            predictions[(frame.name, category, mode)] = pred
            if seeds and provider(category) is not None:
                runs_at = [_run(frame, category, mode, provider(category), truth, seed=s, num_points=num_points)[0]
                           for s in seeds]
                agreement.append({"frame": frame.name, "category": category, "mode": mode, "seeds": list(seeds),
                                  "statuses": [r["status"] for r in runs_at],
                                  "states": [r["joint_state"][0] if r["ok"] and r["joint_state"] else None
                                             for r in runs_at],
                                  "errors": [r["joint_state_error_deg"] for r in runs_at]})
    isolation = [{"frame": frame.name, "size": [frame.intrinsics.width, frame.intrinsics.height], "category": c,
                  "ms": isolation_times(frame, c, seed=seed)}
                 for frame in frames for c in dict.fromkeys(o.category for o in frame.objects or ()) or negatives]
    used = {c: {"file": str(w), "sha256": getattr(providers[c].network, "sha256", None)}
            for c, w in weights.items() if providers.get(c) is not None}
    return {"records": records, "frames": summaries, "predictions": predictions, "frame_data": frames,
            "isolation": isolation, "weights": used, "refine": refine, "agreement": agreement}


#: Isolation is timed alone this many times per frame and category (the median is reported).
ISOLATION_REPEATS = 5


def isolation_times(frame, category: str, *, seed: int = 0, repeats: int = ISOLATION_REPEATS) -> list:
    """Milliseconds of :func:`ancsh.data.isolate.isolate_object` on ``frame``'s depth, ``repeats`` times after one
    warm-up call (one process; the numbers move with the machine's load)."""
    import time

    from ..data.conventions import convention
    from ..data.isolate import isolate_object

    size_range = convention(category).diagonal_range
    isolate_object(frame.depth, frame.intrinsics, size_range, rng=seed)
    out = []
    for _ in range(int(repeats)):
        t0 = time.perf_counter()
        isolate_object(frame.depth, frame.intrinsics, size_range, rng=seed)
        out.append(1e3 * (time.perf_counter() - t0))
    return out


def _fmt(x, spec=".1f", none="-"):
    return none if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, spec)


def draw_real_frame(frame, records, predictions):
    """One figure per frame: a panel per run (module docstring)."""
    from matplotlib.figure import Figure

    from ..data.show import draw_fit_on_image

    n = len(records)
    cols = min(3, n)
    rows = math.ceil(n / cols)
    aspect = frame.intrinsics.height / frame.intrinsics.width
    fig = Figure(figsize=(5.2 * cols, 5.2 * aspect * rows + 0.9), dpi=90)
    truth_masks = [o.mask for o in frame.objects]
    for i, rec in enumerate(records):
        ax = fig.add_subplot(rows, cols, i + 1)
        if frame.rgb is not None:
            ax.imshow(frame.rgb, interpolation="nearest")
        else:
            ax.imshow(np.ma.masked_where(frame.depth <= 0, frame.depth), cmap="gray", interpolation="nearest")
        for m in truth_masks:
            ax.contour(m.astype(float), levels=[0.5], colors="lime", linewidths=1.0)
        pred = predictions.get((rec["frame"], rec["category"], rec["mode"]))
        if pred is not None and pred.isolation is not None and pred.isolation.mask.any():
            ax.contour(pred.isolation.mask.astype(float), levels=[0.5], colors="red", linewidths=1.0)
        if pred is not None and pred.result.ok and pred.result.boxes_cam:
            length = 0.6 * max(float(np.linalg.norm(np.ptp(pred.points_cam, axis=0))), 1e-3)
            draw_fit_on_image(ax, pred.result, frame.intrinsics, length)
        if rec["hint_pixel"] is not None:
            ax.plot(*rec["hint_pixel"], marker="+", color="yellow", ms=12, mew=2)
        ax.set_xlim(-0.5, frame.intrinsics.width - 0.5)
        ax.set_ylim(frame.intrinsics.height - 0.5, -0.5)
        ax.set_xticks([])
        ax.set_yticks([])
        state = ", ".join(_fmt(s) for s in rec.get("joint_state") or [])
        ax.set_title(f"{rec['category']} ({rec['mode']}): {rec['status']}, p_good {_fmt(rec.get('p_good'), '.2f')}\n"
                     f"mask IoU {_fmt(rec.get('mask_iou'), '.2f')}, state {state or '-'}", fontsize=8)
    fig.suptitle(f"{frame.name}: true mask green, isolated red, fitted boxes and joint axes (black)", fontsize=10)
    fig.tight_layout()
    return fig


def write_real_frames_report(results: dict, path, *, command: str) -> Path:
    """Markdown at ``path``, the records as JSON beside it, a picture per frame (``<stem>_<frame>.png``)."""
    path = Path(path)
    prov = Provenance(command)
    recs = results["records"]
    lines = [
        "# Real sensor frames: `ancsh predict` against measured truth", "",
        f"Command: `{command}`  ",
        f"Date: {prov.date}; machine: {prov.machine_text}  ",
        "Study: `ancsh.studies.real_frames` (frames: `ancsh.data.real_frames`, schema `real-frame-truth/1`)", "",
        *([("Networks under test (not the shipped ones): " + ", ".join(
            f"{c} `{w['file']}` (sha256 {str(w['sha256'])[:12]})" for c, w in results["weights"].items())), ""]
          if results.get("weights") else []),
        *([("Refinements other than `--refine auto` (its calibrations of p_good / p_object were made on auto's fits): "
            + ", ".join(f"{c} `{o}`" for c, o in results["refine"].items())), ""] if results.get("refine") else []),
        "Each object is predicted as a user would run `ancsh predict`: with its mask (`mask`), without one (`auto`) and "
        "with a `--pixel` hint at the mask's centre (`pixel`); on a frame with no object of any category, every category "
        "with shipped weights runs without a mask and must not report `success`. Exit = the exit code of `ancsh predict` "
        "(0 only for `success`). Mask IoU: the isolated pixels against the true mask. State: the fitted opening in the "
        "category's convention (degrees, 0 = closed); error against the frame's measurement (its uncertainty in the "
        "frame table). p_object: the calibrated probability that the fitted pixels are an object of the category "
        "(`ancsh calibrate --object`; below `MIN_P_OBJECT` without a mask and `MIN_P_OBJECT_MASKED` with one the status "
        "is `not_this_category`); explained / see-through / hidden: the "
        "fitted category template rendered against the depth (`ancsh.solvers.render_compare`; hidden = the share of the "
        "model's pixels behind a nearer surface). Sizes: each part's fitted amodal "
        "box, largest extent first (metres). Times in milliseconds on one process: isolate = segmenting the image "
        "(the budget is 200 ms at 1280x720), verify = fitting the candidate segments, network and fit of the chosen "
        "one, total with reading and render-and-compare.", "",
        "## Frames", "",
        "| frame | pixels | objects (truth) |",
        "|---|---|---|",
    ]
    for f in results["frames"]:
        objs = "; ".join(f"{o['category']} (`{o['mask']}`, {o['mask_pixels']} px, opening {_fmt(o['joint_state_deg'])} "
                         f"± {_fmt(o['uncertainty_deg'])}°)" for o in f["objects"]) or "none of any category (negative)"
        lines.append(f"| {f['frame']} | {f['size'][0]}x{f['size'][1]} | {objs} |")
    lines += ["", "## Runs", "",
              "| frame | category | mode | status | exit | p_good | p_object | explained / see-through / hidden | mask IoU | state (°) "
              "| truth (°) | error (°) | part sizes (m) | isolate | verify | network | fit | total |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    truth_of = {(f["frame"], o["category"]): o["joint_state_deg"] for f in results["frames"] for o in f["objects"]}
    for r in recs:
        t = r.get("timings_ms", {})
        sizes = " / ".join("×".join(f"{x:.2f}" for x in s) for s in r.get("part_sizes_m") or []) or "-"
        state = ", ".join(_fmt(s) for s in r.get("joint_state") or []) or "-"
        rc = r.get("render_compare") or {}
        compare = (f"{_fmt(rc.get('explained'), '.2f')} / {_fmt(rc.get('see_through'), '.2f')} / "
                   f"{_fmt(rc.get('hidden'), '.2f')}") if rc else "-"
        lines.append(
            f"| {r['frame']} | {r['category']} | {r['mode']} | {r['status']} | {r['exit_code']} | {_fmt(r.get('p_good'), '.2f')} "
            f"| {_fmt(r.get('p_object'), '.2f')} | {compare} | {_fmt(r.get('mask_iou'), '.2f')} | {state} "
            f"| {_fmt(truth_of.get((r['frame'], r['category'])))} | {_fmt(r.get('joint_state_error_deg'))} | {sizes} "
            f"| {_fmt(t.get('isolate'), '.0f')} | {_fmt(t.get('verify'), '.0f')} | {_fmt(t.get('network'), '.0f')} "
            f"| {_fmt(t.get('fit'), '.0f')} | {_fmt(t.get('total'), '.0f')} |")
    negatives = [r for r in recs if r["truth_category"] is None]
    positives = [r for r in recs if r["truth_category"] is not None]
    lines += ["", "## Summary", ""]
    if negatives:
        wrong = [r for r in negatives if r["ok"]]
        names = ", ".join(f"{r['frame']}/{r['category']}" for r in wrong) or "none"
        lines.append(f"- Negative frames: {len(wrong)} of {len(negatives)} runs report `success` ({names}).")
    for mode in MODES:
        sel = [r for r in positives if r["mode"] == mode]
        if not sel:
            continue
        ok = sum(r["ok"] for r in sel)
        errs = [r["joint_state_error_deg"] for r in sel if r.get("joint_state_error_deg") is not None and r["ok"]]
        ious = [r["mask_iou"] for r in sel if r.get("mask_iou") is not None]
        lines.append(f"- `{mode}`: {ok} of {len(sel)} objects `success`"
                     + (f"; joint-state error {', '.join(f'{e:.1f}' for e in errs)}°" if errs else "")
                     + (f"; mask IoU {', '.join(f'{x:.2f}' for x in ious)}" if ious else "") + ".")
    timed = results.get("isolation") or []
    if timed:
        lines += ["", "## Isolation time", "",
                  f"`ancsh.data.isolate.isolate_object` alone, {ISOLATION_REPEATS} times per frame and category after a "
                  "warm-up call, in this process (ms; the budget is 200 ms at 1280x720 on one core).", "",
                  "| frame | pixels | category | median | min | max |", "|---|---|---|---|---|---|"]
        for t in timed:
            lines.append(f"| {t['frame']} | {t['size'][0]}x{t['size'][1]} | {t['category']} | {np.median(t['ms']):.0f} "
                         f"| {min(t['ms']):.0f} | {max(t['ms']):.0f} |")
        big = [np.median(t["ms"]) for t in timed if t["size"][0] * t["size"][1] >= 1280 * 720]
        if big:
            lines += ["", f"At 1280x720 or more: median {np.median(big):.0f} ms, the slowest frame {max(big):.0f} ms."]
    agreement = results.get("agreement") or []
    if agreement:
        lines += ["", "## The same answer at every seed", "",
                  f"Every run again at seeds {', '.join(map(str, agreement[0]['seeds']))}: the most common status and at how "
                  "many seeds it came, the spread (std) of the successful states and their largest error against the "
                  "truth (degrees).", "", "| frame | category | mode | status (seeds) | state std | largest error |",
                  "|---|---|---|---|---|---|"]
        for a in agreement:
            common = max(set(a["statuses"]), key=a["statuses"].count)
            ok = [q for q, st in zip(a["states"], a["statuses"]) if st == "success" and q is not None]
            errs = [e for e, st in zip(a["errors"], a["statuses"]) if st == "success" and e is not None]
            lines.append(f"| {a['frame']} | {a['category']} | {a['mode']} | {common} ({a['statuses'].count(common)}/"
                         f"{len(a['statuses'])}) | {_fmt(float(np.std(ok, ddof=1)) if len(ok) > 1 else None)} "
                         f"| {_fmt(max(errs) if errs else None)} |")
    lines.append("")
    for f in results["frame_data"]:
        fr = [r for r in recs if r["frame"] == f.name]
        pic = path.with_name(f"{path.stem}_{f.name}.png")
        save_figure(draw_real_frame(f, fr, results["predictions"]), pic)
        lines += [f"![{f.name}]({pic.name})", ""]
    write_text(path, "\n".join(lines))
    write_json(path.with_suffix(".json"), json_safe({"command": command, "date": prov.date, "machine": prov.machine,
                                                     "frames": results["frames"], "records": recs,
                                                     "isolation_ms": timed, "weights": results.get("weights") or {},
                                                     "agreement": agreement,
                                                     "refine": results.get("refine") or {}}),
               indent=1)
    return path
