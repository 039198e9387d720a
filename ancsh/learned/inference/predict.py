"""``ancsh predict``: one depth image in, per-part poses, amodal boxes, joints and states out.

Pipeline: read the depth image (16-bit PNG in millimetres by default, or ``.npy`` in metres),
back-project the valid pixels (``depth > 0``, finite, inside the optional mask and below the optional
``max_depth``), sample ``num_points`` of them with a seed, run the category's shipped ANCSH network
(:class:`~ancsh.learned.inference.provider.LearnedProvider`) and fit a formulation
(:func:`ancsh.solvers.fit`). :meth:`DepthPrediction.to_json` gives the result as plain JSON;
:func:`draw_prediction` draws boxes and joint axes over the depth image and over the point cloud.

Frames: camera (OpenCV: x right, y down, z forward), metres. A part pose maps its NPCS coordinates
``c`` to the camera: ``p = scale * rotation @ c + translation``.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from ...data.images import read_depth, read_intrinsics, read_mask  # noqa: F401 - re-exported
from ...data.render import Intrinsics
from .checks import (  # noqa: F401 - re-exported
    MAX_RELATIVE_RESIDUAL,
    MAX_SPREAD_DEG,
    MIN_INLIER_RATIO,
    MIN_P_OBJECT,
    MIN_P_OBJECT_MASKED,
    NEAR_CLOSED_DEG,
    SIZE_TOLERANCE,
    check_confidence,
    check_plausibility,
    near_closed_notes,
    object_diagonal,
    part_quality,
)
from .category import Category, load_category
from .candidate import (  # noqa: F401 - re-exported
    CONSENSUS_HYPOTHESES,
    MIN_POINTS,
    depth_to_points,
    fit_candidate,
    fit_candidate_refinements,
    infer,
    inflate_uncertainty,
)
from .objects import ObjectCandidate, mask_bbox, mask_rle, same_object, select_objects
from .picture import draw_prediction  # noqa: F401 - re-exported
from .refine_network import DEFAULT_PASSES

__all__ = ["MIN_POINTS", "SIZE_TOLERANCE", "MIN_INLIER_RATIO", "MAX_RELATIVE_RESIDUAL", "MAX_VERIFIED", "MAX_MERGED",
           "MAX_SPREAD_DEG", "MIN_P_OBJECT", "NEAR_CLOSED_DEG",
           "DepthPrediction", "fit_candidate", "make_provider", "fit_candidate_refinements", "check_confidence", "check_plausibility",
           "check_weights_category", "part_quality", "depth_to_points", "draw_prediction", "predict_depth",
           "read_depth", "read_intrinsics", "read_mask"]


#: The plane search of isolation is seeded with this, not with ``seed``: the candidate segments are a function of the
#: image, so the answer does not change with the seed through them (on a frame with a robot arm beside a mug, 2 or 3
#: planes were removed by seed, and with them arm pieces came and went as candidates); ``seed`` drives the sampling and
#: fitting hypotheses of each candidate, whose consensus is the answer.
ISOLATION_SEED = 0
#: Isolation without a hint fits at most this many candidate segments and keeps the best supported.
MAX_VERIFIED = 5
#: When none of them passes, at most this many unions of two that touch (:func:`ancsh.data.isolate.merged_candidate`:
#: an object cut in two by plane removal) are fitted too.
MAX_MERGED = 2
#: ``to_urdf`` with the observed depth: the template is the best of this many nearest by render-and-compare
#: (``docs/results/twin.md``: against the nearest alone; 20 instead of 5 lowered the oracle cabinets' median residual
#: by 1-5 mm for 0.2-0.3 s more per export).
URDF_CANDIDATES = 20
#: ... the best this many aligned to the depth (``align_model``, each at 3 sizes; twin.md: residual 2-4x lower;
#: ~2.7 s of CPU per export; 1.6 s at one size, 0.5 s without aligning).
URDF_ALIGN = 3


# --------------------------------------------------------------------------------------------
# prediction
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DepthPrediction:
    """Result of :func:`predict_depth`.

    Attributes
    ----------
    category : str
        The category's name.
    result : FitResult
        Part poses ``T_cam_npcs``, amodal boxes, camera-frame joints and states, status.
    points_cam : (n, 3) float64
        The sampled points (camera frame, metres).
    pixels : (n, 2) int64
        Their ``(u, v)``.
    part_labels : (n,) int64
        Predicted part of each point.
    part_names, joint_names : tuple of str
    weights : str
        The weights file used.
    valid_pixels : int
    timings_ms : dict
        ``isolate`` (segmenting the image; 0 with a mask), ``verify`` (fitting the candidate segments, all
        of them), ``backproject``, ``network``, ``fit`` (the chosen candidate's), ``total`` (milliseconds).
    joint_types : tuple of str
        ``"revolute"`` / ``"prismatic"`` per joint.
    joint_parents, joint_children : tuple of int
        Part indices joined by each joint.
    joint_rest : tuple of float
        The category's rest state of each joint (NaN when unknown); ``rest_description`` says it in words.
    weights_sha256 : str or None
    notes : tuple of str
        What the user should know (isolation choice, fewer valid pixels than asked for, ...).
    isolation : Isolation or None
        What :func:`ancsh.data.isolate.isolate_object` found, when it ran.
    part_quality : tuple of dict
        Per part: ``points``, ``inlier_ratio``, ``residual_m`` (median distance between each
        observed point and its predicted NPCS mapped by the fitted pose), ``seg_margin`` (mean
        difference of the two highest part probabilities of its points).
    p_good : float or None
        Calibrated probability that every part's rotation error is below 10 deg
        (:mod:`ancsh.learned.inference.confidence`); ``None`` without a calibration for the category or a fit.
    p_object : float or None
        Calibrated probability that the fitted pixels are an object of the category (render-and-compare and
        size, :mod:`ancsh.studies.object_evidence`); ``None`` without that calibration or a fit.
    render_compare : DepthComparison or None
        The fitted category template rendered and compared with the observed depth
        (:func:`ancsh.solvers.twin.compare_fit`), where there is a mask or an isolated segment.
    correspondences : Correspondences or None
        What the fit was made on (its joint tree and types; not in the JSON); ``None`` without a network pass.
    object_id : int
        The object's number in the frame's object list (0: the best supported).
    mask : (H, W) bool or None
        The object's pixels: its isolated segment without occluders and without pixels of a better-supported object,
        the user's mask, or (no isolation) every valid pixel; ``None`` when nothing was found.
    objects : tuple of DepthPrediction
        Every object of the category the frame holds (:func:`predict_depth`), ``objects[0]`` this one; each of them has
        an empty ``objects``. Empty for an object of the list itself.
    consensus : dict or None
        How the object's hypotheses went (:func:`~ancsh.learned.inference.candidate.consensus`): ``hypotheses``,
        ``passed``, ``statuses``, ``chosen``, ``state_std`` (per joint, rad or m: the spread of the passing
        hypotheses' states) and ``rotation_spread_deg`` (per part).
    rejected : tuple of DepthPrediction
        The candidate segments that were fitted and failed a check (``object_id`` -1; their status says which), for
        pictures and the JSON's ``rejected`` list.
    category_info : Category or None
        The category as it was loaded for this prediction (:func:`~ancsh.learned.inference.category.load_category`:
        its convention, calibrations, template), not in the JSON.
    """

    category: str
    result: object
    points_cam: np.ndarray
    pixels: np.ndarray
    part_labels: np.ndarray
    part_names: tuple
    joint_names: tuple
    weights: str
    valid_pixels: int
    timings_ms: dict = field(default_factory=dict)
    joint_types: tuple = ()
    joint_parents: tuple = ()
    joint_children: tuple = ()
    joint_rest: tuple = ()
    rest_description: str = ""
    weights_sha256: str | None = None
    notes: tuple = ()
    isolation: object = None
    part_quality: tuple = ()
    p_good: float | None = None
    p_object: float | None = None
    render_compare: object = None
    correspondences: object = None
    object_id: int = 0
    mask: np.ndarray | None = field(default=None, repr=False)
    objects: tuple = field(default=(), repr=False)
    rejected: tuple = field(default=(), repr=False)
    consensus: dict | None = None
    category_info: Category | None = field(default=None, repr=False)

    def to_urdf(self, folder, **options):
        """:meth:`export_urdf`'s ``.urdf`` path (the same options)."""
        return self.export_urdf(folder, **options)[0]

    def export_urdf(self, folder, *, T_frame_cam=None, root: str = "camera", overwrite: bool = False, observed=None,
                    candidates: int = URDF_CANDIDATES, align: int = URDF_ALIGN, rng=0):
        """Write the fitted object as a URDF folder (:func:`ancsh.solvers.twin.export_fit_urdf`): the category
        template nearest to the fit reshaped to it (with ``observed``, the depth this prediction was made from as an
        :class:`~ancsh.solvers.twin.ObservedDepth`: the one of the ``candidates`` nearest whose render explains that
        depth best, the best ``align`` moved onto it first), the base in the camera frame (or ``root``, the frame of
        ``T_frame_cam``: the camera's pose there), the states in ``joint_states.json`` (the fit's or the aligned model's).

        Returns ``(path, FittedModel)``: the ``.urdf`` file and the model written (its template, whether it was aligned,
        its median |residual| against ``observed``). A failed prediction is refused (``ValueError`` naming its status)."""
        from ...solvers.twin import export_fit_urdf

        if not self.result.ok or self.correspondences is None:
            raise ValueError(f"prediction: a failed prediction (status {self.result.status.value}: {self.result.message}) "
                             "is not exported")
        category = self.category_info if self.category_info is not None else load_category(self.category)
        return export_fit_urdf(self.result, self.correspondences, category.template_library(), folder,
                                  T_frame_cam=T_frame_cam, root=root, name=self.category, overwrite=overwrite,
                                  observed=observed, candidates=candidates if observed is not None else 1,
                                  align=align if observed is not None else 0, rng=rng)

    def object_mask(self, shape) -> np.ndarray | None:
        """The pixels ``(H, W)`` bool this prediction took as the object: :attr:`mask`, else the isolated segment,
        else the sampled points' pixels; ``None`` without points."""
        if self.mask is not None and self.mask.shape == tuple(shape):
            return np.asarray(self.mask, dtype=bool)
        if self.isolation is not None and np.asarray(self.isolation.mask).any():
            return np.asarray(self.isolation.mask, dtype=bool)
        if len(self.pixels) == 0:
            return None
        mask = np.zeros(shape, dtype=bool)
        mask[self.pixels[:, 1], self.pixels[:, 0]] = True
        return mask

    def object_json(self) -> dict:
        """This object's record of the JSON's ``objects`` list (``docs/json_schema.md``): its id, pixel mask, status,
        evidence, parts and joints (plain JSON; NaN -> ``None``)."""
        from ...outputs import json_safe

        r = self.result
        counts = np.bincount(self.part_labels, minlength=len(self.part_names))
        parts = []
        for j, name in enumerate(self.part_names):
            rec = {"name": name, "points": int(counts[j]), "pose": None, "box": None,
                   "quality": self.part_quality[j] if j < len(self.part_quality) else None}
            if j < len(r.T_cam_npcs):
                T = r.T_cam_npcs[j]
                rec["pose"] = {"rotation": T.rotation.tolist(), "translation": T.translation.tolist(), "scale": float(T.scale)}
            if j < len(r.boxes_cam):
                b = r.boxes_cam[j]
                rec["box"] = {"center": b.center.tolist(), "rotation": b.rotation.tolist(), "extents": b.extents.tolist(),
                              "corners": b.corners().tolist()}
            parts.append(rec)
        joints = []
        for k, name in enumerate(self.joint_names):
            jt = self.joint_types[k] if k < len(self.joint_types) else None
            rest = float(self.joint_rest[k]) if k < len(self.joint_rest) else float("nan")
            joints.append({
                "name": name, "type": jt,
                "parent": self.part_names[int(self.joint_parents[k])], "child": self.part_names[int(self.joint_children[k])],
                "axis_cam": r.joint_axes_cam[k].tolist(), "pivot_cam": r.joint_pivots_cam[k].tolist(),
                "state": float(r.joint_states[k]), "state_abs": float(r.joint_states[k]) + rest, "rest": rest,
                "state_unit": "rad" if jt == "revolute" else "m",
            })
        return json_safe({
            "id": int(self.object_id), "status": r.status.value, "ok": bool(r.ok), "message": r.message,
            "mask": None if self.mask is None else mask_rle(self.mask),
            "iterations": int(r.iterations), "max_constraint_violation": float(r.max_constraint_violation),
            "points": int(self.points_cam.shape[0]), "valid_pixels": int(self.valid_pixels),
            "confidence": {"p_good": self.p_good, "good": "every part's rotation error below 10 deg",
                           "calibration": "ancsh calibrate (docs/results/<category>_confidence.md)",
                           "p_object": self.p_object, "object": "the fitted pixels are an object of the category"},
            "render_compare": None if self.render_compare is None else self.render_compare.to_dict(),
            "consensus": self.consensus, "notes": list(self.notes), "parts": parts, "joints": joints,
            "uncertainty": None if getattr(r, "uncertainty", None) is None else r.uncertainty.to_dict(),
            "timings_ms": {k: v for k, v in self.timings_ms.items() if k not in ("isolate", "verify", "total")},
        })

    def to_json(self) -> dict:
        """Plain-JSON description (lists, floats; NaN -> ``None``); the schema is ``docs/json_schema.md``
        (``ancsh.prediction/2``): ``objects`` lists every object found, and the top-level keys of schema 1 (status,
        parts, joints, ...) are the first object's."""
        from ...outputs import json_safe, provenance

        r = self.result
        objects = [o.object_json() for o in (self.objects or (self,))]
        first = dict(objects[0])
        first.pop("id")
        first.pop("mask")
        first.pop("timings_ms")
        data = {
            "schema": "ancsh.prediction/2", **provenance(self.weights, self.weights_sha256),
            "category": self.category, "rest_state": self.rest_description,
            "formulation": r.formulation, "solver": r.solver, **first,
            "objects_found": sum(o["ok"] for o in objects), "objects": objects,
            "rejected": [{"segment": None if o.isolation is None else o.isolation.chosen, "status": o.result.status.value,
                          "message": o.result.message, "bbox": None if o.mask is None else mask_bbox(o.mask)}
                         for o in self.rejected],
            "isolation": None if self.isolation is None else self.isolation.to_dict(),
            "timings_ms": dict(self.timings_ms),
            "frames": "camera frame (x right, y down, z forward), metres; pose maps part NPCS c to the camera: "
                      "p = scale * rotation @ c + translation; joint 'state' relative to the category's rest state "
                      "('rest'), 'state_abs' = state + rest",
        }
        return json_safe(data)



def _loaded(category, provider):
    """``category`` loaded once: the provider's own :class:`~ancsh.learned.inference.category.Category` where
    ``category`` names it (no second read of its calibrations), else :func:`load_category`."""
    info = getattr(provider, "category_info", None)
    if isinstance(category, str) and info is not None and category == info.name:
        return info
    return load_category(category, network_category=None if provider is None else provider.category)


def _refuse_other_network(provider, category: Category, argument: str) -> None:
    """A ``ValueError`` starting with ``argument`` (the option that brought the network) when ``provider`` holds a
    network of another category than ``category``'s (a network that names no category passes)."""
    if provider.category is not None and provider.category != category.name:
        raise ValueError(f"{argument} holds a {provider.category} network, not a {category.name} one")


def check_weights_category(provider, category, weights) -> None:
    """Refuse a weights file trained for another category or predicting another structure than ``category``'s (a
    :class:`~ancsh.learned.inference.category.Category`, or a name, loaded here)."""
    category = load_category(category, network_category=provider.category)
    _refuse_other_network(provider, category, f"weights: {weights}")
    conv = category.convention
    if conv is None:  # a category without a convention: only the network's own category is known
        return
    provider.check_structure(conv.part_names, conv.joint_types, where=f"weights: category {category.name}")


def make_provider(category, *, weights=None, seed: int = 0, refine: str | None = "auto", refiner=None,
                  device="cpu", refine_passes: int = DEFAULT_PASSES):
    """The :class:`~ancsh.learned.inference.provider.LearnedProvider` :func:`predict_depth` makes for these options
    when given none: ``category``'s network (a :class:`~ancsh.learned.inference.category.Category`, or a name, spec
    file or folder, loaded here; or ``weights``, checked to be of that category), the refinement network loaded where
    ``refine="network"``, the category's measured choice otherwise. ``FileNotFoundError``-like errors
    (:func:`~ancsh.learned.network.weights.missing_weights_error`) for a category without a network."""
    from .provider import LearnedProvider
    from ..network.weights import missing_weights_error

    category = load_category(category)
    if weights is None and not category.weights_path().is_file():
        raise missing_weights_error(category.name)
    provider = LearnedProvider(category.weights_path() if weights is None else weights, seed=seed,
                               refine="network" if refine == "network" else "auto", refiner=refiner, device=device,
                               refine_passes=refine_passes, category=category if weights is None else None)
    if weights is not None:
        check_weights_category(provider, category, weights)
    return provider


def predict_depth(depth, intrinsics: Intrinsics, category: str, *, mask=None, max_depth: float | None = None,
                  weights=None, provider=None, formulation: str = "exact_reduced", num_points: int = 1024,
                  seed: int = 0, isolate: bool = True, hint=None, refine: str | None = "provider",
                  refiner=None, device="cpu", refine_passes: int = DEFAULT_PASSES,
                  max_objects: int | None = None, hypotheses: int = CONSENSUS_HYPOTHESES) -> DepthPrediction:
    """Run the learned pipeline on one depth image: the one call for a prediction.

    Without a ``mask``, the object is found first: :func:`ancsh.data.isolate.isolate_object` proposes
    candidate segments (supporting planes removed, the rest split at depth jumps) and up to
    :data:`MAX_VERIFIED` of them (the ones ``hint`` points at, or those whose size fits the category)
    are fitted and judged; the best supported one that passes every check wins, else the status is
    ``no_object``. The chosen segment's pixels that lie in front of the fitted model (render-and-compare: a toy in
    an open box) are left out of the reported object mask (``isolation.mask``) as occluders. A fit that fails a check comes back with a failed status naming it: plausibility
    (:func:`check_plausibility`) and, where the category has an object calibration, ``p_object``
    (:func:`check_confidence`, after render-and-compare of the fitted category template).

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
    category : str
        Object category (a name, or a category spec file / built category folder, registered here); its weights are
        used unless ``weights`` or ``provider`` is given.
    mask : (H, W) bool, optional
        The object's pixels; it wins over isolation.
    max_depth : float, optional
        Metres.
    weights : str or Path, optional
        A weights file instead of the shipped ones.
    provider : LearnedProvider, optional
        A ready provider (reused across calls), of ``category``'s network (another category's is refused).
    formulation : str
        A key of :data:`ancsh.solvers.FORMULATIONS`.
    num_points : int
        Points sampled from the valid pixels.
    seed : int
        Seed of the hypotheses of each candidate (point sampling, RANSAC, refinement); the isolation is seeded with
        :data:`ISOLATION_SEED` (its segments are a function of the image).
    isolate : bool
        Isolate the object when no ``mask`` is given (default). ``False`` uses every valid pixel.
    hint : ObjectHint, optional
        A pixel or box on the object, for isolation.
    refine : str or None
        Refinement of the fit (:meth:`LearnedProvider.refine`): ``"template"`` (the category template),
        ``"network"`` (the refinement network), ``"auto"`` (the one measured to help the category most, or none),
        ``None`` / ``"none"`` (off); default: the provider's option (a provider made here: ``"auto"``).
    refiner : str or Path, optional
        With ``refine="network"`` and no ``provider``: a refinement network's weights file instead of the
        category's shipped ``<category>_refine.pt``.
    device : str
        Where the network runs without a ``provider``: ``"cpu"`` (default), ``"cuda"`` or ``"auto"``.
    refine_passes : int
        With ``refine="network"`` and no ``provider``: passes of the refinement network (default
        :data:`~ancsh.learned.inference.refine_network.DEFAULT_PASSES`; ``docs/results/refine_network.md``).
    max_objects : int, optional
        Without a mask or hint: at most this many objects in :attr:`DepthPrediction.objects` (default: every one that
        passes the verification). A mask or a hint selects one object.
    hypotheses : int
        Independent tries per candidate (samplings of its pixels, network passes, RANSAC and refinement seeds; default
        :data:`~ancsh.learned.inference.candidate.CONSENSUS_HYPOTHESES`): the answer is their consensus
        (:func:`~ancsh.learned.inference.candidate.consensus`), reported in :attr:`DepthPrediction.consensus`. A
        segment found without the user's mask or hint passes only when every hypothesis does; under a mask or hint
        most of them must. 1: a single try, the answer of one seed. Measured on ``bench scenes`` (seed 0; before the
        noise-aware isolation and ``p_object``'s segment model of issue 59, so the figures are that time's), all /
        most of 3 / one hypothesis: stress scenes 26 / 25 / - of 124 objects right, 6 / 12 / - wrong successes;
        single objects 74 / 83 / 84 of 158 right, 10 / 14 / 16 wrong, 8 / 13 / 14 of 158 empty scenes taken for an
        object: fewer right for fewer false reports, the trade the issue's targets (<= 2 % of each) ask for.

    Returns
    -------
    DepthPrediction
        The best-supported object, with every object found in ``objects`` (itself first; module
        :mod:`~ancsh.learned.inference.objects`). When none passes, the best-supported failure alone.

    Raises
    ------
    FileNotFoundError
        No shipped weights for ``category`` (the message names the available ones).
    ValueError
        Bad inputs (shapes, empty depth after masking, depths that look like millimetres, unknown formulation).
    """
    from ...data.images import MAX_PLAUSIBLE_DEPTH
    from ...solvers import FORMULATIONS

    # the category resolved once (a name, a spec file, a built folder, or a Category): nothing below looks a name up
    category = _loaded(category, provider)
    if formulation not in FORMULATIONS:
        raise ValueError(f"formulation: expected one of {sorted(FORMULATIONS)}, got {formulation!r}")
    if max_objects is not None and (isinstance(max_objects, bool) or int(max_objects) != max_objects or max_objects < 1):
        raise ValueError(f"max_objects: expected a positive integer or None, got {max_objects!r}")
    if isinstance(hypotheses, bool) or int(hypotheses) != hypotheses or hypotheses < 1:
        raise ValueError(f"hypotheses: expected a positive integer, got {hypotheses!r}")
    t_start = time.perf_counter()
    if provider is None:
        provider = make_provider(category, weights=weights, seed=seed, refine=refine, refiner=refiner, device=device,
                                 refine_passes=refine_passes)
    else:
        _refuse_other_network(provider, category, "provider:")
    d = np.asarray(depth, dtype=np.float64)
    good = d[np.isfinite(d) & (d > 0)]
    if good.size and float(np.median(good)) > MAX_PLAUSIBLE_DEPTH:
        raise ValueError(f"depth: median depth {float(np.median(good)):.4g} m looks like millimetres; depth is in metres "
                         "(divide by 1000)")
    notes = []
    isolation = None
    t_iso = t_verify = 0.0
    part_names, joint_names = category.names(provider.network.num_parts, len(provider.network.revolute))
    t0 = time.perf_counter()
    if mask is None and isolate:
        from ...data.isolate import isolate_object

        isolation = isolate_object(d, intrinsics, category.size_range, hint=hint, max_depth=max_depth, rng=ISOLATION_SEED)
        t_iso = time.perf_counter() - t0
    elif mask is not None and hint is not None:
        notes.append("a mask was given: the hint is ignored")
    if isolation is None:  # a mask (or every valid pixel, checked as one: no check is skipped): one attempt
        whole = mask if mask is not None else np.isfinite(d) & (d > 0)
        best = fit_candidate(d, intrinsics, whole, category, provider, formulation, num_points, seed, max_depth, refine,
                             hypotheses=hypotheses, **_gate(user_given=mask is not None))
        found, rejected = [ObjectCandidate(None, best, np.asarray(whole, dtype=bool))], []
    elif isolation.chosen is None:  # nothing but planes / noise: no object to fit
        best = fit_candidate(d, intrinsics, None, category, provider, formulation, num_points, seed, max_depth, refine,
                             why=f"no object found ({isolation.reason})")
        found, rejected = [ObjectCandidate(None, best, np.zeros(d.shape, dtype=bool))], []
    else:
        t0 = time.perf_counter()
        found, rejected, isolation = _verify_candidates(
            isolation, hint, d, intrinsics, category, provider, formulation, num_points, seed, max_depth, refine,
            max_objects=1 if hint is not None else max_objects, hypotheses=hypotheses)
        t_verify = time.perf_counter() - t0
    shared = {"category": category, "provider": provider, "valid_notes": notes, "isolation": isolation,
              "joint_names": joint_names, "part_names": part_names, "num_points": num_points,
              "timings": {"isolate": 1e3 * t_iso, "verify": 1e3 * t_verify}}
    objects = [_object_prediction(k, c, shared, d) for k, c in enumerate(found)]
    shared["valid_notes"] = []
    failed = tuple(_object_prediction(-1, c, shared, d, occluders=False) for c in rejected)
    total = 1e3 * (time.perf_counter() - t_start)
    objects = [dataclasses.replace(o, timings_ms={**o.timings_ms, "total": total}) for o in objects]
    return dataclasses.replace(objects[0], objects=tuple(objects), rejected=failed)


def _object_prediction(index: int, found: ObjectCandidate, shared: dict, d, *, occluders: bool = True) -> DepthPrediction:
    """Object ``index`` of :func:`predict_depth`'s list from its candidate (``shared``: what every object has in
    common: the category, provider, isolation, names, notes and the isolation / verification times); ``occluders``:
    leave the pixels in front of the fitted model out of its mask."""
    best, provider, isolation = found.attempt, shared["provider"], shared["isolation"]
    mask = np.asarray(found.mask, dtype=bool)
    if isolation is not None and isolation.chosen is not None and found.segment is not None:
        isolation = isolation.with_choice(found.segment, isolation.reason, isolation.verified)
        if occluders:
            isolation = _without_occluders(isolation, best, d)
        isolation = dataclasses.replace(isolation, mask=isolation.mask & mask)
        mask = isolation.mask
    notes = list(shared["valid_notes"])
    if isolation is not None:
        notes.append(isolation.summary())
    notes += best["notes"]
    num_points = shared["num_points"]
    if 0 < best["valid"] < num_points:
        notes.append(f"{best['valid']} valid pixels, fewer than the {num_points} points asked for: all of them are used "
                     f"(the network pads its input to {provider.network.config.num_points} points with repeats)")
    result = best["result"]
    category, joint_names = shared["category"], shared["joint_names"]
    if result.ok:
        notes += near_closed_notes(category.convention, result, joint_names)
    rest, rest_text = category.rest_states(len(joint_names))
    return DepthPrediction(
        category=category.name, category_info=category, result=result, points_cam=best["pts"], pixels=best["pixels"],
        part_labels=best["labels"],
        part_names=shared["part_names"], joint_names=joint_names, weights=str(provider.network.source),
        valid_pixels=best["valid"],
        timings_ms={**shared["timings"], "backproject": 1e3 * best["t_bp"], "network": 1e3 * best["t_net"],
                    "fit": 1e3 * result.time_s, "render_compare": 1e3 * best["t_compare"]},
        joint_types=best["types"], joint_parents=tuple(int(p) for p in best["parents"]),
        joint_children=tuple(int(c) for c in best["children"]), joint_rest=rest, rest_description=rest_text,
        weights_sha256=getattr(provider.network, "sha256", None), notes=tuple(notes), isolation=isolation,
        part_quality=best["quality"], p_good=best["p_good"], p_object=best["p_object"],
        render_compare=best["comparison"], correspondences=best.get("corr"), object_id=index,
        consensus=best.get("consensus"),
        mask=mask if mask.any() else None,
    )


def _gate(*, user_given: bool) -> dict:
    """:func:`fit_candidate`'s object gate: under the user's mask or hint (``user_given``) ``p_object`` refuses only
    below :data:`MIN_P_OBJECT_MASKED` and most hypotheses must pass; a segment found without help needs
    :data:`MIN_P_OBJECT` and every hypothesis, hypotheses that agree (:data:`MAX_SPREAD_DEG`, else ``ambiguous``),
    and is judged by the calibration's segment model (:func:`~ancsh.learned.inference.confidence.object_model`)."""
    return {"min_p_object": MIN_P_OBJECT_MASKED if user_given else MIN_P_OBJECT, "unanimous": not user_given,
            "segmented": not user_given}


def _score(attempt) -> float:
    """How well a candidate's fit is supported (higher is better; -1 for a failed fit): its calibrated
    ``p_object`` where there is one, else the share of its pixels its rendered template explains times the
    share it does not see through, else 0."""
    if attempt["p_object"] is not None:
        return float(attempt["p_object"]) if attempt["result"].ok else -1.0 + 1e-3 * float(attempt["p_object"])
    if not attempt["result"].ok:
        return -1.0
    c = attempt["comparison"]
    if c is None or not (np.isfinite(c.explained) and np.isfinite(c.see_through)):
        return 0.0
    return float(c.explained * (1.0 - c.see_through))


def _verify_candidates(isolation, hint, d, intrinsics, category, provider, formulation, num_points, seed, max_depth,
                       refine, *, max_objects: int | None = None, hypotheses: int = CONSENSUS_HYPOTHESES) -> tuple:
    """Fit the isolation's candidates and make the object list (the module's verification; see :func:`predict_depth`).

    With a hint, the candidates it points at (the segments under the pixel, from every depth of plane
    removal, or those in the box; up to :data:`MAX_VERIFIED`) are fitted. Without one, up to
    :data:`MAX_VERIFIED` candidates whose size fits the category (or the first, when none does) are
    fitted, skipping one that is mostly an object already passed (:func:`~ancsh.learned.inference.objects.same_object`).
    These cheap checks of the segment alone come before the network, and a segment that fails one is not fitted: one
    that lies behind its surroundings (:func:`ancsh.data.isolate.behind_surroundings`: a wall or a curtain seen around
    nearer things) is no object (``not_this_category``); without a hint, one that runs out of the image
    (:func:`ancsh.data.isolate.out_of_view`: a sliver of wall or floor at the edge) is ``out_of_view``. When
    none passes, up to :data:`MAX_MERGED` unions of two fitted candidates that touch in the image
    (:func:`ancsh.data.isolate.merged_candidate`: an object that plane removal cut in two) are fitted and judged
    alike. Every fit that passes is an object (:func:`~ancsh.learned.inference.objects.select_objects`: best supported
    first, at most ``max_objects``, no pixel in two); when none passes, the best-supported one comes back alone with
    status ``no_object``.

    Returns ``(objects, rejected, isolation)``: lists of :class:`~ancsh.learned.inference.objects.ObjectCandidate`
    (the objects; the fitted candidates that failed) and the isolation with the first object chosen and every judged
    candidate in ``verified``.
    """
    import itertools

    from ...solvers.types import FitStatus

    if hint is not None:
        chosen = list(isolation.hinted[:MAX_VERIFIED]) or isolation.order[:1]
    else:
        chosen = [c for c in isolation.order if isolation.clusters[c].fits_category] or isolation.order[:1]
    from ...data.isolate import behind_surroundings, merged_candidate, out_of_view

    attempts, verified, masks = {}, [], {}

    def judge(isolation, c, mask):
        """Fit candidate ``c`` of ``isolation`` (its pixels ``mask``) and check it; its attempt and evidence go to
        ``attempts`` / ``verified``."""
        masks[c] = mask
        # the cheap checks of the segment alone first: one that fails them never reaches the network
        background, jumps, behind = behind_surroundings(d, mask)
        cut, edge_share = out_of_view(mask, isolation.stride) if hint is None else (False, 0.0)
        if background or cut:
            a = fit_candidate(d, intrinsics, mask, category, provider, formulation, num_points, seed, max_depth,
                              refine, why="not fitted")
            if background:
                status, message = FitStatus.NOT_THIS_CATEGORY, (
                    f"check foreground: the segment lies behind its surroundings ({100 * behind:.0f} % of the depth "
                    f"jumps around it, {100 * jumps:.0f} % of its edge): a background surface, not an object; not "
                    "fitted")
            else:
                status, message = FitStatus.OUT_OF_VIEW, (
                    f"check view: the segment runs out of the image ({100 * edge_share:.0f} % of its outline on the "
                    "image's edge): only part of it is seen, so a fit cannot be checked as a whole object; not "
                    "fitted: give a mask or a --pixel / --box hint to fit it anyway")
            a["result"] = dataclasses.replace(a["result"], status=status, message=message)
        else:
            a = fit_candidate(d, intrinsics, mask, category, provider, formulation, num_points, seed, max_depth,
                              refine, hypotheses=hypotheses, **_gate(user_given=hint is not None))
        attempts[c] = a
        verified.append({"segment": int(c), "status": a["result"].status.value, "p_good": a["p_good"],
                         "p_object": a["p_object"], "score": _score(a), "diagonal_m": isolation.clusters[c].diagonal,
                         "render_compare": None if a["comparison"] is None else a["comparison"].to_dict()})

    for c in chosen:
        if len(attempts) == MAX_VERIFIED:
            break
        mask = isolation.mask_of(c)
        passed = [masks[k] for k, a in attempts.items() if a["result"].ok]
        if passed and same_object(mask, passed):
            continue  # the same object again (another depth of plane removal): not worth a fit
        judge(isolation, c, mask)
    if not any(a["result"].ok for a in attempts.values()):
        merged = 0
        for i, j in itertools.combinations(list(attempts), 2):
            if merged == MAX_MERGED:
                break
            union = merged_candidate(isolation, i, j, d, intrinsics, category.size_range)
            if union is not None:
                isolation, c = union
                judge(isolation, c, isolation.mask_of(c))
                verified[-1]["merged"] = [int(i), int(j)]
                merged += 1
    found = select_objects([ObjectCandidate(c, a, masks[c]) for c, a in attempts.items()], _score,
                           max_objects=max_objects)
    if found:
        best = found[0].segment
        why = (f"{isolation.reason}; of {len(attempts)} candidate(s) fitted, segment {best} is the best supported"
               if len(attempts) > 1 else isolation.reason)
        if len(found) > 1:
            why += f"; {len(found)} objects passed (segments {', '.join(str(f.segment) for f in found)})"
        joined = next((v["merged"] for v in verified if v["segment"] == best and "merged" in v), None)
        if joined is not None:
            why += f" (segments {joined[0]} and {joined[1]} joined: none of the candidates passed alone)"
        rejected = [ObjectCandidate(c, a, masks[c]) for c, a in attempts.items() if not a["result"].ok]
        return found, rejected, isolation.with_choice(best, why, verified)
    best = max(attempts, key=lambda c: _score(attempts[c]))
    failures = "; ".join(f"segment {v['segment']} ({v['diagonal_m']:.2f} m): {v['status']}" for v in verified)
    a = dict(attempts[best])
    a["result"] = dataclasses.replace(a["result"], status=FitStatus.NO_OBJECT, message=(
        f"check object: no candidate passed its checks, the {category.name} is not found ({failures})"))
    isolation = isolation.with_choice(best, f"no candidate passed: the best supported shown ({failures})", verified)
    rejected = [ObjectCandidate(c, a, masks[c]) for c, a in attempts.items() if c != best]
    return [ObjectCandidate(best, a, masks[best])], rejected, isolation


def _without_occluders(isolation, attempt, depth):
    """The isolation with the chosen segment's pixels that lie in front of the fitted model left out of its mask
    (:func:`ancsh.solvers.render_compare.occluding_pixels`: a toy in an open box, a hand on a lid); unchanged when
    the fit failed or was not compared."""
    import dataclasses

    from ...solvers.render_compare import occluding_pixels

    comparison = attempt["comparison"]
    if comparison is None or not attempt["result"].ok or not isolation.mask.any():
        return isolation
    occluded = occluding_pixels(comparison, depth, isolation.mask)
    n = int(np.count_nonzero(occluded))
    if n == 0:
        return isolation
    share = n / max(int(np.count_nonzero(isolation.mask)), 1)
    return dataclasses.replace(isolation, mask=isolation.mask & ~occluded,
                               reason=f"{isolation.reason}; {n} pixels ({100 * share:.0f} %) in front of the fitted "
                                      "model left out as occluders")
