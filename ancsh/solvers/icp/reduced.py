"""One reduced-coordinate solve of articulated ICP: the core's reduced program (object pose + joint states)
on template correspondences, from the current estimate and with the model's metric scale fixed
(:func:`reduced_step`), and the Gauss-Newton covariance of its solution (:func:`icp_uncertainty`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...geometry.transforms import Sim3
from ..types import FitStatus
from .template import ArticulatedPose, TemplateProvider

__all__ = ["icp_uncertainty", "reduced_step"]

_REDUCED_CACHE: dict = {}


# ---------------------------------------------------------------------------------------------
# one reduced-coordinate solve
# ---------------------------------------------------------------------------------------------
class _Reduced:
    """The reduced-coordinate program of one model with its static inputs."""

    def __init__(self, provider: TemplateProvider, point_to_plane: bool, point_data: bool = True, prior: bool = False):
        from ..backends import Bounds
        from ..program import ProgramKey, get_program
        from ..terms import CanonicalParameters, DataTerm, KinematicStructure, PointToPlaneTerm, TemporalPriorTerm

        model, cs = provider.model, provider.canonical
        corr = provider.empty_correspondences()
        self.structure = KinematicStructure.from_correspondences(corr)
        terms = ((DataTerm,) if point_data else ()) + ((PointToPlaneTerm,) if point_to_plane else ())
        terms += (TemporalPriorTerm,) if prior else ()
        self.program = get_program(ProgramKey(self.structure, "reduced", False, terms))
        self.model, self.cs = model, cs
        self.diagonal = 1.0 / cs.T_naocs_base.scale  # metres per NAOCS unit
        self.canonical = CanonicalParameters.of(cs)
        self.bounds = Bounds.of(self.program, corr.joint_limits)

    def previous(self, prediction: ArticulatedPose, weight: float, state_weight: float):
        """The :class:`~ancsh.solvers.terms.PreviousSolution` of a predicted estimate (tracking)."""
        from ..terms import PreviousSolution

        T = prediction.T_cam_base @ self.cs.T_naocs_base.inverse()
        return PreviousSolution(Sim3.unchecked(T.rotation, T.translation, self.diagonal),
                                prediction.q - self.model.rest_states, weight, state_weight)

    def inputs(self, estimate: ArticulatedPose, points, corr, point_weight: float, plane: bool, previous=None):
        """The program's inputs: the start at ``estimate`` and the moments of ``corr``."""
        from ..terms import PartMoments, ProgramInputs, ProgramStart, part_moments, plane_moments

        T_cam_naocs = estimate.T_cam_base @ self.cs.T_naocs_base.inverse()
        start = ProgramStart(T_cam_naocs=Sim3.unchecked(T_cam_naocs.rotation, T_cam_naocs.translation, self.diagonal))
        w = np.asarray(corr.weights)
        total = w.sum()
        moments = []
        for j in range(self.model.num_parts):
            sel = (corr.part_labels == j) & (w > 0)
            share = w[sel].sum() / total if total > 0 else 0.0
            if share <= 0 or sel.sum() < 1:
                moments.append(PartMoments.zeros())
                continue
            mom = part_moments(points[sel], corr.npcs[sel], w[sel], self.diagonal)
            a = np.sqrt(share * point_weight)
            Lp = None
            if plane:
                Lp = np.sqrt(share) * plane_moments(points[sel], corr.npcs[sel], corr.normals_npcs[sel], w[sel], mom.pbar)
            moments.append(PartMoments(a * mom.Lm, a * mom.B, a * mom.sqrt_c0, mom.cbar, mom.pbar, Lp))
        return ProgramInputs(self.diagonal, self.canonical, start, tuple(moments), previous=previous)

    def x0(self, estimate: ArticulatedPose) -> np.ndarray:
        return self.program.initial_x(estimate.q - self.model.rest_states)

    def estimate(self, x, p) -> ArticulatedPose:
        """The base pose and absolute joint states at the solution ``x`` (parameters ``p``)."""
        sol = self.program.unpack(x, p)
        T = sol.T_cam_naocs @ self.cs.T_naocs_base
        return ArticulatedPose(Sim3(T.rotation, T.translation), sol.joint_states + self.model.rest_states)


def reduced_step(provider: TemplateProvider, points_cam, corr, *, point_to_plane: bool = True, point_weight: float = 0.05,
                 solver: str = "lsq", max_iterations: int = 20, prior=None):
    """One reduced-coordinate solve on template correspondences, from ``provider.estimate``.

    Parameters
    ----------
    provider : TemplateProvider
        At the current estimate (the start of the solve).
    points_cam : (N, 3) float64
        Observed points (metres, camera frame), aligned with ``corr``.
    corr : TemplateCorrespondences
        ``provider.correspond(points_cam)``.
    prior : (ArticulatedPose, float, float), optional
        ``(prediction, pose weight, joint-state weight)``: adds the
        :class:`~ancsh.solvers.terms.TemporalPriorTerm` toward the predicted estimate (tracking).

    Returns
    -------
    (ArticulatedPose, SolveOutcome)
        The new estimate (``provider.estimate`` when the solve failed) and the backend outcome.
    """
    from ..backends import SolverOptions, solve

    red, p = _program_at(provider, points_cam, corr, point_to_plane, point_weight, prior)
    x0 = red.x0(provider.estimate)
    out = solve(solver, red.program, p, x0, red.bounds, SolverOptions(max_iterations, 1e-12))
    if out.status not in (FitStatus.SUCCESS, FitStatus.MAX_ITER) or not np.all(np.isfinite(out.x)):
        return provider.estimate, out
    return red.estimate(out.x, p), out


def _program_at(provider: TemplateProvider, points_cam, corr, point_to_plane: bool, point_weight: float, prior=None):
    """``(_Reduced, p)``: the reduced program of :func:`reduced_step` and its parameters at ``provider.estimate``."""
    red = _reduced_for(provider, point_to_plane, point_weight > 0 or not point_to_plane, prior is not None)
    previous = None if prior is None else red.previous(*prior)
    inputs = red.inputs(provider.estimate, points_cam, corr, point_weight if point_to_plane else 1.0, point_to_plane,
                        previous)
    return red, red.program.pack(inputs)


def icp_uncertainty(provider: TemplateProvider, points_cam, corr, *, point_to_plane: bool = True,
                    point_weight: float = 0.05):
    """The covariance of an articulated ICP fit at ``provider.estimate``, in the model's part frames.

    Gauss-Newton sandwich of :func:`ancsh.solvers.uncertainty.fit_covariance` on the reduced
    program that :func:`reduced_step` solves (same residuals, same correspondences and robust
    weights; no temporal prior, as for :func:`ancsh.solvers.fit`), with the object scale fixed (a
    CAD model is metric): object pose and one state per joint. The part and object covariances
    are mapped from the program's frames (NPCS, NAOCS) to the frames the ICP result reports
    (``T_cam_parts``, ``T_cam_base``; :meth:`~ancsh.solvers.uncertainty.FitUncertainty.composed`).
    ``noise_std_m`` is each part's weighted RMS closest-point distance (metres): the
    point-to-plane residual, one component per point.

    Parameters
    ----------
    provider : TemplateProvider
        At the fitted estimate.
    points_cam : (N, 3) float64
        Observed points (metres, camera frame).
    corr : TemplateCorrespondences
        ``provider.correspond(points_cam)`` (the final gate).
    point_to_plane, point_weight
        The data terms of the fit (:class:`ArticulatedIcpConfig`).

    Returns
    -------
    FitUncertainty
        Status ``"singular"`` (infinite variances) where the data leave a direction free (a part
        without points, a planar part sliding in its plane), ``"unavailable"`` without enough points.
    """
    from ..uncertainty import effective_points, fit_covariance

    red, p = _program_at(provider, points_cam, corr, point_to_plane, 0.0 if point_to_plane else point_weight)
    x = red.x0(provider.estimate)
    w = np.asarray(corr.weights, dtype=np.float64)
    M = red.model.num_parts
    sel = [(corr.part_labels == j) & (w > 0) for j in range(M)]
    unc = fit_covariance(red.program, x, p, [effective_points(w[s]) for s in sel])
    d = np.asarray(corr.distances, dtype=np.float64)
    noise = np.array([np.sqrt(np.sum(w[s] * d[s] ** 2) / np.sum(w[s])) if s.any() else np.nan for s in sel])
    sol = red.program.unpack(x, p)
    unc = unc.composed(sol.T_cam_npcs, provider.T_npcs_part, sol.T_cam_naocs, red.cs.T_naocs_base)
    return replace(unc, noise_std_m=noise)


def _reduced_for(provider: TemplateProvider, point_to_plane: bool, point_data: bool = True, prior: bool = False) -> _Reduced:
    key = (id(provider.template), point_to_plane, point_data, prior)
    hit = _REDUCED_CACHE.get(key)
    if hit is None or hit[0] is not provider.template:
        if len(_REDUCED_CACHE) > 64:
            _REDUCED_CACHE.clear()
        hit = (provider.template, _Reduced(provider, point_to_plane, point_data, prior))
        _REDUCED_CACHE[key] = hit
    return hit[1]
