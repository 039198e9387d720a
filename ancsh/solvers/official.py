"""The official ANCSH code's pairwise fitting scheme, reproduced as a baseline.

The reference implementation released with the paper does not solve one problem over all
parts. It fits *pairs*: for every joint, the parent part (the base, in every category of
the paper) together with the child part, independently of the other pairs:

1. RANSAC with ``num_hypotheses`` (200) hypotheses. Each draws ``sample_size`` (3)
   correspondences per part, with replacement.
2. Per part, the scale is the least-squares ratio of all pairwise distances
   (camera over NPCS) of the sample; the camera points are divided by the inverse ratio
   (NPCS over camera) and both sets are centred; Umeyama (Kabsch) on the centred sample
   gives the initial rotation.
3. ``scipy.optimize.least_squares(method="lm", ftol=1e-4)`` (finite-difference
   Jacobian) refines the two rotation vectors with the residuals

   - revolute: ``[y0 - R0 x0; y1 - R1 x1; R0 u - R1 u]``, the axis row ``u`` (NAOCS
     axis, which is also the NPCS direction) repeated ``min(n0, n1)`` times;
   - prismatic: ``[y0 - R0 x0; y1 - R1 x1; r0 - r1]`` (the difference of the two rotation
     vectors). **Here this differs from the original code**: its fitting script calls the
     estimator without the joint type, so there every joint -- prismatic ones too -- uses the
     revolute residual; this baseline uses the rotation-vector residual the estimator defines
     for prismatic joints;

   where ``x`` are the centred NPCS and ``y`` the centred, rescaled camera points.
4. The translation is ``mean(y - s R x)`` over the (uncentred) sample.
5. A hypothesis is scored by the mean over the two parts of the fraction of the part's
   points whose residual ``|p - (s R c + t)|`` is below ``inlier_threshold`` object
   units; the best (first strictly best) hypothesis wins.
6. Steps 2-4 are repeated on all inliers of the best hypothesis.

A child part takes its pose from its own joint's pair; the base part (more generally a
part that is no joint's child) takes its pose from the first pair it belongs to, as the
official code does with the base of pair ``(0, 1)``.

The official code measures the inlier threshold (0.1) in the units of its camera point
clouds, which are object-normalised. Here camera points are metres, so the threshold is
``inlier_threshold * object_scale`` where ``object_scale`` is the object's size in metres
per NAOCS unit: given, or estimated from the correspondences as the median over parts of
the ratio of RMS spreads (camera over NPCS) divided by the part's NPCS -> NAOCS scale.

Beyond the original code, like every other method: zero-weight correspondences are left out
(they carry no match) and other non-uniform weights are refused (``ValueError``: the scheme has no
weights); parts whose NPCS or camera points are coincident or collinear fail as ``DEGENERATE``;
mismatched point counts raise ``ValueError``; above 4096 points the pairwise-distance scale is
computed on an evenly spaced subset of 4096 of them (the original builds ``N x N`` matrices: 126 GiB
for a 200k-point refit set).

This module is deliberately plain numpy/scipy, so that the baseline is what the official
code computes, residual for residual. It is slow on purpose only in the ways the official
code is slow (many hypotheses, a finite-difference Levenberg-Marquardt per hypothesis,
quadratic pairwise-distance scale).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.distance import pdist

from ..geometry._checks import check_generator

__all__ = ["OfficialArrays", "OfficialSettings", "PairFit", "estimate_object_scale", "fit_official", "fit_official_arrays", "fit_pair"]


@dataclass(frozen=True)
class OfficialSettings:
    """Settings of the official pairwise scheme (defaults: the official values).

    Attributes
    ----------
    num_hypotheses : int
        RANSAC hypotheses per pair (official: 200).
    sample_size : int
        Correspondences drawn per part per hypothesis, with replacement (official: 3).
    inlier_threshold : float
        Inlier residual bound in object units (official: 0.1).
    ftol : float
        ``least_squares`` relative cost tolerance (official: 1e-4).
    object_scale : float or None
        Metres per object unit for the threshold; ``None`` estimates it from the
        correspondences (see module docstring).
    """

    num_hypotheses: int = 200
    sample_size: int = 3
    inlier_threshold: float = 0.1
    ftol: float = 1e-4
    object_scale: float | None = None

    def __post_init__(self):
        if not isinstance(self.num_hypotheses, (int, np.integer)) or self.num_hypotheses < 1:
            raise ValueError(f"num_hypotheses: expected a positive integer, got {self.num_hypotheses!r}")
        if not isinstance(self.sample_size, (int, np.integer)) or self.sample_size < 3:
            raise ValueError(f"sample_size: expected an integer >= 3, got {self.sample_size!r}")
        for name in ("inlier_threshold", "ftol"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name}: expected a positive finite number, got {v!r}")
        if self.object_scale is not None and (not np.isfinite(self.object_scale) or self.object_scale <= 0):
            raise ValueError(f"object_scale: expected None or a positive finite number, got {self.object_scale!r}")


@dataclass(frozen=True)
class PairFit:
    """Result of one pair: similarity ``y ~= scale * R @ x + t`` for both parts.

    Attributes
    ----------
    rotations : (2, 3, 3) float64
    translations : (2, 3) float64
        Camera frame, metres.
    scales : (2,) float64
    inliers : tuple of two (n_i,) bool arrays
        Inliers of the best hypothesis (the refit set).
    score : float
        Mean inlier ratio of the best hypothesis.
    ok : bool
        ``False`` if the pair could not be fitted (too few points, degenerate refit).
    message : str
    """

    rotations: np.ndarray
    translations: np.ndarray
    scales: np.ndarray
    inliers: tuple
    score: float
    ok: bool
    message: str


# --- the official estimator, verifier and RANSAC loop ---------------------------------
_PDIST_MAX_POINTS = 4096  # above this many points the pairwise sums use an evenly spaced subset of this size


def _pairwise_sums(src: np.ndarray, dst: np.ndarray) -> tuple[float, float, float]:
    """``(a . b, a . a, b . b)`` over all point pairs, ``a`` / ``b`` the pairwise distances of ``src`` / ``dst``.

    The official code builds the full ``N x N`` matrices (126 GiB at ``N = 200k``); above
    ``_PDIST_MAX_POINTS`` points the sums run over an evenly spaced subset of that many points
    (their ratios, the scales, estimate the full ones; time and memory stay bounded).
    """
    n = len(src)
    if n > _PDIST_MAX_POINTS:
        keep = np.linspace(0, n - 1, _PDIST_MAX_POINTS).round().astype(np.int64)
        src, dst = src[keep], dst[keep]
    a, b = pdist(src), pdist(dst)
    return float(a @ b), float(a @ a), float(b @ b)


def _pairwise_scale(src: np.ndarray, dst: np.ndarray) -> float:
    """Least-squares ratio ``b ~= s a`` of all pairwise distances (dst over src).

    The official code sums over the full ``N x N`` distance matrix with a ``1e-6``
    regulariser in the denominator; the condensed (half) matrix with ``5e-7`` is the same.
    """
    ab, aa, _ = _pairwise_sums(src, dst)
    return ab / (aa + 5e-7)


def _kabsch(src_c: np.ndarray, dst_c: np.ndarray) -> np.ndarray:
    """Rotation ``R`` minimising ``sum |dst_c - R src_c|^2`` for centred ``(n, 3)`` sets."""
    U, _, Vt = np.linalg.svd(dst_c.T @ src_c)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        U[:, -1] = -U[:, -1]
    return U @ Vt


def _rodrigues(r: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector ``(3,)`` (Rodrigues; scalar maths, it is called a lot)."""
    x, y, z = float(r[0]), float(r[1]), float(r[2])
    theta = math.sqrt(x * x + y * y + z * z)
    if theta < 1e-12:
        return np.eye(3)
    x, y, z = x / theta, y / theta, z / theta
    s, c = math.sin(theta), math.cos(theta)
    v = 1.0 - c
    return np.array([
        [c + x * x * v, x * y * v - z * s, x * z * v + y * s],
        [y * x * v + z * s, c + y * y * v, y * z * v - x * s],
        [z * x * v - y * s, z * y * v + x * s, c + z * z * v],
    ])


def _rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix (inverse of :func:`_rodrigues`)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_rotvec()


def _residual_revolute(params, x0, y0, x1, y1, axis_rows):
    R0 = _rodrigues(params[:3])
    R1 = _rodrigues(params[3:])
    return np.concatenate(
        [(y0 - x0 @ R0.T).ravel(), (y1 - x1 @ R1.T).ravel(), (axis_rows @ R0.T - axis_rows @ R1.T).ravel()]
    )


def _residual_prismatic(params, x0, y0, x1, y1):
    R0 = _rodrigues(params[:3])
    R1 = _rodrigues(params[3:])
    return np.concatenate([(y0 - x0 @ R0.T).ravel(), (y1 - x1 @ R1.T).ravel(), params[:3] - params[3:]])


def _estimate(x0, y0, x1, y1, axis, revolute: bool, ftol: float):
    """The official joint transformation estimator on one sample (or the inlier set)."""
    (ab0, aa0, bb0), (ab1, aa1, bb1) = _pairwise_sums(x0, y0), _pairwise_sums(x1, y1)
    s0, s1 = ab0 / (aa0 + 5e-7), ab1 / (aa1 + 5e-7)  # as _pairwise_scale, both directions from one pass
    s0_inv, s1_inv = ab0 / (bb0 + 5e-7), ab1 / (bb1 + 5e-7)
    y0c = s0_inv * y0
    y0c = y0c - y0c.mean(axis=0)
    y1c = s1_inv * y1
    y1c = y1c - y1c.mean(axis=0)
    x0c = x0 - x0.mean(axis=0)
    x1c = x1 - x1.mean(axis=0)
    R0, R1 = _kabsch(x0c, y0c), _kabsch(x1c, y1c)
    start = np.concatenate([_rotvec(R0), _rotvec(R1)])
    if revolute:
        axis_rows = np.tile(axis, (min(len(x0), len(x1)), 1))
        sol = least_squares(_residual_revolute, start, method="lm", ftol=ftol, args=(x0c, y0c, x1c, y1c, axis_rows))
    else:
        sol = least_squares(_residual_prismatic, start, method="lm", ftol=ftol, args=(x0c, y0c, x1c, y1c))
    R0, R1 = _rodrigues(sol.x[:3]), _rodrigues(sol.x[3:])
    t0 = np.mean(y0 - s0 * (x0 @ R0.T), axis=0)
    t1 = np.mean(y1 - s1 * (x1 @ R1.T), axis=0)
    return np.stack([R0, R1]), np.stack([t0, t1]), np.array([s0, s1])


def _verify(x0, y0, x1, y1, model, threshold: float):
    Rs, ts, ss = model
    r0 = np.linalg.norm(y0 - ss[0] * (x0 @ Rs[0].T) - ts[0], axis=1)
    r1 = np.linalg.norm(y1 - ss[1] * (x1 @ Rs[1].T) - ts[1], axis=1)
    in0, in1 = r0 < threshold, r1 < threshold
    return 0.5 * (in0.mean() + in1.mean()), (in0, in1)


def fit_pair(x0, y0, x1, y1, axis, revolute: bool, threshold: float, settings: OfficialSettings, rng) -> PairFit:
    """Official RANSAC + LM fit of one part pair.

    Parameters
    ----------
    x0, x1 : (n0, 3), (n1, 3) float64
        NPCS coordinates of the two parts' points.
    y0, y1 : (n0, 3), (n1, 3) float64
        The same points in the camera frame (metres).
    axis : (3,) float64
        Joint axis in NAOCS (= NPCS orientation), unit.
    revolute : bool
        Joint type (selects the residual).
    threshold : float
        Inlier bound in metres.
    settings : OfficialSettings
    rng : numpy.random.Generator or int
    """
    rng = check_generator(rng)
    n0, n1 = len(x0), len(x1)
    empty = PairFit(np.stack([np.eye(3)] * 2), np.zeros((2, 3)), np.ones(2),
                    (np.zeros(n0, bool), np.zeros(n1, bool)), 0.0, False, "")
    if n0 < 3 or n1 < 3:
        return _replace(empty, message=f"a part of the pair has fewer than 3 points ({n0}, {n1})")
    if not np.all(np.isfinite(axis)):
        return _replace(empty, message="joint axis is not finite")
    best_score, best_inliers = -np.inf, None
    k = settings.sample_size
    for _ in range(settings.num_hypotheses):
        i0 = rng.integers(n0, size=k)
        i1 = rng.integers(n1, size=k)
        model = _estimate(x0[i0], y0[i0], x1[i1], y1[i1], axis, revolute, settings.ftol)
        score, inliers = _verify(x0, y0, x1, y1, model, threshold)
        if score > best_score:
            best_score, best_inliers = score, inliers
    in0, in1 = best_inliers
    if in0.sum() < 3 or in1.sum() < 3:
        return _replace(empty, inliers=best_inliers, score=float(best_score),
                        message=f"best hypothesis has fewer than 3 inliers on a part ({in0.sum()}, {in1.sum()})")
    Rs, ts, ss = _estimate(x0[in0], y0[in0], x1[in1], y1[in1], axis, revolute, settings.ftol)
    ok = bool(np.all(ss > 0) and np.all(np.isfinite(ts)) and np.all(np.isfinite(Rs)))
    return PairFit(Rs, ts, ss, best_inliers, float(best_score), ok, "" if ok else "degenerate refit (zero scale)")


def _replace(fit: PairFit, **changes) -> PairFit:
    from dataclasses import replace

    return replace(fit, **changes)


def estimate_object_scale(npcs, points, labels, npcs_scale) -> float:
    """Metres per NAOCS unit: median over parts (>= 3 points) of RMS spread ratio / NPCS scale.

    Parameters
    ----------
    npcs, points : (N, 3) float64
        NPCS coordinates and camera points (metres).
    labels : (N,) int
    npcs_scale : (M,) float64
        NPCS -> NAOCS scale of each part.
    """
    ratios = []
    for j, g in enumerate(npcs_scale):
        sel = labels == j
        if sel.sum() < 3:
            continue
        sx = np.sqrt(np.mean(np.sum((npcs[sel] - npcs[sel].mean(0)) ** 2, axis=1)))
        sy = np.sqrt(np.mean(np.sum((points[sel] - points[sel].mean(0)) ** 2, axis=1)))
        if sx > 0 and g > 0:
            ratios.append(sy / sx / g)
    return float(np.median(ratios)) if ratios else float("nan")


@dataclass(frozen=True)
class OfficialArrays:
    """Part poses of the official scheme, before post-processing.

    Attributes
    ----------
    rotations : (M, 3, 3), translations : (M, 3), scales : (M,)
        ``T_cam_npcs`` of every part (camera frame, metres).
    inliers : (N,) bool
        Inliers of the pair that gave each point's part its pose.
    ok : bool
    message : str
    time_s : float
    """

    rotations: np.ndarray
    translations: np.ndarray
    scales: np.ndarray
    inliers: np.ndarray
    ok: bool
    message: str
    time_s: float


def fit_official_arrays(points, npcs, labels, npcs_scale, joint_types, joint_parents, joint_children,
                        joint_axes_naocs, *, settings: OfficialSettings = OfficialSettings(), rng=0) -> OfficialArrays:
    """The official pairwise scheme on plain arrays (``N`` points, ``M`` parts, ``K`` joints).

    Parameters
    ----------
    points : (N, 3) float64
        Camera-frame points (metres).
    npcs : (N, 3) float64
        NPCS coordinate of each point in its labelled part.
    labels : (N,) int
        Part label of each point, ``0..M-1``.
    npcs_scale : (M,) float64
        NPCS -> NAOCS scales (only used to estimate the object scale).
    joint_types : (K,) sequence of str / JointType
    joint_parents, joint_children : (K,) int
    joint_axes_naocs : (K, 3) float64
    settings : OfficialSettings
    rng : numpy.random.Generator or int
    """
    t_start = time.perf_counter()
    rng = check_generator(rng)
    points = np.asarray(points, dtype=np.float64)
    npcs = np.asarray(npcs, dtype=np.float64)
    labels = np.asarray(labels)
    M = len(npcs_scale)
    K = len(joint_types)
    Rs = np.stack([np.eye(3)] * M)
    ts = np.zeros((M, 3))
    ss = np.ones(M)
    inliers = np.zeros(len(points), dtype=bool)
    done = np.zeros(M, dtype=bool)
    messages = []
    scale = settings.object_scale
    if scale is None:
        scale = estimate_object_scale(npcs, points, labels, npcs_scale)
    if not np.isfinite(scale) or scale <= 0:
        return OfficialArrays(Rs, ts, ss, inliers, False, "cannot estimate the object scale (too few points)",
                              time.perf_counter() - t_start)
    threshold = settings.inlier_threshold * scale
    idx = [np.nonzero(labels == j)[0] for j in range(M)]
    if K == 0:
        messages.append("the model has no joint: the official scheme fits pairs only")
    for k in range(K):
        p, c = int(joint_parents[k]), int(joint_children[k])
        revolute = str(getattr(joint_types[k], "value", joint_types[k])) == "revolute"
        axis = np.asarray(joint_axes_naocs[k], dtype=np.float64)
        fit = fit_pair(npcs[idx[p]], points[idx[p]], npcs[idx[c]], points[idx[c]], axis, revolute,
                       threshold, settings, rng)
        if not fit.ok:
            messages.append(f"joint {k}: {fit.message}")
            continue
        for slot, j in ((0, p), (1, c)):
            if slot == 1 or not done[j]:
                Rs[j], ts[j], ss[j] = fit.rotations[slot], fit.translations[slot], fit.scales[slot]
                inliers[idx[j]] = fit.inliers[slot]
                done[j] = True
    ok = bool(done.all())
    if not ok and not messages:
        messages.append(f"parts {np.nonzero(~done)[0].tolist()} were not fitted")
    return OfficialArrays(Rs, ts, ss, inliers, ok, "; ".join(messages) or "ok", time.perf_counter() - t_start)


# --- FitResult wrapper ----------------------------------------------------------------
def fit_official(observation, correspondences, *, settings: OfficialSettings = OfficialSettings(), rng=0):
    """Fit all parts with the official pairwise scheme; a :class:`~ancsh.solvers.types.FitResult`.

    Parameters
    ----------
    observation : Observation
        ``N`` camera-frame points (metres).
    correspondences : Correspondences
        Per-point labels and NPCS, per-part NPCS -> NAOCS, per-joint NAOCS axes and pivots.
    settings : OfficialSettings
        Defaults are the official values.
    rng : numpy.random.Generator or int
        RANSAC sampling.

    Returns
    -------
    FitResult
        ``formulation="official"``, ``solver="scipy-lm"``; camera-space joints and amodal
        boxes from the part poses (paper Sec. 4.4). A failure to fit is a status
        (``TOO_FEW_POINTS``, ``DEGENERATE`` for coincident or collinear part points).

    Raises
    ------
    ValueError
        For bad arguments, as every method: wrong types, mismatched point counts, non-uniform
        positive weights.
    """
    from .types import Correspondences, FitResult, FitStatus, Observation

    if not isinstance(observation, Observation):
        raise ValueError(f"observation: expected an Observation, got {type(observation).__name__}")
    if not isinstance(correspondences, Correspondences):
        raise ValueError(f"correspondences: expected Correspondences, got {type(correspondences).__name__}")
    t_start = time.perf_counter()
    c = correspondences
    n, K = observation.num_points, c.num_joints
    name = dict(formulation="official", solver="scipy-lm", num_joints=K, num_points=n)
    if c.num_points != n:
        raise ValueError(f"correspondences: {c.num_points} points do not match the observation's {n}")
    keep = np.ones(n, dtype=bool)
    if c.weights is not None:
        w = np.asarray(c.weights, dtype=np.float64)
        keep = w > 0
        if keep.any() and np.ptp(w[keep]) > 1e-12 * np.max(w[keep]):
            raise ValueError("correspondences.weights: the official scheme has no point weights; pass equal weights "
                             "(zero-weight points are left out) or none")
    points, labels, npcs = observation.points_cam[keep], c.part_labels[keep], c.npcs[keep]
    counts = np.bincount(labels, minlength=c.num_parts)
    if np.any(counts < 3):
        return FitResult.failure(FitStatus.TOO_FEW_POINTS, f"parts {np.nonzero(counts < 3)[0].tolist()} have fewer than 3 points",
                                 **name, time_s=time.perf_counter() - t_start)
    from ..geometry.umeyama import DegeneratePointsError, umeyama

    for j in range(c.num_parts):
        sel = labels == j
        try:
            umeyama(npcs[sel], points[sel])  # the same coincident / collinear test as every other method
        except DegeneratePointsError as exc:
            return FitResult.failure(FitStatus.DEGENERATE, f"part {j}: {exc}", **name, time_s=time.perf_counter() - t_start)
    res = fit_official_arrays(points, npcs, labels, c.npcs_scale, c.joint_types,
                              c.joint_parents, c.joint_children, c.joint_axes_naocs, settings=settings, rng=rng)
    if not res.ok:
        return FitResult.failure(FitStatus.DEGENERATE, res.message, **name, time_s=time.perf_counter() - t_start)
    from ..geometry.transforms import Sim3

    poses = tuple(Sim3(res.rotations[j], res.translations[j], float(res.scales[j])) for j in range(c.num_parts))
    axes, pivots, states = camera_joints(poses, c)
    inliers = np.zeros(n, dtype=bool)
    inliers[keep] = res.inliers
    boxes = amodal_boxes(poses, c, inliers)
    return FitResult(
        formulation="official", solver="scipy-lm", T_cam_npcs=poses, joint_axes_cam=axes, joint_pivots_cam=pivots,
        joint_states=states, boxes_cam=boxes, status=FitStatus.SUCCESS, message=res.message,
        inliers=inliers, time_s=time.perf_counter() - t_start,
    )


def camera_joints(poses, correspondences):
    """Camera-space joint axes, pivots and states from part poses (paper Sec. 4.4).

    Evaluates the solver core's post-processing (:func:`ancsh.solvers.program.postprocess_function`),
    so the official baseline reports joints exactly as every formulation does.

    Returns
    -------
    axes : (K, 3), pivots : (K, 3) metres, states : (K,) radians / metres
    """
    from .program import postprocess_function
    from .terms import CanonicalParameters, KinematicStructure

    c = correspondences
    post = postprocess_function(KinematicStructure.from_correspondences(c))
    return post(poses, CanonicalParameters.of(c))


def amodal_boxes(poses, correspondences, inliers):
    """Amodal part boxes in the camera frame: the NPCS box mapped by the part pose.

    The NPCS box is centred at the NPCS origin with the given ``npcs_extents``, else (NOCS
    style, as :func:`ancsh.solvers.fit.fit` does) symmetric about the origin and just
    containing the part's inlier NPCS.
    """
    from ..geometry.boxes import OrientedBox

    c = correspondences
    boxes = []
    for j, T in enumerate(poses):
        if c.npcs_extents is not None:
            extents = c.npcs_extents[j]
        else:
            sel = (c.part_labels == j) & inliers
            if not sel.any():
                sel = c.part_labels == j
            extents = 2.0 * np.max(np.abs(c.npcs[sel]), axis=0)
        boxes.append(OrientedBox(np.zeros(3), np.eye(3), extents).transformed(T))
    return tuple(boxes)
