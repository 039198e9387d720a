"""The status of an instance fit at the sensor noise (:class:`NoiseJudge`): does the fit explain the depth, does a
distinct fit explain it as well, has a fit stopped by the iteration limit stopped moving. Articulated ICP uses it
with ``ArticulatedIcpConfig(noise_status=True)`` (``ancsh fit-cad``)."""

from __future__ import annotations

import numpy as np

from ...geometry._checks import check_number, check_positive
from ...geometry.metrics import AD_THRESHOLD
from ..types import FitStatus
from .scoring import NOISE_SIGMAS, DepthSupport, FitScorer, depth_support, noise_tolerance, paired_z
from .template import ArticulatedPose, ModelSurface

__all__ = ["AMBIGUITY_Z", "NoiseJudge", "SCORE_SEED"]

AMBIGUITY_Z = 3.0
"""A rival fit explains the points significantly worse when it puts fewer of them on the model than the best fit by
this many standard errors (:func:`~.scoring.paired_z`, McNemar's test; one-sided 0.13% for normal statistics)."""

SCORE_SEED = 0
"""Seed of the surface samples that score fits at the noise (a constant: the choice must not depend on the fit's
``rng``)."""


class NoiseJudge:
    """Scores fits of one model to one set of points at the sensor noise and gives the best one's status.

    Parameters
    ----------
    model : ArticulatedModel
    points : (N, 3) float64
        Observed points (camera frame, metres), ``N > 10``.
    surface : ModelSurface
        ``model``'s closest-point structure.
    floor : float
        Smallest tolerance (metres): the solver's resolution, e.g. its convergence tolerance.
    share : float
        In ``(0, 1]``: a fit explains the points when at least this share lies within the tolerance of the model and
        at most ``1 - share`` of its visible surface is unobserved (:meth:`DepthSupport.explains`).
    """

    def __init__(self, model, points, surface: ModelSurface, floor: float, share: float):
        self.model, self.surface = model, surface
        self.share = check_number(share, "share", minimum=0.0, maximum=1.0, lower_open=True)
        self.scorer = FitScorer(points, SCORE_SEED)
        self.samples, self.labels, _ = self.scorer.samples(surface)
        self.tolerance, self.sigma = noise_tolerance(points, check_positive(floor, "floor"))
        self.diameters = []
        for j in range(model.num_parts):
            p = self.samples[self.labels == j]
            self.diameters.append(float(np.max(np.linalg.norm(p[:, None] - p[None], axis=2))) if len(p) else 0.0)

    def support(self, estimate: ArticulatedPose) -> DepthSupport:
        """:func:`~.scoring.depth_support` of ``estimate`` at the tolerance."""
        return depth_support(self.scorer, self.surface, estimate.part_poses(self.model), self.tolerance)

    def explains(self, support: DepthSupport) -> bool:
        return support.explains(self.share)

    def distinct(self, a: ArticulatedPose, b: ArticulatedPose) -> bool:
        """Some part of ``a`` is more than :data:`~ancsh.geometry.metrics.AD_THRESHOLD` of its diameter (mean distance
        of its surface samples) from the same part of ``b``."""
        pa, pb = a.part_poses(self.model), b.part_poses(self.model)
        for j, d in enumerate(self.diameters):
            p = self.samples[self.labels == j]
            if len(p) and np.mean(np.linalg.norm(pa[j].apply(p) - pb[j].apply(p), axis=1)) > AD_THRESHOLD * d:
                return True
        return False

    def verdict(self, estimates, supports, best: int, status: FitStatus, message: str, step: float,
                max_iterations: int) -> tuple[FitStatus, str]:
        """``(status, message)`` of ``estimates[best]``, whose solver status is ``SUCCESS`` or ``MAX_ITER``.

        Parameters
        ----------
        estimates : sequence of ArticulatedPose
            Every finished fit (the best and its rivals); ``supports`` their :meth:`support`.
        best : int
        status, message : FitStatus, str
            The solver's status and message of the best fit.
        step : float
            How far its last iteration moved its parts (metres, farthest model point).
        max_iterations : int
            The iteration limit (for the message).
        """
        sup, fit = supports[best], estimates[best]
        noise = (f"{self.tolerance:.3g} ({NOISE_SIGMAS:g} x the sensor noise {self.sigma:.2g} estimated from the "
                 "points, or the solver's resolution)")
        if not self.explains(sup):
            return FitStatus.LARGE_RESIDUAL, (
                f"{message}, but {100 * sup.share:.0f}% of the points lie within {noise} of the model and "
                f"{100 * sup.unobserved:.0f}% of its visible surface is unobserved (at least {100 * self.share:.0f}% "
                f"and at most {100 * (1 - self.share):.0f}% are needed): the fit does not explain the depth")
        for i, (other, s2) in enumerate(zip(estimates, supports)):
            if i == best or not self.explains(s2) or not self.distinct(fit, other):
                continue
            z = paired_z(sup, s2)
            if z < AMBIGUITY_Z:
                return FitStatus.AMBIGUOUS, (
                    f"{message}, but a fit turned away from it (some part beyond {AD_THRESHOLD:g} of its diameter) "
                    f"explains the points as well: {100 * s2.share:.0f}% against {100 * sup.share:.0f}% within "
                    f"{noise}, "
                    f"{z:.1f} standard errors worse ({AMBIGUITY_Z:g} needed): the depth cannot tell them apart")
        if status == FitStatus.MAX_ITER and step < self.tolerance:
            return FitStatus.SUCCESS, (
                f"converged to the sensor noise: {100 * sup.share:.0f}% of the points within {noise} of the model, "
                f"the last of {max_iterations} iterations moved no part by more than {step:.2g}")
        return status, message
