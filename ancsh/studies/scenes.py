"""``ancsh bench scenes``: ``ancsh predict`` without a mask on rendered scenes, against the truth of every pixel.

Each test frame of a category is rendered in a scene (:func:`ancsh.data.scenes.render_scene`: a floor or a staircase,
a wall or a curtain behind, clutter beside), with the dataset's sensor noise. Per frame, three runs of
:func:`ancsh.learned.inference.predict.predict_depth`:

- ``mask``: with the object's visible pixels as the mask (what isolation could at best hand the fit);
- ``auto``: without a mask, as a user runs ``ancsh predict`` (isolation, verification of the candidates);
- ``empty``: the same scene without the object: the category is not there, and ``success`` is a false report.

Per run: status, the isolated mask's IoU with the object's visible pixels, the mean rotation error over the parts and
the mean joint-state error (``ancsh.evaluation.evaluate_fit`` against the frame's ground truth; degrees, or object
units for prismatic joints) and the time. The rendered counterpart of ``ancsh bench real-frames``.
"""

from __future__ import annotations

import time
import zlib
from pathlib import Path

import numpy as np

from .report import Provenance, median_text, write_json, write_text

__all__ = ["MODES", "WRONG_MASK_IOU", "WRONG_ROTATION_DEG", "load_scenes_records", "measure_scenes",
           "merge_scenes_records", "wrong_success", "write_scenes_report"]

#: The runs per scene (module docstring).
MODES = ("mask", "auto", "empty")
#: A scene whose clutter leaves fewer of the object's pixels visible is left out (and counted).
MIN_VISIBLE_PIXELS = 300
#: An ``auto`` success is counted wrong (:func:`wrong_success`) when its isolated mask overlaps the object's visible
#: pixels by less than this IoU (something else, or a fragment, was fitted) ...
WRONG_MASK_IOU = 0.5
#: ... or when its mean part rotation is further off than this (degrees): a success status a user should not trust.
WRONG_ROTATION_DEG = 20.0


def _record(pred, scene, category, index, mode, seconds) -> dict:
    from ..evaluation import evaluate_fit

    r = pred.result
    rec = {"category": category, "frame": int(index), "support": scene.support, "mode": mode, "status": r.status.value,
           "ok": bool(r.ok), "mask_iou": None, "rot_deg": None, "state_err": None, "time_ms": 1e3 * seconds}
    if mode == "auto" and pred.isolation is not None:
        m, v = np.asarray(pred.isolation.mask, dtype=bool), scene.visible
        rec["mask_iou"] = float(np.count_nonzero(m & v) / max(np.count_nonzero(m | v), 1))
    if mode == "empty" and r.ok and pred.isolation is not None:  # what was taken for the object
        rec["found"] = _found_on(np.asarray(pred.isolation.mask, dtype=bool), scene)
    if r.ok and mode != "empty":
        ev = evaluate_fit(r, scene.frame.gt)
        rec["rot_deg"] = float(np.mean([p.rot_deg for p in ev.parts]))
        errs = [j.state_err for j in ev.joints if np.isfinite(j.state_err)]
        rec["state_err"] = float(np.mean(errs)) if errs else None
    return rec


def wrong_success(record: dict) -> bool:
    """Whether a run reported ``success`` on the wrong thing or far off: an ``auto`` run whose isolated mask has an
    IoU below :data:`WRONG_MASK_IOU` with the object's visible pixels, or any run of a scene with the object whose mean
    part rotation is more than :data:`WRONG_ROTATION_DEG` off. ``False`` for a run that did not succeed."""
    if not record["ok"] or record["mode"] == "empty":
        return False
    iou, rot = record.get("mask_iou"), record.get("rot_deg")
    return (record["mode"] == "auto" and iou is not None and iou < WRONG_MASK_IOU) or (rot is not None and rot > WRONG_ROTATION_DEG)


def _found_on(mask, scene) -> str:
    """``"clutter:<kind>"`` when most of ``mask`` shows one clutter piece, else ``"surroundings"`` (walls, supports)."""
    labels = scene.clutter[mask] if scene.clutter is not None else np.empty(0, int)
    counts = np.bincount(labels[labels >= 0], minlength=len(scene.clutter_kinds))
    if len(counts) and counts.max() > 0.5 * max(np.count_nonzero(mask), 1):
        return "clutter:" + scene.clutter_kinds[int(counts.argmax())]
    return "surroundings"


def measure_scenes(categories, frames: int = 20, *, seed: int = 0, progress=None) -> dict:
    """Run the scene benchmark (module docstring).

    Parameters
    ----------
    categories : sequence of str
        Categories with shipped weights.
    frames : int
        Scenes per category (test frames ``0 .. frames - 1`` of the seed's stream).
    seed : int
        The test stream's seed; scene ``i``'s surroundings and noise come from ``(seed, i, the category)``.
    progress : callable, optional
        Called with a line per category.

    Returns
    -------
    dict
        ``{"records": [...], "settings": {...}}``.
    """
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.noise import DepthNoise, apply_noise
    from ..data.scenes import render_scene
    from ..learned.inference.predict import predict_depth
    from ..learned.inference.provider import LearnedProvider

    if isinstance(frames, bool) or int(frames) != frames or frames < 1:
        raise ValueError(f"frames: expected a positive integer, got {frames!r}")
    records, hidden = [], []
    for category in categories:
        provider = LearnedProvider(category, seed=seed, refine="auto")
        gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=seed))
        for i in range(int(frames)):
            key = [seed, i, zlib.crc32(category.encode())]  # each category's scenes differ (walls, stairs, clutter)
            scenes = {w: render_scene(gen, i, np.random.default_rng(key), with_object=w) for w in (True, False)}
            noise_rng = np.random.default_rng(key + [1])
            depth = apply_noise(scenes[True].depth, DepthNoise(), noise_rng)
            empty = apply_noise(scenes[False].depth, DepthNoise(), noise_rng)
            visible = scenes[True].visible & (depth > 0)
            if np.count_nonzero(visible) < MIN_VISIBLE_PIXELS:  # the clutter hides the object
                hidden.append({"category": category, "frame": int(i), "visible_pixels": int(np.count_nonzero(visible))})
                continue
            for mode in MODES:
                t0 = time.perf_counter()
                pred = predict_depth(empty if mode == "empty" else depth, scenes[True].intrinsics, category,
                                     mask=visible if mode == "mask" else None, provider=provider, seed=i)
                records.append(_record(pred, scenes[mode != "empty"], category, i, mode, time.perf_counter() - t0))
        if progress is not None:
            sel = [r for r in records if r["category"] == category]
            progress(f"{category}: " + ", ".join(
                f"{m} {sum(r['ok'] for r in sel if r['mode'] == m)}/{frames} success" for m in MODES))
    return {"records": records, "hidden": hidden,
            "settings": {"categories": list(categories), "frames": int(frames), "seed": int(seed)}}


def load_scenes_records(path) -> tuple[dict, Provenance]:
    """The results and provenance of a report's JSON (:func:`write_scenes_report`), to write the report again from
    its records (``ancsh bench scenes --records``) without fitting the scenes again.

    Raises
    ------
    ValueError
        When ``path`` is missing or not such a file (naming it).
    """
    import json

    try:
        data = json.loads(Path(path).read_text())
        results = {"records": data["records"], "hidden": data.get("hidden") or [], "settings": data["settings"]}
        if data.get("stress") is not None:
            results["stress"] = data["stress"]
        prov = Provenance(data["command"], date=data["date"], machine=data["machine"])
    except (OSError, KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"--records: {path} is not the JSON of an `ancsh bench scenes` report ({exc})") from exc
    return results, prov


def merge_scenes_records(parts) -> tuple[dict, Provenance]:
    """One report's results from runs of the same settings on different categories (``(results, provenance)`` of
    :func:`load_scenes_records` each: a 2-core machine runs the categories as two processes), their records in the
    runs' order; the provenance joins their commands (``;``) and keeps the first run's date and machine.

    Raises
    ------
    ValueError
        Naming ``--records``, for runs of other settings (frames, seeds, stress scenes), runs that share a category,
        or a run with stress scenes beside one without.
    """
    parts = list(parts)
    if len(parts) == 1:
        return parts[0]

    def settings(results, key=None):
        block = results if key is None else results.get(key)
        return None if block is None else {k: v for k, v in block["settings"].items() if k != "categories"}

    first = parts[0][0]
    seen = []
    for results, _ in parts:
        for key in (None, "stress"):
            if settings(results, key) != settings(first, key):
                what = "stress scenes" if key else "scenes"
                raise ValueError(f"--records: the runs' {what} have other settings ({settings(first, key)} and "
                                 f"{settings(results, key)}); merge runs of one command on other --categories only")
        shared = sorted(set(seen) & set(results["settings"]["categories"]))
        if shared:
            raise ValueError(f"--records: {', '.join(shared)} measured in two runs; merge runs of other --categories")
        seen += list(results["settings"]["categories"])
    merged = {"records": [r for results, _ in parts for r in results["records"]],
              "hidden": [h for results, _ in parts for h in results["hidden"]],
              "settings": {**first["settings"], "categories": seen}}
    if "stress" in first:
        merged["stress"] = {"records": [r for results, _ in parts for r in results["stress"]["records"]],
                            "hidden": [h for results, _ in parts for h in results["stress"].get("hidden", [])],
                            "settings": {**first["stress"]["settings"],
                                         "categories": [c for results, _ in parts
                                                        for c in results["stress"]["settings"]["categories"]]}}
    prov = parts[0][1]
    return merged, Provenance("; ".join(p.command for _, p in parts), date=prov.date, machine=prov.machine)


def side_by_side(results: dict, real_frames) -> list:
    """Markdown lines: the real frames (a ``bench real-frames`` JSON, ``real_frames``: its path) beside the single-object
    and stress scenes, per way of asking (with the object's mask, without one, with a pixel hint): successes that are
    right, wrong successes, and scenes or frames without the object reported as one."""
    import json

    data = json.loads(Path(real_frames).read_text())
    real = [r for r in data["records"] if r.get("truth_category")]
    negative = [r for r in data["records"] if not r.get("truth_category")]

    def share(rows, good):
        return f"{sum(map(good, rows))}/{len(rows)}" if rows else "-"

    recs = results["records"]
    single = {m: [r for r in recs if r["mode"] == m] for m in MODES}
    lines = ["## Real frames and rendered scenes side by side", "",
             f"The real frames from `{Path(real_frames).name}` (`{data.get('command', '?')}`, {data.get('date', '?')}; "
             "right = `success`, its joint error in the last column); the scenes as above (right = `success` and not "
             "wrong). Empty: frames or scenes without the object (the real negative frame once per category).", "",
             "| source | with mask: right | without: right (wrong) | with a hint: right | empty: false success "
             "| joint error of the real successes (deg) |", "|---|---|---|---|---|---|"]
    by = {m: [r for r in real if r["mode"] == m] for m in ("mask", "auto", "pixel")}
    errs = [r["joint_state_error_deg"] for r in real if r["ok"] and r.get("joint_state_error_deg") is not None]
    lines.append(f"| real frames | {share(by['mask'], lambda r: r['ok'])} | {share(by['auto'], lambda r: r['ok'])} "
                 f"| {share(by['pixel'], lambda r: r['ok'])} | {share(negative, lambda r: r['ok'])} "
                 f"| {', '.join(f'{e:.1f}' for e in errs) or '-'} |")
    lines.append(f"| single-object scenes | {share(single['mask'], lambda r: r['ok'] and not wrong_success(r))} "
                 f"| {share(single['auto'], lambda r: r['ok'] and not wrong_success(r))} "
                 f"({sum(map(wrong_success, single['auto']))}) | - | {share(single['empty'], lambda r: r['ok'])} | - |")
    stress = results.get("stress")
    if stress is not None:
        seed0 = stress["settings"]["seeds"][0]
        st = {m: [r for r in stress["records"] if r["mode"] == m and r["object"] is not None
                  and (m != "auto" or r["seed"] == seed0)] for m in ("mask", "auto", "hint")}
        wrong = sum(r["ok"] and r["wrong"] for r in stress["records"] if r["mode"] == "auto" and r["seed"] == seed0)
        empty = [r for r in stress["records"] if r["mode"] == "empty"]
        right = (lambda r: r["found"] and not r["wrong"])
        lines.append(f"| stress scenes (objects) | {share(st['mask'], right)} | {share(st['auto'], right)} ({wrong}) "
                     f"| {share(st['hint'], right)} | {share(empty, lambda r: r['ok'])} | - |")
    return lines + [""]


def write_scenes_report(results: dict, path, provenance: Provenance, *, rewritten_by: str | None = None,
                        real_frames=None) -> Path:
    """Markdown at ``path`` and the records as JSON beside it.

    ``provenance``: the measuring run's -- this run's (``Provenance(command)``), or, when the report is written again
    from its records (:func:`load_scenes_records`) by the command ``rewritten_by``, the one stored with them.
    ``real_frames``: a ``bench real-frames`` JSON to summarise beside the scenes (:func:`side_by_side`).
    """
    path = Path(path)
    recs = results["records"]
    n = results["settings"]["frames"]
    lines = [
        "# Rendered scenes: `ancsh predict` without a mask", "",
        f"Command: `{provenance.command}`  ",
        f"Date: {provenance.date}; machine: {provenance.machine_text}  ",
        *([f"Report written again from the records by `{rewritten_by}`  "] if rewritten_by else []),
        "Study: `ancsh.studies.scenes` (scenes: `ancsh.data.scenes.render_scene`)", "",
        "## Single objects", "",
        f"{n} test frames per category, each in a scene: on a floor or (one in three) the lowest tread of a staircase, a "
        "wall or a curtain behind, up to two pieces of clutter beside; the dataset's sensor noise. `mask`: predicted "
        "with the object's visible pixels as the mask; `auto`: without a mask (isolation and verification, as a user "
        "runs `ancsh predict`); `empty`: the same scene without the object, where `success` is a false report. "
        "Rotation: the mean over the parts; state: the mean joint-state error (degrees; object units for prismatic "
        "joints); medians over the frames that succeeded. Mask IoU: the isolated pixels against the object's visible "
        "ones (median over every `auto` run). Time: median per run (ms). *Wrong*: a `success` on the wrong thing or far "
        f"off (an `auto` mask IoU below {WRONG_MASK_IOU:g}, or a mean part rotation over {WRONG_ROTATION_DEG:g}°); what a user "
        "should not have been told: with `no_object` they look again, with a wrong success they act on it.", "",
        "| category | mask: success (wrong) | auto: success (wrong) | auto: mask IoU | rotation (°): mask / auto "
        "| state: mask / auto | empty: false success | time (ms): mask / auto |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in results["settings"]["categories"]:
        by = {m: [r for r in recs if r["category"] == c and r["mode"] == m] for m in MODES}
        ok = {m: [r for r in by[m] if r["ok"]] for m in MODES}
        lines.append(
            f"| {c} | {len(ok['mask'])}/{len(by['mask'])} ({sum(map(wrong_success, ok['mask']))}) "
            f"| {len(ok['auto'])}/{len(by['auto'])} ({sum(map(wrong_success, ok['auto']))}) "
            f"| {median_text([r['mask_iou'] for r in by['auto']], '.2f')} "
            f"| {median_text([r['rot_deg'] for r in ok['mask']])} / {median_text([r['rot_deg'] for r in ok['auto']])} "
            f"| {median_text([r['state_err'] for r in ok['mask']], '.3g')} / {median_text([r['state_err'] for r in ok['auto']], '.3g')} "
            f"| {len(ok['empty'])}/{len(by['empty'])} "
            f"| {median_text([r['time_ms'] for r in by['mask']], '.0f')} / {median_text([r['time_ms'] for r in by['auto']], '.0f')} |")
    stairs = [r for r in recs if r["mode"] == "auto" and r["support"] == "stairs"]
    floor = [r for r in recs if r["mode"] == "auto" and r["support"] == "floor"]
    hidden = results.get("hidden") or []
    if hidden:
        lines += ["", f"Left out: {len(hidden)} scene(s) whose clutter hides the object (fewer than {MIN_VISIBLE_PIXELS} "
                  "of its pixels visible): " + ", ".join(f"{h['category']} {h['frame']}" for h in hidden) + "."]
    auto = [r for r in recs if r["mode"] == "auto"]
    lines += ["", "By support (`auto`, every category): "
              f"floor {sum(r['ok'] for r in floor)}/{len(floor)} success ({sum(map(wrong_success, floor))} wrong), mask IoU "
              f"{median_text([r['mask_iou'] for r in floor], '.2f')}; "
              f"stairs {sum(r['ok'] for r in stairs)}/{len(stairs)} success ({sum(map(wrong_success, stairs))} wrong), mask IoU "
              f"{median_text([r['mask_iou'] for r in stairs], '.2f')}. Right successes without a mask, every category: "
              f"{sum(r['ok'] and not wrong_success(r) for r in auto)}/{len(auto)}.", ""]
    false = [r for r in recs if r["mode"] == "empty" and r["ok"] and r.get("found")]
    if false:
        import collections

        counts = collections.Counter(r["found"] for r in false)
        lines += ["Empty scenes reported as an object, by what was taken for it (`clutter:<kind>`: most of the isolated "
                  "pixels show that clutter piece -- a closed box and a `box` piece look alike in depth; "
                  "`surroundings`: the walls, floor or stairs): "
                  + ", ".join(f"{k} {n}" for k, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))) + ".", ""]
    if results.get("stress") is not None:
        from .stress_scenes import stress_table

        lines += stress_table(results["stress"])
    if real_frames is not None:
        lines += side_by_side(results, real_frames)
    write_text(path, "\n".join(lines))
    write_json(path.with_suffix(".json"), {"command": provenance.command, "date": provenance.date,
                                           "machine": provenance.machine, "settings": results["settings"],
                                           "records": recs, "hidden": hidden, "stress": results.get("stress")}, indent=1)
    return path
