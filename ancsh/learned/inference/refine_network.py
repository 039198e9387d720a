"""A second (and third) pass of a refinement network on pose-canonicalised input.

The first pass fits the first-stage network's correspondences. Its base part's rotation
``R_cam_naocs`` is the object's estimated orientation; the observed points, rotated by its
transpose, are close to the NAOCS orientation, which is what a refinement network
(:attr:`~ancsh.learned.network.config.TrainConfig.refine_perturb_deg`, the second stage of CAPTRA
and DeepIM) was trained on. Its predictions are canonical (segmentation, NPCS, NPCS -> NAOCS
scale and translation, NAOCS joint votes), so they pair with the unrotated camera-frame points
and the same exact fit runs again. Passes repeat while the object's rotation still moves.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ...solvers.types import FitResult, Observation

__all__ = ["DEFAULT_PASSES", "NetworkRefinement", "passes_text", "refine_with_network"]

DEFAULT_PASSES = 1
"""Passes of the refinement network at test time (CAPTRA and DeepIM use 1-4). One: measured against two on 300 test
frames of each shipped refiner's category (``docs/results/refine_network.md``), one pass errs less on the oven,
drawer and washing machine, as much on the eyeglasses and 0.14 deg more on the laptop, at half the cost."""


def passes_text(passes: int) -> str:
    """``"1 pass"``, ``"2 passes"``: a count of passes as reports and reasons write it."""
    return f"{passes} pass{'es' if passes > 1 else ''}"


@dataclass(frozen=True)
class NetworkRefinement:
    """The outcome of :func:`refine_with_network`.

    Attributes
    ----------
    result : FitResult
        The last successful pass's fit (the input fit when no pass succeeded).
    inference : Inference or None
        That pass's network output and correspondences (``None`` when no pass succeeded).
    accepted : bool
        Whether at least one pass succeeded (``result`` is a refined fit).
    passes : int
        Passes run.
    rotation_change_deg : tuple of float
        Per successful pass, the angle (degrees) between the object rotation it started from and the one it fitted.
    reason : str
        Why it stopped.
    time_s : float
        Wall time of the refinement alone (network passes and fits), seconds.
    """

    result: FitResult
    inference: object  # ancsh.learned.inference.provider.Inference or None
    accepted: bool
    passes: int
    rotation_change_deg: tuple
    reason: str
    time_s: float


def refine_with_network(refiner, observation: Observation, fit_result: FitResult, *, formulation: str = "exact_reduced",
                        passes: int = DEFAULT_PASSES, config=None, rng=0, tol_deg: float = 0.25) -> NetworkRefinement:
    """Refine a fit with a refinement network's correspondences on the points in its NAOCS orientation.

    Parameters
    ----------
    refiner : LearnedProvider
        A provider of a refinement network (``network.config.is_refiner``).
    observation : Observation
        The observed points (camera frame, metres) the fit was made on.
    fit_result : FitResult
        The first fit (successful, with part poses).
    formulation : str
        Formulation of the refined fits (:func:`ancsh.solvers.fit`).
    passes : int
        At most this many passes.
    config : FitConfig, optional
        Of the refined fits (default: the refiner's, :meth:`LearnedProvider.fit_config`).
    rng : int or numpy.random.Generator
        Seeds the fits' RANSAC.
    tol_deg : float
        Stop once a pass moves the object's rotation less than this (degrees).

    Returns
    -------
    NetworkRefinement
    """
    from ...geometry.rotations import rotation_angle
    from ...solvers import fit
    from ...model.articulated import joint_tree_root

    if not getattr(refiner.network.config, "is_refiner", False):
        raise ValueError(f"refiner: {refiner.network.source} is a first-stage network, not a refinement network "
                         "(TrainConfig.refine_perturb_deg = 0)")
    if isinstance(passes, bool) or int(passes) != passes or passes < 1:
        raise ValueError(f"passes: expected a positive integer, got {passes!r}")
    if not isinstance(fit_result, FitResult) or not fit_result.ok or not fit_result.T_cam_npcs:
        raise ValueError("fit_result: expected a successful fit with part poses")
    root = joint_tree_root(refiner.num_parts, refiner.network.joint_children)
    t0 = time.perf_counter()
    result, inference, changes = fit_result, None, []
    reason = passes_text(int(passes))
    for p in range(int(passes)):
        R_start = result.T_cam_npcs[root].rotation
        inf = refiner.infer(observation, input_rotation=R_start.T)
        r = fit(observation, inf.correspondences, formulation, config=refiner.fit_config() if config is None else config,
                rng=rng)
        if not r.ok or not r.T_cam_npcs:
            reason = f"pass {p + 1}: the fit failed ({r.status.value}: {r.message})"
            break
        changes.append(float(np.degrees(rotation_angle(R_start.T @ r.T_cam_npcs[root].rotation))))
        result, inference = r, inf
        if changes[-1] < tol_deg:
            reason = f"converged after {p + 1} pass(es) (rotation moved {changes[-1]:.2f} deg < {tol_deg:g})"
            break
    return NetworkRefinement(result=result, inference=inference, accepted=inference is not None, passes=p + 1,
                             rotation_change_deg=tuple(changes), reason=reason, time_s=time.perf_counter() - t0)
