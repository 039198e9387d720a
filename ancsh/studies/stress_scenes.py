"""The stress scenes of ``ancsh bench scenes``: several objects of one category, a translucent one, keyed by object.

Standing in for the real scenes the project does not have (two boxes on a table, one translucent; a laptop on a desk),
each test frame of a category is rendered in a scene (:func:`ancsh.data.scenes.render_scene`) of one :data:`KINDS`
kind, in turn: ``pair`` (one more object of the category beside it, or touching it), ``triple`` (two more),
``translucent`` (a pair, one of the two mostly without depth), ``single`` (the frame's object alone); with the dataset's
sensor noise. With companions the camera stands further back, so the objects are smaller and off the image centre. Runs of
:func:`ancsh.learned.inference.predict.predict_depth` per scene:

- ``auto``: without a mask, at each seed of ``seeds``: every object it returns is matched to the truth by mask overlap
  (:func:`match_objects`);
- ``mask`` / ``hint``: per object, its visible pixels as the mask / a pixel hint at its centre (at the first seed);
- ``empty``: the same scene without any object (at the first seed): every ``success`` is a false report.

Records are keyed by object (``frame``, ``object``): per run its status (``missed`` when no returned object is it),
whether it was ``found`` (a success whose mask overlaps it by IoU >= :data:`FOUND_IOU`), ``merged`` (one returned mask
holds :data:`MERGED_SHARE` of it and of another object), its mask IoU and its rotation and joint-state errors
(``ancsh.evaluation.evaluate_fit``; degrees, metres for prismatic joints). A success that is no object of the scene (IoU
below :data:`FOUND_IOU` with every one) or more than :data:`WRONG_ROTATION_DEG` off is *wrong*.
"""

from __future__ import annotations

import time
import zlib

import numpy as np

from .report import median_text

__all__ = ["FOUND_IOU", "KINDS", "MERGED_SHARE", "STAGES", "WRONG_ROTATION_DEG", "candidate_masks", "loss_stage",
           "match_objects", "measure_stress_scenes", "stress_summary", "stress_table"]

#: Scene kinds, in turn over the frames: (name, companions, index of the translucent object or None).
KINDS = (("pair", 1, None), ("triple", 2, None), ("translucent", 1, 1), ("single", 0, None))
#: A returned object is the scene object its mask overlaps by at least this IoU.
FOUND_IOU = 0.5
#: A returned mask holding this share of two scene objects' visible pixels each merged them.
MERGED_SHARE = 0.5
#: A success more than this far off (mean part rotation, degrees) is wrong.
WRONG_ROTATION_DEG = 20.0
#: The scenes are rendered at this many times the frames' pixels along each side (1280x960 from 640x480: the real
#: scenes' sensors are 1280x720).
PIXEL_SCALE = 2
#: A scene object with fewer visible pixels is left out (and counted).
MIN_VISIBLE_PIXELS = 300


def _iou(a, b) -> float:
    return float(np.count_nonzero(a & b) / max(np.count_nonzero(a | b), 1))


def match_objects(masks, oks, visibles) -> tuple[dict, list, set]:
    """Match returned objects to scene objects by mask overlap.

    Parameters
    ----------
    masks : list of (H, W) bool or None
        The returned objects' masks.
    oks : list of bool
        Their successes.
    visibles : list of (H, W) bool
        The scene objects' visible pixels.

    Returns
    -------
    matched : dict
        Scene object -> ``(returned index, IoU)``, each returned object used once, the largest IoUs first (only pairs
        with IoU >= :data:`FOUND_IOU`).
    unmatched : list of int
        Returned objects that are no scene object.
    merged : set of int
        Scene objects of which one returned mask holds :data:`MERGED_SHARE` together with another one's.
    """
    empty = np.zeros_like(visibles[0], dtype=bool) if visibles else None
    ms = [empty if m is None else np.asarray(m, dtype=bool) for m in masks]
    pairs = sorted(((_iou(m, v), i, k) for i, m in enumerate(ms) for k, v in enumerate(visibles)), reverse=True)
    matched, used = {}, set()
    for iou, i, k in pairs:
        if iou < FOUND_IOU:
            break
        if i in used or k in matched:
            continue
        matched[k] = (i, iou)
        used.add(i)
    merged = set()
    for m in ms:
        held = [k for k, v in enumerate(visibles) if np.count_nonzero(m & v) >= MERGED_SHARE * max(np.count_nonzero(v), 1)]
        if len(held) >= 2:
            merged.update(held)
    return matched, [i for i in range(len(ms)) if i not in used], merged


def _errors(result, gt) -> tuple:
    """``(mean part rotation error (deg), mean joint-state error (deg or m), its unit)`` of a successful fit."""
    from ..evaluation import evaluate_fit

    ev = evaluate_fit(result, gt)
    errs = [j.state_err for j in ev.joints if np.isfinite(j.state_err)]
    unit = "m" if ev.joints and all(j.type == "prismatic" for j in ev.joints) else "deg"
    return float(np.mean([p.rot_deg for p in ev.parts])), (float(np.mean(errs)) if errs else None), unit


#: Where an ``auto`` run lost an object (:func:`loss_stage`), in the order of the pipeline.
STAGES = ("right", "wrong fit", "no segment: in a larger one", "no segment: cut up or removed", "segment not fitted",
          "segment refused", "segment passed, not returned")


def loss_stage(isolation, visible, found: bool, wrong: bool, masks=None) -> tuple[str, str | None]:
    """Where an ``auto`` run of ``ancsh predict`` lost a scene object, from its isolation alone (no fit is repeated):
    ``(stage, detail)``, ``stage`` one of :data:`STAGES`.

    ``right`` / ``wrong fit``: a success matched it (``found``), within or beyond :data:`WRONG_ROTATION_DEG`
    (``wrong``). Else, by the candidate segments (:class:`~ancsh.data.isolate.Isolation`): none has an IoU of
    :data:`FOUND_IOU` with the object's ``visible`` pixels -- ``in a larger one`` when one candidate holds
    :data:`MERGED_SHARE` of them (the object merged with another or with its surroundings), else ``cut up or
    removed`` (its pixels in pieces, taken for a support plane, or without depth); ``segment not fitted``: such a
    candidate exists but none was verified; ``segment refused``: they were, and failed (``detail``: the status of the
    one nearest the object); ``segment passed, not returned``: one passed but is not in the object list. ``masks``:
    the candidates' full-resolution pixels (:func:`candidate_masks`), when the caller judges several objects of one
    run."""
    if found:
        return ("wrong fit" if wrong else "right"), None
    vis = np.asarray(visible, dtype=bool)
    n = max(int(np.count_nonzero(vis)), 1)
    ious, held = {}, 0.0
    for c, m in enumerate(candidate_masks(isolation) if masks is None else masks):
        inter = int(np.count_nonzero(m & vis))
        if inter:
            ious[c] = _iou(m, vis)
            held = max(held, inter / n)
    good = {c: v for c, v in ious.items() if v >= FOUND_IOU}
    if not good:
        return ("no segment: in a larger one" if held >= MERGED_SHARE else "no segment: cut up or removed"), None
    verified = {v["segment"]: v["status"] for v in isolation.verified}
    tried = [c for c in sorted(good, key=good.get, reverse=True) if c in verified]
    if not tried:
        return "segment not fitted", None
    if any(verified[c] == "success" for c in tried):
        return "segment passed, not returned", None
    return "segment refused", verified[tried[0]]


def candidate_masks(isolation) -> list:
    """Every candidate segment's full-resolution pixels ``(H, W)`` bool of an isolation (none for ``None``)."""
    return [] if isolation is None else [isolation.mask_of(c) for c in range(len(isolation.clusters))]


def _object_records(pred, scene, base, mode, seed, seconds, only=None) -> list:
    """Records of one run: one per scene object (or only ``only``), plus one per wrong extra success; an ``auto``
    run's records say where it lost each object (``stage``, ``stage_detail``: :func:`loss_stage`)."""
    objects = [o for o in (pred.objects or (pred,))]
    visibles = [o.visible for o in scene.objects]
    matched, unmatched, merged = match_objects([o.mask for o in objects], [o.result.ok for o in objects], visibles)
    out, masks = [], None
    for k, so in enumerate(scene.objects):
        if only is not None and k != only:
            continue
        rec = {**base, "object": k, "placement": so.placement, "translucent": bool(so.translucent), "mode": mode,
               "seed": int(seed), "status": "missed", "ok": False, "found": False, "merged": k in merged,
               "mask_iou": None, "rot_deg": None, "state_err": None, "state_unit": None, "wrong": False,
               "time_ms": 1e3 * seconds}
        if k in matched:
            i, iou = matched[k]
            r = objects[i].result
            rec.update(status=r.status.value, ok=bool(r.ok), mask_iou=iou, found=bool(r.ok))
            if r.ok and so.gt is not None:
                rec["rot_deg"], rec["state_err"], rec["state_unit"] = _errors(r, so.gt)
                rec["wrong"] = rec["rot_deg"] > WRONG_ROTATION_DEG
        elif mode != "auto" and objects and objects[0].result.ok and only is not None:
            # a mask / hint run whose object is not the one asked for: its success is wrong
            rec.update(status=objects[0].result.status.value, ok=True, wrong=True)
        if mode == "auto":
            if masks is None and not rec["found"]:  # upsampled once a run, for all its objects
                masks = candidate_masks(pred.isolation)
            rec["stage"], rec["stage_detail"] = loss_stage(pred.isolation, so.visible, rec["found"], rec["wrong"],
                                                           masks)
        out.append(rec)
    if mode == "auto":
        for i in unmatched:
            if objects[i].result.ok:
                out.append({**base, "object": None, "mode": mode, "seed": int(seed), "status": "success", "ok": True,
                            "wrong": True, "time_ms": 1e3 * seconds})
    return out


def measure_stress_scenes(categories, frames: int = 8, *, seed: int = 0, seeds=(0,), progress=None,
                          pixel_scale: int = PIXEL_SCALE) -> dict:
    """Run the stress scenes (module docstring).

    Parameters
    ----------
    categories : sequence of str
        Categories with shipped weights.
    frames : int
        Scenes per category (test frames ``0 .. frames - 1`` of the seed's stream; kinds in turn).
    seed : int
        The test stream's seed; scene ``i``'s surroundings and noise come from ``(seed, i, the category)``.
    seeds : sequence of int
        ``predict`` seeds of the ``auto`` runs (their agreement is measured).
    progress : callable, optional
        Called with a line per category.
    pixel_scale : int
        :func:`~ancsh.data.scenes.render_scene`'s (default :data:`PIXEL_SCALE`).
    """
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.noise import DepthNoise, apply_noise
    from ..data.scenes import render_scene
    from ..learned.inference.predict import predict_depth
    from ..learned.inference.provider import LearnedProvider
    from ..data.isolate import ObjectHint
    from .real_frames import hint_pixel

    if isinstance(frames, bool) or int(frames) != frames or frames < 1:
        raise ValueError(f"frames: expected a positive integer, got {frames!r}")
    seeds = tuple(int(s) for s in seeds)
    if not seeds:
        raise ValueError("seeds: expected at least one seed")
    records, hidden = [], []
    for category in categories:
        provider = LearnedProvider(category, seed=seed, refine="auto")
        gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=seed))
        for i in range(int(frames)):
            kind, companions, translucent = KINDS[i % len(KINDS)]
            key = [seed, i, zlib.crc32(category.encode()), 0x57]
            scenes = {w: render_scene(gen, i, np.random.default_rng(key), with_object=w, companions=companions,
                                      translucent=translucent, pixel_scale=pixel_scale) for w in (True, False)}
            noise_rng = np.random.default_rng(key + [1])
            depth = apply_noise(scenes[True].depth, DepthNoise(), noise_rng)
            empty = apply_noise(scenes[False].depth, DepthNoise(), noise_rng)
            scene = scenes[True]
            scene = _with_visible(scene, depth)
            if any(np.count_nonzero(o.visible) < MIN_VISIBLE_PIXELS for o in scene.objects):
                hidden.append({"category": category, "frame": int(i), "kind": kind,
                               "visible_pixels": [int(np.count_nonzero(o.visible)) for o in scene.objects]})
                continue
            base = {"category": category, "frame": int(i), "kind": kind, "support": scene.support,
                    "objects": len(scene.objects)}
            for s in seeds:
                t0 = time.perf_counter()
                pred = predict_depth(depth, scene.intrinsics, category, provider=provider, seed=s)
                records += _object_records(pred, scene, base, "auto", s, time.perf_counter() - t0)
            for k, so in enumerate(scene.objects):
                for mode in ("mask", "hint"):
                    t0 = time.perf_counter()
                    extra = {"mask": so.visible} if mode == "mask" else {"hint": ObjectHint(pixel=hint_pixel(so.visible))}
                    pred = predict_depth(depth, scene.intrinsics, category, provider=provider, seed=seeds[0], **extra)
                    if mode == "mask":
                        pred = _masked(pred, so.visible)
                    records += _object_records(pred, scene, base, mode, seeds[0], time.perf_counter() - t0, only=k)
            t0 = time.perf_counter()
            pred = predict_depth(empty, scene.intrinsics, category, provider=provider, seed=seeds[0])
            records.append({**base, "object": None, "mode": "empty", "seed": seeds[0],
                            "objects_found": sum(o.result.ok for o in (pred.objects or (pred,))),
                            "ok": any(o.result.ok for o in (pred.objects or (pred,))),
                            "time_ms": 1e3 * (time.perf_counter() - t0)})
        if progress is not None:
            sel = [r for r in records if r["category"] == category and r["mode"] == "auto" and r["object"] is not None]
            progress(f"{category} (stress): auto {sum(r['found'] and not r['wrong'] for r in sel)}/{len(sel)} objects "
                     "right")
    return {"records": records, "hidden": hidden,
            "settings": {"categories": list(categories), "frames": int(frames), "seed": int(seed), "seeds": list(seeds),
                         "pixel_scale": int(pixel_scale),
                         "kinds": [k[0] for k in KINDS]}}


def _with_visible(scene, depth):
    """The scene with each object's visible pixels restricted to those the noisy depth still measures."""
    import dataclasses

    objects = tuple(dataclasses.replace(o, visible=o.visible & (depth > 0)) for o in scene.objects)
    return dataclasses.replace(scene, objects=objects, visible=objects[0].visible if objects else scene.visible)


def _masked(pred, mask):
    """A masked prediction's object mask is the user's mask (for matching)."""
    import dataclasses

    return dataclasses.replace(pred, mask=np.asarray(mask, dtype=bool), objects=())


def _share(n, d) -> str:
    return f"{n}/{d}" if d else "-"


def stress_summary(records, seeds) -> dict:
    """Headline figures over every category: objects right without a mask (first seed), wrong successes, merged,
    empty scenes taken for an object, seed agreement (share of objects whose ``auto`` status is the same at all seeds
    but at most one in ten) and the median joint-state errors of the successes (deg; m)."""
    first = [r for r in records if r["mode"] == "auto" and r["seed"] == seeds[0]]
    objs = [r for r in first if r["object"] is not None]
    wrong = [r for r in first if r["ok"] and r["wrong"]]
    empty = [r for r in records if r["mode"] == "empty"]
    by_object = {}
    for r in records:
        if r["mode"] == "auto" and r["object"] is not None:
            by_object.setdefault((r["category"], r["frame"], r["object"]), []).append(r["status"])
    agree = [max(st.count(x) for x in st) >= 0.9 * len(st) for st in by_object.values()]
    ok = [r for r in objs if r["found"] and not r["wrong"]]
    return {"objects": len(objs), "right": len(ok), "wrong_successes": len(wrong),
            "successes": sum(r["ok"] for r in first), "merged": sum(r["merged"] for r in objs),
            "empty": len(empty), "empty_false": sum(r["ok"] for r in empty),
            "seed_agreement": (sum(agree), len(agree)),
            "state_deg": median_text([r["state_err"] for r in ok if r["state_unit"] == "deg"]),
            "state_m": median_text([r["state_err"] for r in ok if r["state_unit"] == "m"], ".3f")}


def stress_table(results) -> list:
    """Markdown lines of the stress section of ``docs/results/scenes.md``."""
    recs, settings = results["records"], results["settings"]
    seeds = settings["seeds"]
    lines = ["## Stress scenes: several objects of one category, keyed by object", "",
             "Each test frame in a scene of one kind, in turn: `pair` (one more object of the category beside it or "
             "touching it), `triple` (two more), `translucent` (a pair, one of them mostly without depth), `single`; "
             "with companions the camera stands further back (smaller objects, off the image centre); images at "
             f"{settings.get('pixel_scale', 1)}x the frames' pixels per side (1280x960). Returned objects "
             f"are matched to the scene's by mask IoU (>= {FOUND_IOU:g}); *merged*: one returned mask holds "
             f"{MERGED_SHARE:.0%} of two objects; *wrong*: a success that is no object of the scene or more than "
             f"{WRONG_ROTATION_DEG:g} deg off (mean part rotation).", "",
             f"{settings['frames']} scenes per category (kinds in turn: {', '.join(settings['kinds'])}); `auto` at seeds "
             f"{', '.join(map(str, seeds))}. Per category: scene objects found right without a mask (at seed "
             f"{seeds[0]}; *wrong*: successes that are no object of the scene or far off), merged, with the object's "
             "mask and with a pixel hint (right / objects), empty scenes reported as an object, seed agreement (objects "
             "whose `auto` status is the same at 9 of 10 seeds or more), median joint-state error of the right `auto` "
             "successes (deg; m for prismatic joints) and median time per run (ms).", "",
             "| category | auto: right / objects (wrong) | merged | mask: right | hint: right | empty: false success "
             "| seed agreement | state (deg) | state (m) | time (ms): auto / mask |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for c in settings["categories"]:
        sel = [r for r in recs if r["category"] == c]
        s = stress_summary(sel, seeds)
        per = {m: [r for r in sel if r["mode"] == m and r["object"] is not None] for m in ("mask", "hint")}
        right = {m: sum(r["found"] and not r["wrong"] for r in per[m]) for m in per}
        times = {m: [r["time_ms"] for r in sel if r["mode"] == m] for m in ("auto", "mask")}
        lines.append(f"| {c} | {_share(s['right'], s['objects'])} ({s['wrong_successes']}) | {s['merged']} "
                     f"| {_share(right['mask'], len(per['mask']))} | {_share(right['hint'], len(per['hint']))} "
                     f"| {_share(s['empty_false'], s['empty'])} | {_share(*s['seed_agreement'])} | {s['state_deg']} "
                     f"| {s['state_m']} | {median_text(times['auto'], '.0f')} / {median_text(times['mask'], '.0f')} |")
    s = stress_summary(recs, seeds)
    kinds = []
    for kind in settings["kinds"]:
        k = [r for r in recs if r.get("kind") == kind and r["mode"] == "auto" and r["seed"] == seeds[0]
             and r["object"] is not None]
        kinds.append(f"{kind} {sum(r['found'] and not r['wrong'] for r in k)}/{len(k)}")
    translucent = [r for r in recs if r["mode"] == "auto" and r["seed"] == seeds[0] and r.get("translucent")]
    lines += ["", f"All categories: {_share(s['right'], s['objects'])} objects right without a mask "
              f"({100 * s['right'] / max(s['objects'], 1):.0f} %), {s['wrong_successes']} wrong successes "
              f"({100 * s['wrong_successes'] / max(s['successes'], 1):.0f} % of the successes), {s['merged']} merged "
              f"({100 * s['merged'] / max(s['objects'], 1):.0f} %), empty scenes taken for an object "
              f"{_share(s['empty_false'], s['empty'])}, seed agreement {_share(*s['seed_agreement'])}. By kind: "
              + ", ".join(kinds) + f"; translucent objects {sum(r['found'] and not r['wrong'] for r in translucent)}"
              f"/{len(translucent)}.", ""]
    lines += _stage_table(recs, settings)
    hidden = results.get("hidden") or []
    if hidden:
        lines += [f"Left out: {len(hidden)} scene(s) with an object of fewer than {MIN_VISIBLE_PIXELS} visible pixels: "
                  + ", ".join(f"{h['category']} {h['frame']}" for h in hidden) + ".", ""]
    return lines


def _stage_table(recs, settings) -> list:
    """Markdown lines: where the ``auto`` runs at the first seed lost each object (:func:`loss_stage`), per category
    (records made before the stages were recorded: none)."""
    from collections import Counter

    first = settings["seeds"][0]
    auto = [r for r in recs if r["mode"] == "auto" and r["seed"] == first and r["object"] is not None]
    if not auto or any("stage" not in r for r in auto):
        return []
    lines = [f"Where the objects are lost (`auto`, seed {first}; `ancsh.studies.stress_scenes.loss_stage`, from the "
             "run's isolation: no fit is repeated). *In a larger segment*: no candidate segment has an IoU of "
             f"{FOUND_IOU:g} with the object, one holds {MERGED_SHARE:.0%} of its pixels (merged with another object or "
             "its surroundings); *cut up or removed*: no candidate holds that much of it (in pieces, taken for a "
             "support, or without depth, as translucent objects are); *not fitted*: a good segment was not among those "
             "verified; *refused*: it was, and failed (the statuses of the one nearest the object; `not_this_category` "
             "is `p_object` or the foreground check); *passed, not returned*: it passed but is not in the object "
             "list.", "",
             "| category | objects | right | wrong fit | in a larger segment | cut up or removed | not fitted "
             "| refused | refused by | passed, not returned |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for c in list(settings["categories"]) + ["all"]:
        sel = [r for r in auto if c == "all" or r["category"] == c]
        n = Counter(r["stage"] for r in sel)
        why = Counter(r["stage_detail"] for r in sel if r["stage"] == "segment refused")
        cells = [str(n[st]) for st in STAGES]
        lines.append(f"| {c} | {len(sel)} | " + " | ".join(cells[:6]) + " | "
                     + (", ".join(f"{k} {v}" for k, v in why.most_common()) or "-") + f" | {cells[6]} |")
    return lines + [""]
