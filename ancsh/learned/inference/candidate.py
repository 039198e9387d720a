"""One candidate segment of ``ancsh predict``: sample its pixels, run the network, fit, refine and judge the fit.

:func:`depth_to_points` back-projects and samples the pixels of a mask; :func:`fit_candidate` runs the network
(:func:`infer`), the fit, the refinement (``LearnedProvider.refine``'s option), the checks
(:mod:`~ancsh.learned.inference.checks`), the measured uncertainty factors (:func:`inflate_uncertainty`) and the
calibrated evidence (``p_good``, render-and-compare and ``p_object``) on one segment;
:func:`fit_candidate_refinements` does so for several refinements on one network pass and first-stage fit (the
``p_object`` calibration, :mod:`ancsh.studies.object_evidence`). :func:`ancsh.learned.inference.predict.predict_depth`
calls it once with a mask, or per verified candidate without one.

Frames: camera (OpenCV: x right, y down, z forward), metres.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from ...data.render import Intrinsics
from .category import Category
from .checks import MAX_SPREAD_DEG, MIN_P_OBJECT, check_confidence, check_plausibility, object_diagonal, part_quality
from .provider import RefinedFit, apply_refinement

__all__ = ["AVERAGING_JUMP_SIGMAS", "CONSENSUS_HYPOTHESES", "MAX_AVERAGING_WINDOW", "MIN_POINTS", "consensus",
           "depth_to_points", "fit_candidate", "object_evidence", "object_feature_vector", "template_comparison",
           "fit_candidate_refinements", "hypothesis_seed", "infer", "inflate_uncertainty", "noise_averaged",
           "training_noise"]


#: Fewer valid points than this: no fit is tried (status ``too_few_points``).
MIN_POINTS = 100
#: A segment whose depth noise (measured in it) is larger than the most the network saw in training is averaged over a
#: window of pixels before it is sampled (:func:`noise_averaged`), at most this wide (pixels).
MAX_AVERAGING_WINDOW = 7
#: Neighbours averaged with a pixel lie within this many of the measured noise's standard deviations of its depth.
AVERAGING_JUMP_SIGMAS = 5.0
#: Hypotheses (independent samplings of the pixels, network passes, RANSAC and refinement seeds) per candidate of
#: ``ancsh predict``: the answer is their consensus (:func:`consensus`), so it does not hang on one seed's luck.
CONSENSUS_HYPOTHESES = 3


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
    from ...data.render import pixels_to_points, valid_depth_pixels
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
    if num_points is not None and (isinstance(num_points, bool) or int(num_points) != num_points or num_points < 1):
        raise ValueError(f"num_points: expected a positive integer, got {num_points!r}")
    flat = np.flatnonzero(sel)  # row-major pixel order
    if num_points is not None and valid > num_points:
        flat = np.sort(check_generator(rng).choice(flat, size=int(num_points), replace=False))
    v, u = np.divmod(flat, d.shape[1])
    return pixels_to_points(u, v, d[v, u], intrinsics), np.stack([u, v], axis=1).astype(np.int64), valid


def fit_candidate(d, intrinsics, mask, category, provider, formulation, num_points, seed, max_depth, refine, *, why=None,
                  object_gate: bool = True, hypotheses: int = CONSENSUS_HYPOTHESES,
                  min_p_object: float = MIN_P_OBJECT, unanimous: bool = False, segmented: bool = False) -> dict:
    """Sample the pixels of ``mask``, run the network, fit, refine and judge the fit: one candidate segment of
    :func:`~ancsh.learned.inference.predict.predict_depth` (called once with a mask, or per verified candidate without
    one), as the consensus of ``hypotheses`` independent tries (:func:`consensus`; the tries stop once the failures are
    a majority: a candidate that fails at every seed costs about half of them). A segment noisier than its network saw
    in training is averaged first (:func:`noise_averaged`, said in ``notes``); :func:`fit_candidate_refinements`
    takes the depth as given.

    ``d``: (H, W) depth (metres, 0 = none); ``mask``: (H, W) bool or ``None`` (every valid pixel); ``category``: the
    :class:`~ancsh.learned.inference.category.Category` (its convention, calibrations, template); ``refine``:
    ``LearnedProvider.refine``'s option; ``why``: when given, nothing is sampled and the candidate fails with
    ``too_few_points`` naming it; ``object_gate=False`` measures the object evidence without letting ``p_object``
    fail the fit (the ``p_object`` calibration, :mod:`ancsh.studies.object_evidence`); ``min_p_object``: the gate's
    threshold (:data:`~ancsh.learned.inference.checks.MIN_P_OBJECT_MASKED` under the user's mask or hint);
    ``unanimous``: the candidate passes only when every hypothesis does and they agree (a segment found without the
    user's help: :func:`consensus` with ``max_spread_deg`` :data:`~ancsh.learned.inference.checks.MAX_SPREAD_DEG`;
    else most of them must pass), and the tries stop at the first failure; ``segmented``: ``mask`` is a segment the
    isolation found without the user's help, judged by the calibration's segment model
    (:func:`~ancsh.learned.inference.confidence.object_model`). The other arguments are
    :func:`~ancsh.learned.inference.predict.predict_depth`'s.

    Returns a dict: ``result`` (FitResult), ``pts`` ((N, 3) camera frame, metres), ``pixels``, ``valid``, ``labels``,
    ``quality``, ``p_good`` / ``p_object`` (or ``None``), ``comparison`` (render-and-compare or ``None``), ``corr``,
    stage times ``t_bp`` / ``t_net`` / ``t_compare`` (seconds, summed over the hypotheses), ``notes``, the joint
    structure and ``consensus`` (:func:`consensus`'s record).
    """
    if isinstance(hypotheses, bool) or int(hypotheses) != hypotheses or hypotheses < 1:
        raise ValueError(f"hypotheses: expected a positive integer, got {hypotheses!r}")
    H = int(hypotheses) if why is None else 1
    needed = H if unanimous else H // 2 + 1
    note = None
    if why is None:
        d, window, sigma = noise_averaged(d, mask, category)
        if window > 1:
            seen = training_noise(category)
            note = (f"depth averaged over {window} x {window} pixels inside the segment before sampling: its noise "
                    f"(sigma {1e3 * sigma:.1f} mm) is {sigma / seen:.1f} times the most the network saw in training "
                    f"({1e3 * seen:.1f} mm at its size)")
    tries = []
    for h in range(H):
        tries.append(fit_candidate_refinements(d, intrinsics, mask, category, provider, formulation, num_points,
                                               hypothesis_seed(seed, h), max_depth, (refine,), why=why,
                                               object_gate=object_gate, min_p_object=min_p_object,
                                               segmented=segmented)[0])
        passed = sum(t["result"].ok for t in tries)
        if tries[-1]["valid"] < MIN_POINTS or passed + H - len(tries) < needed:
            break  # nothing to sample again, or the passes needed can no longer come
    best = consensus(tries, needed=H if unanimous else None, max_spread_deg=MAX_SPREAD_DEG if unanimous else None)
    if note is not None:
        best["notes"] = list(best["notes"]) + [note]
    return best


def training_noise(category) -> float:
    """The largest depth noise (standard deviation, metres) the network of ``category`` saw in training, at the
    category's typical size: the dataset's sensor model (:class:`~ancsh.data.noise.DepthNoise`) at the farthest
    training view (the category's viewpoint range, in box diagonals, times its typical diagonal)."""
    from ...data.noise import DepthNoise
    from ...data.render import viewpoint_range

    far = viewpoint_range(category.convention).distance[1]
    return float(DepthNoise().sigma(far * category.typical_size))


def noise_averaged(d, mask, category) -> tuple[np.ndarray, int, float]:
    """The depth a candidate is sampled from: where the noise measured in the segment
    (:func:`ancsh.data.noise.measured_sigma`) is larger than the most its network saw in training
    (:func:`training_noise`; a far object: a sensor's noise grows about with the square of the depth), its pixels are
    averaged over a window wide enough to bring it down to that (:func:`ancsh.data.noise.averaged_depth`; the side
    grows with the ratio, at most :data:`MAX_AVERAGING_WINDOW`), neighbours on another surface (beyond
    :data:`AVERAGING_JUMP_SIGMAS` of the noise) left out.

    Parameters
    ----------
    d : (H, W) float64
        Metres, 0 = no measurement.
    mask : (H, W) bool or None
        The segment (``None``: every measured pixel).
    category : Category

    Returns
    -------
    (depth, window, sigma)
        The depth (``d`` itself when not averaged), the window's side (pixels; 1 = not averaged) and the measured
        noise (metres; NaN where too few pixels to measure it).
    """
    from ...data.noise import averaged_depth, measured_sigma

    m = np.asarray(d) > 0 if mask is None else mask
    sigma = measured_sigma(d, m)
    ratio = sigma / training_noise(category)
    if not np.isfinite(ratio) or ratio <= 1.0:
        return d, 1, sigma
    window = min(MAX_AVERAGING_WINDOW, 2 * int(np.ceil((ratio - 1.0) / 2.0)) + 1)
    return averaged_depth(d, m, window, AVERAGING_JUMP_SIGMAS * sigma), window, sigma


def hypothesis_seed(seed: int, h: int) -> int:
    """The seed of hypothesis ``h`` of a candidate fitted with ``seed`` (hypothesis 0 keeps ``seed``: one hypothesis is
    the single fit of before)."""
    if h == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), int(h), 0xC0]).generate_state(1)[0])


def _state_differences(states, reference, types) -> np.ndarray:
    """``states - reference`` per joint (``(..., K)``), revolute ones wrapped into ``[-pi, pi)`` (radians; metres for
    prismatic joints); ``types``: ``"revolute"`` / ``"prismatic"`` per joint."""
    diff = np.asarray(states, dtype=np.float64) - np.asarray(reference, dtype=np.float64)
    revolute = np.array([t == "revolute" for t in types], dtype=bool)
    return np.where(revolute, (diff + np.pi) % (2 * np.pi) - np.pi, diff)


def _distance(a, b) -> float:
    """How far two hypotheses' fits are apart: the largest joint-state difference in units of the joint-range
    tolerance (:data:`~ancsh.solvers.limits.LIMIT_TOLERANCE_RAD` / ``_M``), plus the mean part rotation difference in
    those radians."""
    from ...geometry.rotations import rotation_angle
    from ...solvers.limits import LIMIT_TOLERANCE_M, LIMIT_TOLERANCE_RAD

    ra, rb = a["result"], b["result"]
    tol = np.array([LIMIT_TOLERANCE_RAD if t == "revolute" else LIMIT_TOLERANCE_M for t in a["types"]])
    dq = np.abs(_state_differences(ra.joint_states, rb.joint_states, a["types"]))
    rot = [rotation_angle(Ta.rotation.T @ Tb.rotation) for Ta, Tb in zip(ra.T_cam_npcs, rb.T_cam_npcs)]
    return float((np.max(dq / tol) if dq.size else 0.0) + (np.mean(rot) / LIMIT_TOLERANCE_RAD if rot else 0.0))


def consensus(tries: list, *, needed: int | None = None, max_spread_deg: float | None = None) -> dict:
    """The answer of several hypotheses of one candidate (:func:`fit_candidate`'s dicts, each fitted with its own
    seed): when most of them (or ``needed`` of them) pass their checks, the passing one nearest the others (the medoid
    by :func:`_distance`), else the first failure of the most common failed status. Its ``consensus`` record says how they went:
    ``hypotheses``, ``passed``, ``statuses``, ``chosen`` (index), ``state_std`` (per joint, rad or m, over the passing
    ones; ``None`` with fewer than 2) and ``rotation_spread_deg`` (per part, the RMS rotation angle of the passing
    fits from the chosen one); the stage times are summed over the hypotheses. With ``max_spread_deg``, passing
    hypotheses whose mean ``rotation_spread_deg`` exceeds it give status ``ambiguous``: the answer depends on the
    seed."""
    from collections import Counter

    from ...geometry.rotations import rotation_angle

    ok = [i for i, t in enumerate(tries) if t["result"].ok]
    if (len(ok) >= needed) if needed is not None else (2 * len(ok) > len(tries)):
        dist = np.array([[_distance(tries[i], tries[j]) for j in ok] for i in ok])
        chosen = ok[int(np.argmin(dist.sum(axis=1)))]
    else:
        statuses = Counter(t["result"].status for i, t in enumerate(tries) if i not in ok)
        common = statuses.most_common(1)[0][0]
        chosen = next(i for i, t in enumerate(tries) if t["result"].status == common)
    best = dict(tries[chosen])
    record = {"hypotheses": len(tries), "passed": len(ok), "statuses": [t["result"].status.value for t in tries],
              "chosen": int(chosen), "state_std": None, "rotation_spread_deg": None}
    if len(ok) >= 2 and best["result"].ok:
        states = np.array([np.asarray(tries[i]["result"].joint_states, dtype=np.float64) for i in ok])
        wrapped = _state_differences(states, states[ok.index(chosen)], best["types"])
        record["state_std"] = [float(x) for x in wrapped.std(axis=0, ddof=1)]
        R0 = best["result"].T_cam_npcs
        record["rotation_spread_deg"] = [
            float(np.degrees(np.sqrt(np.mean([rotation_angle(R0[j].rotation.T @ tries[i]["result"].T_cam_npcs[j].rotation)
                                              ** 2 for i in ok])))) for j in range(len(R0))]
    if len(tries) > 1:
        for key in ("t_bp", "t_net", "t_compare"):
            best[key] = float(sum(t[key] for t in tries))
        best["notes"] = list(best["notes"]) + [
            f"consensus: {len(ok)} of {len(tries)} hypotheses (samplings and RANSAC seeds) passed"
            + ("" if needed is None else f", {needed} needed") + f"; hypothesis {chosen} is the answer"
            + (" (the passing one nearest the others)" if best["result"].ok else " (most failed alike)")]
    spread = record["rotation_spread_deg"]
    if max_spread_deg is not None and best["result"].ok and spread and float(np.mean(spread)) > max_spread_deg:
        from ...solvers.types import FitStatus

        best["result"] = dataclasses.replace(best["result"], status=FitStatus.AMBIGUOUS, message=(
            f"check consensus: the {len(ok)} passing hypotheses (samplings and RANSAC seeds) disagree, their parts "
            f"{float(np.mean(spread)):.1f} deg apart on average (at most {max_spread_deg:g}): the answer depends on the "
            "seed"))
    best["consensus"] = record
    return best


def fit_candidate_refinements(d, intrinsics, mask, category, provider, formulation, num_points, seed, max_depth,
                              refinements, *, why=None, object_gate: bool = True,
                              min_p_object: float = MIN_P_OBJECT, segmented: bool = False) -> list[dict]:
    """:func:`fit_candidate` once per option of ``refinements`` (a sequence of ``LearnedProvider.refine`` options),
    sharing what does not depend on it: the points, the network pass and the first-stage fit run once.

    Returns one :func:`fit_candidate` dict per option, in order; each is what :func:`fit_candidate` returns for it
    (the seeds are the same), its ``t_bp`` / ``t_net`` the shared stages' times.
    """
    from ...solvers import Observation, fit
    from ...solvers.types import FitResult, FitStatus

    _check_category(category)
    refinements = tuple(refinements)
    if not refinements:
        raise ValueError("refinements: expected at least one LearnedProvider.refine option, got none")
    t0 = time.perf_counter()
    if why is not None:
        pts, pixels, valid = np.zeros((0, 3)), np.zeros((0, 2), dtype=np.int64), 0
    else:
        pts, pixels, valid = depth_to_points(d, intrinsics, mask=mask, max_depth=max_depth, num_points=num_points, rng=seed)
    t_bp = time.perf_counter() - t0
    if valid < MIN_POINTS:
        K = len(provider.network.revolute)
        why = why or f"{valid} valid points"
        result = FitResult.failure(FitStatus.TOO_FEW_POINTS, f"check min_points: {why}, at least "
                                   f"{MIN_POINTS} are needed for a fit", formulation=formulation, solver="none",
                                   num_joints=K, num_points=len(pts))
        return [{"result": result, "pts": pts, "pixels": pixels, "valid": valid,
                 "labels": np.zeros(len(pts), dtype=np.int64), "quality": (), "p_good": None, "p_object": None,
                 "comparison": None, "t_compare": 0.0, "t_net": 0.0, "t_bp": t_bp, "notes": [],
                 "types": tuple("revolute" if r else "prismatic" for r in provider.network.revolute),
                 "parents": provider.network.joint_parents, "children": provider.network.joint_children}
                for _ in refinements]
    obs = Observation(pts)
    t0 = time.perf_counter()
    corr, raw = infer(provider, obs)
    t_net = time.perf_counter() - t0
    first = _FirstStage(obs, pts, pixels, valid, corr, raw, fit(obs, corr, formulation, config=provider.fit_config(),
                                                                rng=seed), t_bp, t_net)
    return [_finish_candidate(first, d, intrinsics, mask, category, provider, formulation, seed, refine, object_gate,
                              min_p_object, segmented) for refine in refinements]


def _check_category(category) -> Category:
    """``category`` checked to be a loaded :class:`~ancsh.learned.inference.category.Category` (a name is refused:
    the entry point resolves it once, :func:`~ancsh.learned.inference.category.load_category`)."""
    if not isinstance(category, Category):
        raise ValueError(f"category: expected a Category (ancsh.learned.inference.category.load_category), got "
                         f"{category!r}")
    return category


@dataclass(frozen=True)
class _FirstStage:
    """What :func:`fit_candidate_refinements` shares between its refinements: the sampled points (camera frame,
    metres) and their pixels, the network's output on them and the first-stage fit, and the two stages' times (s)."""

    observation: object  # ancsh.solvers.Observation of pts
    pts: np.ndarray  # (N, 3)
    pixels: np.ndarray  # (N, 2) int64, (u, v)
    valid: int  # valid pixels of the mask
    corr: object  # Correspondences
    raw: object  # the network's raw prediction
    result: object  # FitResult of the first stage
    t_bp: float
    t_net: float


def _finish_candidate(first: _FirstStage, d, intrinsics, mask, category, provider, formulation, seed, refine,
                      object_gate, min_p_object=MIN_P_OBJECT, segmented=False) -> dict:
    """The refinement ``refine`` of the first-stage fit and its checks and evidence: :func:`fit_candidate_refinements`'
    per-option part (``first`` is not changed: every option starts from it)."""
    pts, corr, raw, result = first.pts, first.corr, first.raw, first.result
    refined = RefinedFit(result, corr, raw, None, None)
    if formulation != "per_part":
        refined = apply_refinement(provider, first.observation, corr, raw, result, refine=refine, rng=seed)
    result, corr, raw = refined.result, refined.correspondences, refined.prediction
    notes = [refined.note] if refined.note else []
    labels = np.asarray(corr.part_labels)
    quality = part_quality(result, pts, corr, raw)
    result = check_plausibility(result, labels, category.convention, quality)
    result = inflate_uncertainty(result, category, provider, template=refined.kind == "template",
                                 network=refined.kind == "network")
    p_good = _p_good(category, quality, getattr(provider.network, "sha256", None)) if result.ok else None
    comparison, p_object, t_rc = None, None, 0.0
    if result.ok and mask is not None:
        t0 = time.perf_counter()
        comparison, p_object = object_evidence(result, corr, d, intrinsics, mask, category, quality, provider, pts,
                                               segmented=segmented)
        t_rc = time.perf_counter() - t0
    if object_gate:
        result = check_confidence(result, p_object, min_p_object)
    return {"result": result, "pts": pts, "pixels": first.pixels, "valid": first.valid, "labels": labels,
            "quality": quality, "p_good": p_good, "p_object": p_object, "comparison": comparison, "t_compare": t_rc,
            "t_net": first.t_net, "t_bp": first.t_bp, "notes": notes, "corr": corr,
            "types": tuple(t.value for t in corr.joint_types), "parents": corr.joint_parents, "children": corr.joint_children}


def template_comparison(result, corr, depth, intrinsics, mask, category: Category):
    """The template of ``category`` (a :class:`~ancsh.learned.inference.category.Category`) posed at the fit, rendered
    and compared with ``depth`` on ``mask`` (:func:`ancsh.solvers.twin.compare_fit`): a
    :class:`~ancsh.solvers.render_compare.DepthComparison`, or ``None`` for a category without templates, an empty
    mask, or a fit without the joints or boxes a template needs."""
    from ...solvers.twin import compare_fit

    if not _check_category(category).has_templates() or mask is None or not np.asarray(mask).any():
        return None
    try:
        return compare_fit(result, corr, category.template_library(), depth, intrinsics, mask)[0]
    except ValueError:  # a fit without the joints or boxes a template needs
        return None


def object_evidence(result, corr, depth, intrinsics, mask, category: Category, quality, provider, points, *,
                    segmented: bool = False) -> tuple:
    """Render-and-compare of the fit (:func:`ancsh.solvers.twin.compare_fit`) and the calibrated
    P(object of the category) where ``category`` has an object calibration
    (:attr:`~ancsh.learned.inference.category.Category.p_object_calibration`, ``<category>_object.json``) for these
    weights (its features:
    :func:`object_feature_vector`; its model for a segment found without the user's help where ``segmented``:
    :func:`~ancsh.learned.inference.confidence.object_model`)."""
    from .confidence import OBJECT_FEATURES, object_model, probability_good

    comparison = template_comparison(result, corr, depth, intrinsics, mask, category)
    if comparison is None:
        return None, None
    calibration = category.p_object_calibration
    if calibration is None or calibration.get("weights_sha256") != getattr(provider.network, "sha256", None):
        return comparison, None
    if calibration.get("features") != list(OBJECT_FEATURES):  # made with other features: recalibrate
        return comparison, None
    x = object_feature_vector(result, comparison, depth, mask, quality, category, points)
    return comparison, probability_good(object_model(calibration, segmented=segmented), x)


def object_feature_vector(result, comparison, depth, mask, quality, category: Category, points) -> np.ndarray:
    """:func:`~ancsh.learned.inference.confidence.object_features` of a fit: its render-and-compare ``comparison`` on
    ``mask`` of ``depth`` aligned along the depth axis (at most
    :data:`~ancsh.learned.inference.confidence.ALIGN_SHARE` of the fitted object's diagonal), its size, its per-part
    ``quality`` and the observed ``points`` (N, 3)."""
    from ...solvers.render_compare import aligned_comparison
    from .confidence import ALIGN_SHARE, object_features

    diagonal = object_diagonal(result.boxes_cam)
    aligned = aligned_comparison(comparison, depth, mask, ALIGN_SHARE * diagonal)
    return object_features(aligned, diagonal, quality, _check_category(category).typical_size, points)


def inflate_uncertainty(result, category: Category, provider, *, template: bool = False, network: bool = False,
                        tracked: str | None = None):
    """The fit with its standard deviations inflated by the factors measured for these weights of
    ``category`` (a :class:`~ancsh.learned.inference.category.Category`; :func:`ancsh.solvers.uncertainty.inflation_for`,
    matched by SHA-256); raw for other weights.
    ``ancsh predict`` and the :class:`~ancsh.tracking.CategoryTracker` apply it to a learned provider's fits.
    ``template``: the fit was refined by the category template (an accepted
    :meth:`LearnedProvider.refine`), whose covariance is the template ICP's: the factors measured for
    those fits apply (provider ``"learned-template"`` of ``ancsh bench uncertainty``).
    ``network``: the fit is the refinement network's (an accepted refinement): the factors measured for
    those fits and that refiner apply (provider ``"learned-network"``).
    ``tracked``: the source of a warm tracked frame (``"network"``, ``"carried"``, ``"template"``): the
    factors measured on tracked frames of that source (provider ``"learned-tracked-<source>"`` of
    ``ancsh bench tracking --calibration-sequences``) apply where measured, else the single-frame ones."""
    import dataclasses

    from ...solvers.uncertainty import tracked_provider

    _check_category(category)
    if result.uncertainty is None:
        return result
    if network:
        inflation = category.inflation(("learned-network",), getattr(provider.refiner.network, "sha256", None))
        return dataclasses.replace(result, uncertainty=result.uncertainty.inflated(inflation))
    single = "learned-template" if template else "learned"
    inflation = category.inflation((tracked_provider("learned", tracked) if tracked else None, single),
                                   getattr(provider.network, "sha256", None))
    return dataclasses.replace(result, uncertainty=result.uncertainty.inflated(inflation))


def _p_good(category: Category, quality, weights_sha256: str | None) -> float | None:
    """Calibrated P(good fit) where ``category`` has a ``p_good`` calibration (``<category>_confidence.json``) made
    for these weights (``weights_sha256``); ``None`` otherwise."""
    from .confidence import fit_features, probability_good

    calibration = category.p_good_calibration
    if calibration is None or calibration.get("weights_sha256") != weights_sha256:
        return None  # calibrated on other weights (e.g. before a retraining): its probabilities would be another net's
    return probability_good(calibration, fit_features(quality, category.typical_size))


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
