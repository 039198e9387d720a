"""Prediction and fusion over time, the tracker's filter: a fit's object pose and joint states as a prior
(:func:`previous_solution`), a warm start moved to a predicted state (:func:`predicted_fit`), the canonical
parameters a fit was solved with (:func:`fitted_canonical`) and their recursive average (:func:`fused_canonical`),
and the carried correspondences re-centred on the network's (:func:`recentred`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..geometry._checks import check_number
from ..geometry.transforms import Sim3
from ..solvers.terms import PreviousSolution
from ..solvers.types import FitResult

__all__ = ["fitted_canonical", "fused_canonical", "predicted_fit", "previous_solution", "recentred"]


def previous_solution(result: FitResult, correspondences, weight: float, state_weight: float) -> PreviousSolution:
    """The :class:`PreviousSolution` of a fit: its object pose through the root part and its joint states.

    Parameters
    ----------
    result : FitResult
        A successful fit.
    correspondences : Correspondences
        The correspondences it was fitted on (their NPCS -> NAOCS map of the root part).
    """
    r = correspondences.root_part
    T = result.T_cam_npcs[r]
    sigma = T.scale / float(correspondences.npcs_scale[r])
    origin = T.translation - sigma * (T.rotation @ np.asarray(correspondences.npcs_translation[r]))
    return PreviousSolution(Sim3.unchecked(T.rotation, origin, sigma), np.asarray(result.joint_states), weight, state_weight)


def fitted_canonical(correspondences, result: FitResult):
    """``correspondences`` with the canonical parameters ``result`` was solved with (:attr:`FitResult.canonical`).

    A fit with free canonical parameters (``FitConfig.naocs_prior_weight > 0``, the default) moves each
    part's NPCS -> NAOCS translation and each pivot by solved offsets; the tracker's predictions
    (:func:`previous_solution`, :func:`predicted_fit`) and carried correspondences must use the moved
    ones, or forward kinematics of the object pose and joint states does not give back the fitted part
    poses (measured on oracle eyeglasses: the temples moved by 3-6 mm along their length, which the
    carried frames' closest-point matches cannot correct). Unchanged where the fit reports none.
    """
    c = getattr(result, "canonical", None)
    if c is None:
        return correspondences
    return dataclasses.replace(correspondences, npcs_translation=c.npcs_translation, joint_pivots_naocs=c.joint_pivots_naocs)


def recentred(carried, network, points_cam, T_cam_npcs, gate: float, threshold: float | None = None):
    """``carried`` correspondences restricted to the points the network's rows keep and shifted to agree with
    them on each part's position along the directions their closest-point matches cannot see.

    A point keeps its carried weight where the carried and the network's label agree and the network's
    NPCS coordinate, posed at ``T_cam_npcs`` (the warm start), lies within ``gate`` metres of it (the
    warm fit's own inlier rule); each part's carried NPCS coordinates are then shifted so that their
    mean over those points equals the network's. The data term's translation of a part is then the
    same for either set of rows at any rotation and scale: in a fused fit the carried rows inform the
    parts' rotations (and the joint states through them), the network's rows their positions -- closest-
    point matches reproduce the predicted pose along a thin part (they cannot see a slide along it),
    where the network's positions are unbiased. Along the directions the part's surface normals do see
    (:func:`~ancsh.geometry.normals.sliding_projector` of the normals of its observed points, ``threshold``),
    the carried rows keep their position: there the closest-point matches hold the previous estimate moved
    by the observed motion, and the fused fit averages positions over time. ``threshold`` ``None``: every
    direction is re-centred.

    Parameters
    ----------
    carried, network : Correspondences
        Of the same ``N`` points.
    points_cam : (N, 3) float64
        The points (camera frame, metres).
    T_cam_npcs : sequence of Sim3
        ``(M,)`` part poses at which the network's inliers are judged.
    gate : float
        Metres.
    threshold : float or None
        Of :func:`~ancsh.geometry.normals.sliding_projector`, ``> 0`` (``None``: re-centre along every direction).
    """
    from ..geometry.normals import estimate_normals, sliding_projector

    if threshold is not None:
        threshold = check_number(threshold, "threshold", minimum=0.0, lower_open=True)
    pts = np.asarray(points_cam, dtype=np.float64)
    normals = None if threshold is None or pts.shape[0] < 3 else estimate_normals(pts)
    npcs = np.array(carried.npcs, dtype=np.float64, copy=True)
    w = np.ones(carried.num_points) if carried.weights is None else np.array(carried.weights, dtype=np.float64)
    keep = np.zeros(carried.num_points, dtype=bool)
    for j, T in enumerate(T_cam_npcs):
        sel = (carried.part_labels == j) & (network.part_labels == j) & (w > 0)
        sel[sel] = np.linalg.norm(T.apply(network.npcs[sel]) - pts[sel], axis=1) <= gate
        keep |= sel
        if np.count_nonzero(sel) >= 3:
            shift = network.npcs[sel].mean(axis=0) - carried.npcs[sel].mean(axis=0)
            if normals is not None:  # the sliding directions, camera frame -> this part's NPCS
                shift = T.rotation.T @ sliding_projector(normals[sel], threshold) @ T.rotation @ shift
            npcs[sel] += shift
    return dataclasses.replace(carried, npcs=npcs, weights=np.where(keep, w, 0.0))


def fused_canonical(network, previous, weight: float):
    """``network`` correspondences with canonical parameters averaged with ``previous``'s (weight ``weight``
    on them): NPCS -> NAOCS scales and translations, joint pivots, and joint axes (normalised) --
    the recursive fusion of tracking applied to the per-frame estimates of the canonical parameters
    (``TrackerConfig.fusion_weight``). ``network`` unchanged where the joint types differ."""
    if previous.num_parts != network.num_parts or tuple(previous.joint_types) != tuple(network.joint_types):
        return network
    a = 1.0 / (1.0 + weight)
    mix = lambda new, old: a * np.asarray(new, dtype=np.float64) + (1.0 - a) * np.asarray(old, dtype=np.float64)  # noqa: E731
    axes = mix(network.joint_axes_naocs, previous.joint_axes_naocs)
    norms = np.linalg.norm(axes, axis=1, keepdims=True)
    axes = np.where(norms > 1e-9, axes / np.maximum(norms, 1e-12), network.joint_axes_naocs)
    return dataclasses.replace(network, npcs_scale=mix(network.npcs_scale, previous.npcs_scale),
                               npcs_translation=mix(network.npcs_translation, previous.npcs_translation),
                               joint_pivots_naocs=mix(network.joint_pivots_naocs, previous.joint_pivots_naocs),
                               joint_axes_naocs=axes)


def predicted_fit(result: FitResult, correspondences, prediction: PreviousSolution) -> FitResult:
    """``result`` with its part poses moved to a predicted object pose and joint states (forward
    kinematics of the reduced program with ``correspondences``' canonical parameters), as a warm start."""
    from ..solvers.program import ProgramKey, get_program
    from ..solvers.terms import CanonicalParameters, KinematicStructure, ProgramInputs, ProgramStart

    prog = get_program(ProgramKey(KinematicStructure.from_correspondences(correspondences), "reduced", False, ()))
    canonical = CanonicalParameters.of(correspondences, correspondences.joint_limits)
    T = prediction.T_cam_naocs
    states = prediction.joint_states
    if correspondences.joint_limits is not None:
        states = np.clip(states, correspondences.joint_limits[:, 0], correspondences.joint_limits[:, 1])
    p = prog.pack(ProgramInputs(T.scale, canonical, ProgramStart(T_cam_naocs=T)))
    poses = prog.unpack(prog.initial_x(states), p).T_cam_npcs
    return dataclasses.replace(result, T_cam_npcs=tuple(poses))
