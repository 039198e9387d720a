"""``ancsh calibrate --object``: is the fitted segment an object of the category at all?

The confidence model of :mod:`ancsh.studies.confidence_calibration` (``p_good``) says how good a fit is, from the
fit's evidence, not whether the pixels were a laptop (on a real frame without one, the laptop network fitted a mug
with ``p_good`` 0.99; the calibrations since issue 63 see other categories' frames as bad fits, but their features
are the fit's inliers and margins only). This study trains the second
model, ``p_object``: a logistic regression (scikit-learn) on :data:`~ancsh.learned.inference.confidence.OBJECT_FEATURES`
(render-and-compare of the fitted category template, the fitted size, the fit's inliers and segmentation
margin) with

- **positives**: rendered, noisy depth frames of the category's held-out instances, each object's pixels as
  the mask, as ``ancsh predict --mask`` sees them;
- **negatives**: the same of every *other* procedural category (their held-out instances; as many frames in
  all as positives), and as many rendered clutter frames the size of the category's objects: boxes, slabs,
  cylinders, spheres and (twice as often) flat pieces of wall, board or table top, alone and in pairs;
- **scenes** (``scenes``, off by default): held-out instances in rendered scenes (:func:`ancsh.data.scenes.render_scene`:
  a floor or a staircase, a wall or a curtain, clutter; one, two or three objects of the category in turn,
  :data:`SCENE_COMPANIONS`), isolated without a mask as ``ancsh predict`` does (the candidates it would verify): a
  candidate that is an object (IoU >= :data:`SCENE_OBJECT_IOU` with one object's visible pixels) is a positive, every
  other one (pieces of wall and floor, clutter, an object merged with its surroundings or with another) a negative.
  In a scene the fitted model is compared against surroundings too (a model reaching beyond the object sees through
  to the wall behind it), and the objects stand further away, noisier, than in the masked renders: these examples
  fit a second model, ``calibration["segments"]`` (on every example: the masked renders' too), which judges the
  segments ``ancsh predict`` finds without a mask or hint
  (:func:`~ancsh.learned.inference.confidence.object_model`); the main model, fitted on the masked renders alone,
  judges fits under a user's mask or hint. (One model fitted on every example accepted 58 % of the laptops and 55 % of
  the microwaves fitted as boxes under a mask, against 7-10 % before.)

Every frame is fitted once per refinement (:data:`REFINEMENTS`: the first stage alone, refined against the
category template, refined by the refinement network; each where the category has it), and the model is fitted on
all of them: ``ancsh predict --refine none|template|network|auto`` is judged by one model measured on fits of each
kind. (Measured on the laptop: a model fitted on its refined default fits alone rejected an unrefined fit of a
clean render that the model fitted on unrefined fits accepted.) Calibrations made before this pooling carry no
``refinements`` entry: they were measured on the fits of the category's default refinement at the time. Only fits that pass the
plausibility checks count (the others fail before ``p_object`` is asked). Half of the frames (alternating, a
frame's fits together) fit the model, the other half measure it; ``--install`` writes
``ancsh/weights/<category>_object.json``, which :func:`ancsh.learned.inference.predict.predict_depth` uses.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..data.scenes import clutter_model
from ..learned.inference.confidence import OBJECT_FEATURES, probability_good
from .confidence_calibration import auc, standardised_logistic
from .report import Provenance, write_text

__all__ = ["REFINEMENTS", "auc", "available_refinements", "collect_object_evidence", "fit_object_calibrator",
           "is_scene_source", "load_evidence", "measure", "save_evidence", "write_object_report"]

#: A scene's candidate segment is an object when its IoU with an object's visible pixels reaches this.
SCENE_OBJECT_IOU = 0.5
#: Scene ``i`` holds ``i % (SCENE_COMPANIONS + 1)`` more objects of the category beside its own (side by side or
#: touching, the camera further back; :func:`ancsh.data.scenes.render_scene`): a segment holding two of them is no
#: object.
SCENE_COMPANIONS = 2
#: The scenes are rendered at this many times the frames' pixels along each side (1280x960, as the real sensors'
#: 1280x720 see them).
SCENE_PIXEL_SCALE = 2
#: The refinements whose fits the model is measured on (``LearnedProvider.refine`` options; ``"network"`` where the
#: category ships a refinement network, ``"template"`` where it has a template library).
REFINEMENTS = ("none", "template", "network")


def available_refinements(category: str) -> tuple[str, ...]:
    """The :data:`REFINEMENTS` ``category`` has: ``"none"`` always, the others where their model is shipped."""
    from ..data.templates import library_path
    from ..learned.network.weights import weights_path

    have = {"none": True, "template": library_path(category).is_file(),
            "network": weights_path(category, "refine").is_file()}
    return tuple(r for r in REFINEMENTS if have[r])


def _scene_candidates(depth, intrinsics, visibles, category, provider, seed, refinements=("none",)) -> tuple[list, int]:
    """``([(features, is_object, refinement), ...], failed)`` for the candidates ``ancsh predict`` would verify
    without a mask, each fitted once per refinement of ``refinements``; ``failed`` counts the fits that failed.
    ``visibles``: the (H, W) bool visible pixels of each object of the scene; a candidate is
    an object when its IoU with one of them reaches :data:`SCENE_OBJECT_IOU`. ``category``: the loaded
    :class:`~ancsh.learned.inference.category.Category`."""
    from ..data.isolate import isolate_object
    from ..learned.inference.predict import MAX_VERIFIED

    iso = isolate_object(depth, intrinsics, category.size_range, rng=seed)
    if iso.chosen is None:
        return [], 0
    chosen = [c for c in iso.order if iso.clusters[c].fits_category][:MAX_VERIFIED] or list(iso.order[:1])
    out, failed = [], 0
    for c in chosen:
        mask = iso.mask_of(c)
        iou = max((np.count_nonzero(mask & v) / max(np.count_nonzero(mask | v), 1) for v in visibles), default=0.0)
        for refine, x in _features(depth, intrinsics, mask, category, provider, seed, refinements):
            if x is None:
                failed += 1
                continue
            out.append((x, bool(iou >= SCENE_OBJECT_IOU), refine))
    return out, failed


def _features(depth, intrinsics, mask, category, provider, seed, refinements) -> list:
    """``[(refine, features), ...]``: the object features of ``ancsh predict --mask --refine REFINE`` on one depth
    image for each ``LearnedProvider.refine`` option of ``refinements``, ``None`` where the fit fails its checks
    (among them fewer valid pixels than ``MIN_POINTS``; the network pass and first-stage fit are shared by the
    options)."""
    from ..learned.inference.candidate import fit_candidate_refinements, object_feature_vector

    fits = fit_candidate_refinements(depth, intrinsics, mask, category, provider, "exact_reduced", 1024, seed, None,
                                     refinements, object_gate=False)
    return [(refine, object_feature_vector(a["result"], a["comparison"], depth, mask, a["quality"], category, a["pts"])
             if a["result"].ok and a["comparison"] is not None else None) for refine, a in zip(refinements, fits)]


def collect_object_evidence(category: str, frames: int, *, seed: int = 11, progress: bool = True, scenes: int = 0,
                            refinements=None) -> dict:
    """Features of positives and negatives (module docstring): ``frames`` positive frames, about as many negatives,
    each frame fitted once per refinement.

    Parameters
    ----------
    refinements : sequence of str, optional
        ``LearnedProvider.refine`` options each frame is fitted with (default: :func:`available_refinements`).

    Returns
    -------
    dict
        One row per fit that passed its checks: ``{"X": (F, D), "is_object": (F,) bool, "source": [str],
        "refinement": [str], "frame": (F,) int (the frame's index: a frame's fits share it), "failed": {source:
        fits}, "refinements": [str]}``.
    """
    from tqdm import tqdm

    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.noise import DepthNoise, apply_noise
    from ..data.conventions import convention
    from ..data.procedural import CATEGORIES
    from ..data.render import Intrinsics, ModelRenderer, sample_viewpoint
    from ..learned.inference.category import load_category
    from ..learned.inference.provider import LearnedProvider

    if isinstance(frames, bool) or int(frames) != frames or frames < 8:
        raise ValueError(f"frames: expected an integer >= 8, got {frames!r}")
    refinements = available_refinements(category) if refinements is None else tuple(refinements)
    unknown = [r for r in refinements if r not in REFINEMENTS]
    if not refinements or unknown:
        raise ValueError(f"refinements: expected a non-empty selection of {REFINEMENTS}, got {list(refinements)!r}")
    loaded = load_category(category)
    provider = LearnedProvider(loaded.weights_path(), seed=seed, refine="auto", category=loaded)
    others = [c for c in CATEGORIES if c != category]
    per_other = max(4, int(frames) // len(others))
    n_clutter = int(frames)
    jobs = [(category, i) for i in range(int(frames))] + [(c, i) for c in others for i in range(per_other)]
    jobs += [("clutter", i) for i in range(n_clutter)]
    rng = np.random.default_rng(seed)
    noise = DepthNoise()
    gens = {}
    X, y, src, ref, index, failed = [], [], [], [], [], {}

    def add(x, is_object, source, refine, frame):
        X.append(x)
        y.append(is_object)
        src.append(source)
        ref.append(refine)
        index.append(frame)

    for frame_index, (source, i) in enumerate(tqdm(jobs, desc=f"object evidence {category}", disable=not progress,
                                                   dynamic_ncols=True)):
        if source == "clutter":
            model = clutter_model(rng, convention(category).typical_size)
            T = sample_viewpoint(category, rng, model, np.zeros(0))
            intr = Intrinsics()
            depth = ModelRenderer(model).render(np.zeros(0), T, intr).depth
        else:
            gen = gens.setdefault(source, FrameGenerator(GenerationConfig(category=source, split="test", seed=seed)))
            frame = gen.frame(i)
            _, renderer = gen.instance(frame.instance_index)
            intr = frame.intrinsics
            depth = renderer.render(frame.joint_states_abs, frame.T_cam_base, intr).depth
        depth = apply_noise(depth, noise, rng)
        for refine, x in _features(depth, intr, depth > 0, loaded, provider, i, refinements):
            if x is None:
                failed[source] = failed.get(source, 0) + 1
            else:
                add(x, source == category, source, refine, frame_index)
    from ..data.scenes import render_scene

    scene_gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=seed + 1))
    for i in tqdm(range(int(scenes)), desc=f"object evidence {category}: scenes", disable=not progress,
                  dynamic_ncols=True):
        scene = render_scene(scene_gen, i, rng, companions=i % (SCENE_COMPANIONS + 1), pixel_scale=SCENE_PIXEL_SCALE)
        depth = apply_noise(scene.depth, noise, rng)
        found, n_failed = _scene_candidates(depth, scene.intrinsics, [o.visible & (depth > 0) for o in scene.objects],
                                            loaded, provider, i, refinements)
        if n_failed:
            failed["scene"] = failed.get("scene", 0) + n_failed
        for x, is_object, refine in found:
            add(x, is_object, f"{category} in a scene" if is_object else "scene: not the object", refine, len(jobs) + i)
    return {"X": np.asarray(X).reshape(-1, len(OBJECT_FEATURES)), "is_object": np.asarray(y, dtype=bool), "source": src,
            "refinement": ref, "frame": np.asarray(index, dtype=np.int64), "failed": failed,
            "refinements": list(refinements)}


def is_scene_source(source: str) -> bool:
    """Whether an example's ``source`` (:func:`collect_object_evidence`) is a rendered scene's candidate segment."""
    return source.endswith(" in a scene") or source.startswith("scene:")


def save_evidence(data: dict, path) -> Path:
    """Write :func:`collect_object_evidence`'s ``data`` to ``path`` (``.npz``): ``ancsh calibrate --object --evidence``
    fits a model on it again without fitting the frames."""
    import io

    from ..outputs import write_bytes_atomically

    buffer = io.BytesIO()
    np.savez_compressed(buffer, X=np.asarray(data["X"], dtype=np.float64), is_object=np.asarray(data["is_object"], bool),
                        frame=np.asarray(data["frame"], dtype=np.int64), source=np.asarray(data["source"], dtype=str),
                        refinement=np.asarray(data["refinement"], dtype=str), features=np.asarray(OBJECT_FEATURES),
                        refinements=np.asarray(data["refinements"], dtype=str),
                        failed=np.asarray(json.dumps(data["failed"], sort_keys=True)))
    write_bytes_atomically(Path(path), buffer.getvalue())
    return Path(path)


def load_evidence(path) -> dict:
    """:func:`save_evidence`'s file as :func:`collect_object_evidence`'s dict; a clear error (naming ``evidence``) for a
    file that is not one, or one of other features."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"evidence: {path} is not a file (an <category>_object_evidence.npz that ancsh calibrate "
                         "--object wrote)")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as e:
        raise ValueError(f"evidence: {path} is not an object evidence file ({e})") from None
    missing = {"X", "is_object", "frame", "source", "refinement", "features", "refinements", "failed"} - set(data)
    if missing:
        raise ValueError(f"evidence: {path} lacks {', '.join(sorted(missing))}; write it with ancsh calibrate --object")
    if list(data["features"]) != list(OBJECT_FEATURES):
        raise ValueError(f"evidence: {path} holds the features {list(data['features'])}, this version's are "
                         f"{list(OBJECT_FEATURES)}: collect them again")
    return {"X": data["X"], "is_object": data["is_object"], "frame": data["frame"], "source": data["source"].tolist(),
            "refinement": data["refinement"].tolist(), "refinements": data["refinements"].tolist(),
            "failed": json.loads(str(data["failed"]))}


def fit_object_calibrator(X, is_object) -> dict:
    """Standardised logistic regression of ``is_object`` on ``X`` (the format of the ``p_good`` calibration)."""
    y = np.asarray(is_object, dtype=bool)
    if y.all() or not y.any():
        raise ValueError("is_object: both objects of the category and other things are needed")
    return {"features": list(OBJECT_FEATURES), "meaning": "P(the fitted pixels are an object of the category)",
            **standardised_logistic(X, y, balanced=True), "frames": int(len(y)), "object_rate": float(y.mean())}


def measure(calibration: dict, X, is_object, source, threshold: float, refinement=None) -> dict:
    """Per source on the check frames: fits and the share accepted (``p_object >= threshold``); ``"_all"``: the
    shares of objects and of other things accepted and the :func:`auc`; with ``refinement`` (a refinement per row),
    ``"_refinement"``: those per refinement."""
    p = np.array([probability_good(calibration, x) for x in np.asarray(X)])
    y = np.asarray(is_object, dtype=bool)

    def shares(sel):
        obj, other = sel & y, sel & ~y
        return {"true_accept": float(np.mean(p[obj] >= threshold)) if obj.any() else float("nan"),
                "false_accept": float(np.mean(p[other] >= threshold)) if other.any() else float("nan"),
                "auc": auc(p[obj], p[other]), "objects": int(obj.sum()), "others": int(other.sum())}

    out = {}
    for s in sorted(set(source)):
        sel = np.array([t == s for t in source])
        out[s] = {"frames": int(sel.sum()), "accepted": float(np.mean(p[sel] >= threshold)), "p_mean": float(p[sel].mean())}
    out["_all"] = shares(np.ones(len(y), dtype=bool))
    if refinement is not None:
        refinement = list(refinement)
        out["_refinement"] = {r: shares(np.array([t == r for t in refinement])) for r in dict.fromkeys(refinement)}
    return out


def write_object_report(category: str, calibration: dict, check: dict, data: dict, out_dir, *, command: str,
                        threshold: float, installed: dict | None = None, check_segments: dict | None = None) -> dict:
    """``<category>_object.md`` and ``<category>_object.json`` in ``out_dir``; returns their paths.

    ``check``: :func:`measure` of the main model on the check frames' masked renders; ``installed``: the same of the
    model shipped before this run (compared beside the new one in the per-refinement table), or ``None``;
    ``check_segments``: :func:`measure` of the segment model (``calibration["segments"]``) on every check example,
    scenes' segments included, or ``None`` without scenes."""
    out = Path(out_dir)
    prov = Provenance(command)
    paths = {"md": out / f"{category}_object.md", "json": out / f"{category}_object.json"}
    write_text(paths["json"], json.dumps(calibration, indent=1) + "\n")
    def source_rows(check):
        return "\n".join(f"| {s} | {'yes' if s.split(' ')[0] == category else 'no'} | {r['frames']} | "
                         f"{r['p_mean']:.2f} | {100 * r['accepted']:.0f}% |" for s, r in check.items() if not s.startswith("_"))

    rows = source_rows(check)
    by_refinement = check.get("_refinement") or {}
    before = (installed or {}).get("_refinement") or {}

    def cells(v) -> tuple[str, str, str]:
        """Objects accepted, other things accepted, AUC ("-" where not measured)."""
        t, f, a = v["true_accept"], v["false_accept"], v["auc"]
        return (f"{100 * t:.0f}%" if t == t else "-", f"{100 * f:.0f}%" if f == f else "-", f"{a:.3f}" if a == a else "-")

    refinement_table = ""
    for r, v in by_refinement.items():
        accepted, others, area = cells(v)
        refinement_table += f"| {r} | {v['objects']} | {accepted} | {v['others']} | {others} | {area} |"
        if before:
            refinement_table += f" {' | '.join(cells(before[r]))} |" if r in before else " - | - | - |"
        refinement_table += "\n"
    if refinement_table:
        head = f"| refinement | {category} fits | accepted | other fits | accepted | AUC |"
        rule = "|---|---|---|---|---|---|"
        if before:
            head += f" shipped before: {category} fits accepted | other fits accepted | AUC |"
            rule += "---|---|---|"
        refinement_table = ("Per refinement (`ancsh predict --refine`), on the check frames" + (
            " (beside it the model shipped before this run, on the same fits; with the same seed it may have been "
            "fitted on some of them)" if before else "") + ":\n\n" + head + "\n" + rule + "\n" + refinement_table + "\n")
    failed = ", ".join(f"{s} {n}" for s, n in sorted(data["failed"].items())) or "none"
    def coefficients(model):
        return (", ".join(f"{f} {c:+.2f}" for f, c in zip(calibration["features"], model["coef"]))
                + f"; intercept {model['intercept']:+.2f}")

    segments = ""
    if check_segments is not None:
        seg = calibration["segments"]
        segments = (
            "\n## Segments found without a mask (the `segments` model)\n\n"
            "`ancsh predict` without a mask or hint judges the isolation's candidate segments by a second model, "
            f"fitted the same way on every example of the fitting half ({seg['frames']} fits), the rendered scenes' "
            "candidate segments among them: there the fitted model is compared against surroundings too, and the "
            "network sees objects further away and noisier than in the masked renders. On the check half: "
            f"{100 * check_segments['_all']['true_accept']:.0f}% of the objects' fits accepted, "
            f"{100 * check_segments['_all']['false_accept']:.0f}% of the rest (AUC {check_segments['_all']['auc']:.3f}).\n\n"
            "| source | object | check fits | mean p_object | accepted |\n|---|---|---|---|---|\n"
            + source_rows(check_segments) + f"\n\nStandardised coefficients: {coefficients(seg)}.\n")
    write_text(paths["md"], (
        f"# {category}: is it an object of the category? (`p_object`)\n\n"
        f"Command: `{command}`  \nDate: {prov.date}; machine: {prov.machine_text}  \n"
        "Study: `ancsh.studies.object_evidence`\n\n"
        f"A logistic regression (scikit-learn, balanced classes) on {', '.join(OBJECT_FEATURES)} of the {category} "
        f"network's fits to masked, noisy renders, each frame fitted with every refinement of "
        f"{', '.join(data.get('refinements') or ['provider'])} (one model for all): the {category}'s held-out "
        "instances (objects) against the other "
        "categories' held-out instances and rendered clutter of the category's size (not objects); it judges fits "
        "under a user's mask or hint" + (
            ". Fits to the candidate segments of rendered scenes (one to three held-out objects of the category on a floor or a "
            "staircase, a wall or a curtain behind, clutter beside) isolated without a mask (an object's segment "
            "against the rest) fit the second model below" if check_segments is not None else "") + ". Fits that fail "
        f"the plausibility checks never reach `p_object` and are left out (failed fits: {failed}). Fitted on "
        f"{calibration['frames']} fits (half of the frames, alternating), measured on the other half; `ancsh predict` "
        f"reports `not_this_category` below {threshold} without a mask (the acceptance below is measured there); under "
        "a user's mask or hint only below `MIN_P_OBJECT_MASKED` (`docs/results/mask_refusal.md`).\n\n"
        f"On the check frames: {100 * check['_all']['true_accept']:.0f}% of the {category}'s fits accepted, "
        f"{100 * check['_all']['false_accept']:.0f}% of the others' (AUC {check['_all']['auc']:.3f}: the chance that "
        "an object's p_object exceeds another thing's)" + (
            f"; the model shipped before: {100 * installed['_all']['true_accept']:.0f}%, "
            f"{100 * installed['_all']['false_accept']:.0f}%, AUC {installed['_all']['auc']:.3f}" if installed else "")
        + ".\n\n" + refinement_table +
        "| source | object | check fits | mean p_object | accepted |\n|---|---|---|---|---|\n" + rows + "\n\n"
        f"Standardised coefficients: {coefficients(calibration)}.\n" + segments))
    return paths
