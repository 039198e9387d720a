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

import time
from dataclasses import dataclass, field

import numpy as np

from ...data.images import read_depth, read_intrinsics, read_mask  # noqa: F401 - re-exported
from ...data.render import Intrinsics

__all__ = [
    "MIN_POINTS",
    "SIZE_TOLERANCE",
    "MIN_INLIER_RATIO",
    "MAX_RELATIVE_RESIDUAL",
    "DepthPrediction",
    "check_plausibility",
    "check_weights_category",
    "part_quality",
    "depth_to_points",
    "draw_prediction",
    "predict_depth",
    "read_depth",
    "read_intrinsics",
    "read_mask",
]


#: Fewer valid points than this: no fit is tried (status ``too_few_points``).
MIN_POINTS = 100
#: A fit is plausible when the object's box diagonal lies in the category's rest-state range
#: ``diagonal_range`` widened by this factor both ways (articulation changes the box, and real
#: objects vary beyond the procedural ones).
SIZE_TOLERANCE = 1.5
#: Smallest share of inlier points, overall and for every part with at least 20 points.
MIN_INLIER_RATIO = 0.5
#: Largest median residual of a part (with at least 20 points) as a fraction of the category's typical
#: size: on noisy rendered validation frames of the five categories it stays within 0.01-0.08.
MAX_RELATIVE_RESIDUAL = 0.25


# --------------------------------------------------------------------------------------------
# inputs
# --------------------------------------------------------------------------------------------
def depth_to_points(depth, intrinsics: Intrinsics, *, mask=None, max_depth: float | None = None,
                    num_points: int | None = 1024, rng=0) -> tuple[np.ndarray, np.ndarray, int]:
    """Back-project the valid pixels and sample ``num_points`` of them.

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
        Must match the image size.
    mask : (H, W) bool, optional
    max_depth : float, optional
        Pixels deeper than this (metres) are dropped.
    num_points : int or None
        Points to sample without replacement (all of them when fewer are valid); ``None`` = all.
    rng : numpy.random.Generator or int

    Returns
    -------
    points : (n, 3) float64
        Camera frame, metres.
    pixels : (n, 2) int64
        ``(u, v)`` of each point.
    valid : int
        Number of valid pixels before sampling.

    Raises
    ------
    ValueError
        When no valid pixel remains.
    """
    from ...data.render import backproject, valid_depth_pixels
    from ...geometry._checks import check_generator

    d, sel = valid_depth_pixels(depth, intrinsics, mask)
    if max_depth is not None:
        if not (np.isfinite(max_depth) and max_depth > 0):
            raise ValueError(f"max_depth: expected a positive number, got {max_depth}")
        sel &= d <= max_depth
    valid = int(np.count_nonzero(sel))
    if valid == 0:
        raise ValueError("depth: no valid pixel after masking (depth > 0"
                         + (", inside the mask" if mask is not None else "")
                         + (f", depth <= {max_depth} m" if max_depth is not None else "") + ")")
    if num_points is not None:
        if isinstance(num_points, bool) or int(num_points) != num_points or num_points < 1:
            raise ValueError(f"num_points: expected a positive integer, got {num_points!r}")
        if valid > num_points:
            flat = np.flatnonzero(sel)
            pick = check_generator(rng).choice(flat, size=int(num_points), replace=False)
            sel = np.zeros_like(sel)
            sel.ravel()[pick] = True
    pts = backproject(d, intrinsics, mask=sel)  # row-major pixel order, as np.nonzero
    v, u = np.nonzero(sel & (d > 0))
    return pts, np.stack([u, v], axis=1).astype(np.int64), valid


# --------------------------------------------------------------------------------------------
# prediction
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DepthPrediction:
    """Result of :func:`predict_depth`.

    Attributes
    ----------
    category : str
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
        ``isolate`` (0 with a mask), ``backproject``, ``network``, ``fit``, ``total`` (milliseconds).
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

    def to_json(self) -> dict:
        """Plain-JSON description (lists, floats; NaN -> ``None``); the schema is ``docs/json_schema.md``."""
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
        from ...outputs import provenance

        data = {
            "schema": "ancsh.prediction/1", **provenance(self.weights, self.weights_sha256),
            "category": self.category, "rest_state": self.rest_description,
            "formulation": r.formulation, "solver": r.solver, "status": r.status.value, "ok": bool(r.ok),
            "message": r.message, "iterations": int(r.iterations),
            "max_constraint_violation": float(r.max_constraint_violation),
            "points": int(self.points_cam.shape[0]), "valid_pixels": int(self.valid_pixels),
            "confidence": {"p_good": self.p_good, "good": "every part's rotation error below 10 deg",
                           "calibration": "ancsh calibrate (docs/results/<category>_confidence.md)"},
            "notes": list(self.notes), "isolation": None if self.isolation is None else self.isolation.to_dict(),
            "parts": parts, "joints": joints,
            "uncertainty": None if getattr(r, "uncertainty", None) is None else r.uncertainty.to_dict(),
            "timings_ms": dict(self.timings_ms),
            "frames": "camera frame (x right, y down, z forward), metres; pose maps part NPCS c to the camera: "
                      "p = scale * rotation @ c + translation; joint 'state' relative to the category's rest state "
                      "('rest'), 'state_abs' = state + rest",
        }
        from ...outputs import json_safe

        return json_safe(data)



def check_weights_category(provider, category: str, weights) -> None:
    """Refuse a weights file trained for another category or predicting another structure than ``category``'s."""
    from ...data.conventions import convention

    if provider.category is not None and provider.category != category:
        raise ValueError(f"weights: {weights} holds a {provider.category} network, not a {category} one")
    try:
        conv = convention(category)
    except (KeyError, ValueError):  # a category without a convention: only the network's own category is known
        return
    provider.check_structure(conv.part_names, conv.joint_types, where=f"weights: category {category}")


def predict_depth(depth, intrinsics: Intrinsics, category: str, *, mask=None, max_depth: float | None = None,
                  weights=None, provider=None, formulation: str = "exact_reduced", num_points: int = 1024,
                  seed: int = 0, isolate: bool = True, hint=None, refine: str | None = "provider",
                  device="cpu") -> DepthPrediction:
    """Run the learned pipeline on one depth image: the one call for a prediction.

    Without a ``mask``, the object is isolated first (:func:`ancsh.data.isolate.isolate_object`:
    supporting planes removed, the rest clustered, one cluster chosen by ``hint`` or by the
    category's size and centrality). A fit that fails a plausibility check
    (:func:`check_plausibility`) comes back with a failed status naming the check.

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
    category : str
        Object category; its shipped weights are used unless ``weights`` or ``provider`` is given.
    mask : (H, W) bool, optional
        The object's pixels; it wins over isolation.
    max_depth : float, optional
        Metres.
    weights : str or Path, optional
        A weights file instead of the shipped ones.
    provider : LearnedProvider, optional
        A ready provider (reused across calls).
    formulation : str
        A key of :data:`ancsh.solvers.FORMULATIONS`.
    num_points : int
        Points sampled from the valid pixels.
    seed : int
        Sampling, network chunking and RANSAC seed.
    isolate : bool
        Isolate the object when no ``mask`` is given (default). ``False`` uses every valid pixel.
    hint : ObjectHint, optional
        A pixel or box on the object, for isolation.
    refine : str or None
        Category-template refinement of the fit (:meth:`LearnedProvider.refine`): ``"template"``,
        ``"auto"`` (where measured to help), ``None`` / ``"none"`` (off); default: the provider's
        option (a provider made here: ``"auto"``).
    device : str
        Where the network runs without a ``provider``: ``"cpu"`` (default), ``"cuda"`` or ``"auto"``.

    Raises
    ------
    FileNotFoundError
        No shipped weights for ``category`` (the message names the available ones).
    ValueError
        Bad inputs (shapes, empty depth after masking, depths that look like millimetres, unknown formulation).
    """
    from ...data.images import MAX_PLAUSIBLE_DEPTH
    from ...solvers import FORMULATIONS, Observation, fit
    from ...solvers.types import FitResult, FitStatus
    from .provider import LearnedProvider
    from ..network.weights import weights_path

    if formulation not in FORMULATIONS:
        raise ValueError(f"formulation: expected one of {sorted(FORMULATIONS)}, got {formulation!r}")
    t_start = time.perf_counter()
    if provider is None:
        if weights is None and not weights_path(str(category)).is_file():
            from ..network.weights import missing_weights_error

            raise missing_weights_error(category)
        provider = LearnedProvider(category if weights is None else weights, seed=seed, refine="auto", device=device)
        if weights is not None:
            check_weights_category(provider, category, weights)
    d = np.asarray(depth, dtype=np.float64)
    good = d[np.isfinite(d) & (d > 0)]
    if good.size and float(np.median(good)) > MAX_PLAUSIBLE_DEPTH:
        raise ValueError(f"depth: median depth {float(np.median(good)):.4g} m looks like millimetres; depth is in metres "
                         "(divide by 1000)")
    notes = []
    isolation = None
    t_iso = 0.0
    t0 = time.perf_counter()
    if mask is None and isolate:
        from ...data.isolate import isolate_object

        isolation = isolate_object(d, intrinsics, category, hint=hint, max_depth=max_depth, rng=seed)
        t_iso = time.perf_counter() - t0
        mask = isolation.mask
        notes.append(isolation.summary())
    elif mask is not None and hint is not None:
        notes.append("a mask was given: the hint is ignored")
    if isolation is not None and isolation.chosen is None:  # nothing but planes / noise: no object to fit
        pts, pixels, valid = np.zeros((0, 3)), np.zeros((0, 2), dtype=np.int64), 0
    else:
        pts, pixels, valid = depth_to_points(d, intrinsics, mask=mask, max_depth=max_depth, num_points=num_points,
                                             rng=seed)
    t_bp = time.perf_counter() - t0
    if 0 < valid < num_points:
        notes.append(f"{valid} valid pixels, fewer than the {num_points} points asked for: all of them are used "
                     f"(the network pads its input to {provider.network.config.num_points} points with repeats)")
    part_names, joint_names = _names(category, provider.network.num_parts, len(provider.network.revolute))
    if valid < MIN_POINTS:
        K = len(joint_names)
        why = f"no object found ({isolation.reason})" if valid == 0 else f"{valid} valid points"
        result = FitResult.failure(FitStatus.TOO_FEW_POINTS, f"check min_points: {why}, at least "
                                   f"{MIN_POINTS} are needed for a fit", formulation=formulation, solver="none",
                                   num_joints=K, num_points=len(pts))
        labels = np.zeros(len(pts), dtype=np.int64)
        quality = ()
        p_good = None
        t_net = 0.0
        types = tuple("revolute" if r else "prismatic" for r in provider.network.revolute)
        parents, children = provider.network.joint_parents, provider.network.joint_children
    else:
        obs = Observation(pts)
        t0 = time.perf_counter()
        corr, raw = infer(provider, obs)
        t_net = time.perf_counter() - t0
        result = fit(obs, corr, formulation, rng=seed)
        template_fit = False
        if result.ok and formulation != "per_part":
            refined = provider.refine(obs, corr, result, refine=refine, rng=seed)
            if refined is not None:
                result, template_fit = refined.result, refined.accepted
                notes.append(f"category-template refinement: {'kept' if refined.accepted else 'not kept'} "
                             f"({refined.reason}; template {refined.template or 'none'}, {1e3 * refined.time_s:.0f} ms)")
        labels = np.asarray(corr.part_labels)
        quality = part_quality(result, pts, corr, raw)
        result = check_plausibility(result, labels, category, quality)
        result = inflate_uncertainty(result, category, provider, template=template_fit)
        p_good = _p_good(category, quality, getattr(provider.network, "sha256", None)) if result.ok else None
        types = tuple(t.value for t in corr.joint_types)
        parents, children = corr.joint_parents, corr.joint_children
    rest, rest_text = _rest_states(category, len(joint_names))
    return DepthPrediction(
        category=str(category), result=result, points_cam=pts, pixels=pixels, part_labels=labels,
        part_names=part_names, joint_names=joint_names, weights=str(provider.network.source), valid_pixels=valid,
        timings_ms={"isolate": 1e3 * t_iso, "backproject": 1e3 * (t_bp - t_iso), "network": 1e3 * t_net, "fit": 1e3 * result.time_s,
                    "total": 1e3 * (time.perf_counter() - t_start)},
        joint_types=types,
        joint_parents=tuple(int(p) for p in parents),
        joint_children=tuple(int(c) for c in children),
        joint_rest=rest, rest_description=rest_text,
        weights_sha256=getattr(provider.network, "sha256", None), notes=tuple(notes), isolation=isolation,
        part_quality=quality, p_good=p_good,
    )


def inflate_uncertainty(result, category: str, provider, *, template: bool = False, tracked: str | None = None):
    """The fit with its standard deviations inflated by the factors measured for these weights of
    ``category`` (:func:`ancsh.solvers.uncertainty.inflation_for`, matched by SHA-256); raw for other weights.
    ``ancsh predict`` and the :class:`~ancsh.tracking.CategoryTracker` apply it to a learned provider's fits.
    ``template``: the fit was refined by the category template (an accepted
    :meth:`LearnedProvider.refine`), whose covariance is the template ICP's: the factors measured for
    those fits apply (provider ``"learned-template"`` of ``ancsh bench uncertainty``).
    ``tracked``: the source of a warm tracked frame (``"network"``, ``"carried"``, ``"template"``): the
    factors measured on tracked frames of that source (provider ``"learned-tracked-<source>"`` of
    ``ancsh bench tracking --calibration-sequences``) apply where measured, else the single-frame ones."""
    import dataclasses

    from ...solvers.uncertainty import first_measured_inflation, tracked_provider

    if result.uncertainty is None:
        return result
    single = "learned-template" if template else "learned"
    inflation = first_measured_inflation((tracked_provider("learned", tracked) if tracked else None, single), str(category),
                                         weights_sha256=getattr(provider.network, "sha256", None))
    return dataclasses.replace(result, uncertainty=result.uncertainty.inflated(inflation))


def _p_good(category: str, quality, weights_sha256: str | None) -> float | None:
    """Calibrated P(good fit) where ``ancsh/weights/<category>_confidence.json`` exists and was
    calibrated for these weights (``weights_sha256``); ``None`` otherwise."""
    import json

    from .confidence import calibration_path, fit_features, probability_good

    path = calibration_path(category)
    if not path.is_file():
        return None
    calibration = json.loads(path.read_text())
    if calibration.get("weights_sha256") != weights_sha256:
        return None  # calibrated on other weights (e.g. before a retraining): its probabilities would be another net's
    return probability_good(calibration, fit_features(quality, category))


def infer(provider, observation):
    """``(correspondences, raw network prediction)`` of a provider for an observation.

    Uses ``provider.infer`` where the provider has it (it returns both), else ``correspond`` and
    the ``last_prediction`` it keeps (``None`` when it keeps none).
    """
    if hasattr(provider, "infer"):
        inference = provider.infer(observation)
        return inference.correspondences, inference.prediction
    corr = provider.correspond(observation)
    return corr, getattr(provider, "last_prediction", None)


def part_quality(result, points_cam, corr, prediction=None) -> tuple:
    """Per-part evidence for a fit (see :attr:`DepthPrediction.part_quality`); NaN where undefined.

    Parameters
    ----------
    result : FitResult
    points_cam : (N, 3) float64
        Observed points, camera frame, metres.
    corr : Correspondences
        Their part labels and NPCS.
    prediction : Prediction, optional
        The network's raw output (for the segmentation margin).
    """
    labels = np.asarray(corr.part_labels)
    inl = np.asarray(result.inliers, dtype=bool)
    margin = np.full(len(labels), np.nan)
    if prediction is not None and prediction.seg_prob.shape[0] == len(labels) and prediction.seg_prob.shape[1] > 1:
        top2 = np.sort(prediction.seg_prob, axis=1)[:, -2:]
        margin = top2[:, 1] - top2[:, 0]
    out = []
    for j in range(corr.num_parts):
        sel = labels == j
        n = int(np.count_nonzero(sel))
        rec = {"points": n, "inlier_ratio": float("nan"), "residual_m": float("nan"), "seg_margin": float("nan")}
        if n:
            rec["seg_margin"] = float(np.mean(margin[sel])) if np.isfinite(margin[sel]).all() else float("nan")
            if inl.shape == labels.shape:
                rec["inlier_ratio"] = float(inl[sel].mean())
            if j < len(result.T_cam_npcs):
                fitted = result.T_cam_npcs[j].apply(np.asarray(corr.npcs)[sel])
                rec["residual_m"] = float(np.median(np.linalg.norm(fitted - points_cam[sel], axis=1)))
        out.append(rec)
    return tuple(out)


def check_plausibility(result, part_labels, category: str, quality=()):
    """The fit with a failed status naming the first check it fails (or unchanged).

    Checks, in order: ``too_few_inliers`` (under :data:`MIN_INLIER_RATIO` of all points, or of a
    part's points for parts with at least 20 points), ``implausible_size`` (the diagonal of the
    box around all part boxes, in the base part's box frame, outside the category's
    ``diagonal_range`` widened by :data:`SIZE_TOLERANCE`), ``large_residual`` (a part's median
    residual above :data:`MAX_RELATIVE_RESIDUAL` of the category's typical size); the last two
    only for the procedural categories.

    Parameters
    ----------
    result : FitResult
    part_labels : (N,) int
        The predicted part of each observed point.
    category : str
    quality : sequence of dict, optional
        :func:`part_quality` of the fit (for the residual check).
    """
    import dataclasses

    from ...data.procedural import CATEGORY_INFO
    from ...solvers.types import FitStatus

    if not result.ok:
        return result
    labels = np.asarray(part_labels)
    inl = np.asarray(result.inliers, dtype=bool)
    if inl.shape == labels.shape and inl.size:
        ratios = {j: float(inl[labels == j].mean()) for j in np.unique(labels) if np.count_nonzero(labels == j) >= 20}
        worst = min(ratios, key=ratios.get) if ratios else None
        if inl.mean() < MIN_INLIER_RATIO or (worst is not None and ratios[worst] < MIN_INLIER_RATIO):
            return dataclasses.replace(result, status=FitStatus.TOO_FEW_INLIERS, message=(
                f"check inliers: {100 * inl.mean():.0f}% of the points are inliers (part {worst}: "
                f"{100 * ratios.get(worst, float('nan')):.0f}%), at least {100 * MIN_INLIER_RATIO:.0f}% are needed"))
    info = CATEGORY_INFO.get(category)
    if info is not None and result.boxes_cam:
        lo, hi = info.diagonal_range
        diag = object_diagonal(result.boxes_cam)
        if not lo / SIZE_TOLERANCE <= diag <= hi * SIZE_TOLERANCE:
            return dataclasses.replace(result, status=FitStatus.IMPLAUSIBLE_SIZE, message=(
                f"check size: the fitted {category} is {diag:.3g} m across, outside {lo / SIZE_TOLERANCE:.3g}"
                f"..{hi * SIZE_TOLERANCE:.3g} m (the category's {lo}..{hi} m, widened {SIZE_TOLERANCE}x)"))
    if info is not None:
        limit = MAX_RELATIVE_RESIDUAL * info.typical_size
        for j, q in enumerate(quality):
            if q["points"] >= 20 and q["residual_m"] > limit:
                name = info.part_names[j] if j < len(info.part_names) else f"part{j}"
                return dataclasses.replace(result, status=FitStatus.LARGE_RESIDUAL, message=(
                    f"check residual: part {name}'s points lie {1e3 * q['residual_m']:.0f} mm (median) from the fit, "
                    f"above {1e3 * limit:.0f} mm ({MAX_RELATIVE_RESIDUAL} of a typical {category})"))
    return result


def object_diagonal(boxes) -> float:
    """Diagonal (metres) of the box around all part boxes, aligned with the first part's box."""
    R = boxes[0].rotation
    corners = np.concatenate([b.corners() for b in boxes]) @ R
    return float(np.linalg.norm(np.ptp(corners, axis=0)))


def _rest_states(category: str, K: int) -> tuple[tuple, str]:
    """Rest joint states of a procedural category (NaN otherwise) and their description."""
    from ...data.procedural import CATEGORY_INFO, load_instance

    info = CATEGORY_INFO.get(category)
    if info is None or info.num_joints != K:
        return tuple([float("nan")] * K), "unknown category: rest states unknown"
    model = load_instance(category, "test", 0)
    return tuple(float(q) for q in model.rest_states), info.rest_description


def _names(category: str, M: int, K: int) -> tuple[tuple, tuple]:
    from ...data.procedural import CATEGORY_INFO

    info = CATEGORY_INFO.get(category)
    if info is not None and len(info.part_names) == M and len(info.joint_names) == K:
        return tuple(info.part_names), tuple(info.joint_names)
    return tuple(f"part{j}" for j in range(M)), tuple(f"joint{k}" for k in range(K))


# --------------------------------------------------------------------------------------------
# picture
# --------------------------------------------------------------------------------------------
def draw_prediction(depth, prediction: DepthPrediction, intrinsics: Intrinsics, *, title: str = "", rgb=None):
    """Boxes and joint axes over the point cloud (3D) and projected on the depth (or colour) image.

    Uses :func:`ancsh.data.show.draw_fit` and puts the depth image, or ``rgb`` when given
    (``(H, W, 3)`` uint8, registered to the depth), under its image-plane panel; a legend names the
    parts. Returns a matplotlib ``Figure`` (Agg).
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    from ...data.show import draw_fit

    r = prediction.result
    fig = Figure(figsize=(14, 6), dpi=100)
    if prediction.points_cam.shape[0] == 0:  # nothing fitted: the depth image and the isolation only
        ax = fig.add_subplot(1, 1, 1)
        d = np.asarray(depth, dtype=np.float64)
        ax.imshow(np.ma.masked_where(d <= 0, d), cmap="gray", interpolation="nearest")
        _draw_isolation(ax, prediction.isolation)
        ax.set_title(title or f"{prediction.category}: {r.status.value}: {r.message}", fontsize=9)
        return fig
    title = title or (f"{prediction.category}: {r.formulation} fit, status {r.status.value} "
                      f"({prediction.points_cam.shape[0]} points)")
    draw_fit(prediction.points_cam, r, intrinsics, labels=prediction.part_labels, title=title, fig=fig)
    handles = [Line2D([], [], marker="o", linestyle="", color=colormaps["tab10"](j % 10), label=name)
               for j, name in enumerate(prediction.part_names)]
    fig.axes[0].legend(handles=handles, loc="upper left", fontsize=8, title="parts", title_fontsize=8)
    ax = fig.axes[-1]
    xlim, ylim = ax.get_xlim(), ax.get_ylim()
    d = np.asarray(depth, dtype=np.float64)
    extent = (-0.5, d.shape[1] - 0.5, d.shape[0] - 0.5, -0.5)
    if rgb is None:
        im = ax.imshow(np.ma.masked_where(d <= 0, d), cmap="gray", interpolation="nearest", zorder=0, extent=extent)
    else:
        ax.imshow(np.asarray(rgb), interpolation="nearest", zorder=0, extent=extent)
    for coll in ax.collections:
        coll.set_alpha(0.35)
    # the whole image, or more where the projected boxes reach beyond it
    ax.set_xlim(min(xlim[0], extent[0]), max(xlim[1], extent[1]))
    ax.set_ylim(max(ylim[0], extent[2]), min(ylim[1], extent[3]))
    if rgb is None:
        fig.colorbar(im, ax=ax, label="depth (m)", shrink=0.8)
    _draw_isolation(ax, prediction.isolation)
    ax.set_title(("colour" if rgb is not None else "depth") + " image: boxes (part colours) and joint axes (black) projected"
                 + ("; isolated object outlined in red, other clusters in blue" if prediction.isolation is not None else ""),
                 fontsize=9)
    return fig


def _draw_isolation(ax, isolation) -> None:
    """Outline the chosen cluster (red) and the others (blue) of an :class:`~ancsh.data.isolate.Isolation`."""
    if isolation is None:
        return
    others = (isolation.labels >= 0) & ~isolation.mask
    if others.any():
        ax.contour(others.astype(float), levels=[0.5], colors="tab:blue", linewidths=0.8)
    if isolation.mask.any():
        ax.contour(isolation.mask.astype(float), levels=[0.5], colors="red", linewidths=1.2)
