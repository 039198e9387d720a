"""Cold fits of one frame, the per-frame baseline of tracking and its re-initialisation: the provider, RANSAC and
the formulation (:func:`fit_frame`), judged by the plausibility checks of ``ancsh predict`` and a residual limit
(:func:`check_fit`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..solvers.fit import fit
from ..solvers.types import FitResult, FitStatus, Observation
from .config import TrackerConfig, with_provider_fit

__all__ = ["check_fit", "cold_fit", "fit_frame", "tracked_category"]


def tracked_category(category, provider):
    """The :class:`~ancsh.learned.inference.category.Category` of a tracker's ``category`` (a name, spec file, folder
    or Category, loaded once; a name without a convention allowed where it is the provider's network's), ``None`` for
    none."""
    if category is None:
        return None
    from ..learned.inference.category import load_category

    return load_category(category, network_category=getattr(provider, "category", None))


def check_fit(result: FitResult, points_cam, correspondences, category, max_relative_residual: float) -> FitResult:
    """The fit, or a copy with the failed status of the first plausibility check it fails (``category``: a
    :class:`~ancsh.learned.inference.category.Category` or ``None``).

    The checks of ``ancsh predict`` (:func:`ancsh.learned.inference.predict.check_plausibility`: inliers,
    the category's size range, its residual limit), then a residual limit relative to the
    fitted object: a part (with at least 20 points) whose median distance between its points and
    their fitted NPCS exceeds ``max_relative_residual`` object diagonals is ``large_residual``.
    """

    from ..learned.inference.predict import check_plausibility, part_quality

    if not result.ok:
        return result
    quality = part_quality(result, points_cam, correspondences)
    checked = check_plausibility(result, correspondences.part_labels, None if category is None else category.convention,
                                 quality)
    if not checked.ok:
        return checked
    L = float(np.median([T.scale / g for T, g in zip(result.T_cam_npcs, correspondences.npcs_scale)]))
    for j, q in enumerate(quality):
        if q["points"] >= 20 and q["residual_m"] > max_relative_residual * L:
            return dataclasses.replace(result, status=FitStatus.LARGE_RESIDUAL, message=(
                f"check residual: part {j}'s points lie {q['residual_m'] / L:.3g} object diagonals (median) from the fit, "
                f"above {max_relative_residual}"))
    return result


def fit_frame(provider, observation: Observation, config: TrackerConfig, category=None, rng=0):
    """An independent (cold) fit of one frame: the provider, RANSAC + the formulation, the checks (``category``: a
    name, spec file, folder or loaded Category, :func:`tracked_category`; ``None``: no category checks).

    Returns ``(FitResult, Correspondences or None)``; fewer than ``config.min_points`` points give
    ``too_few_points`` without calling the provider. This is the per-frame baseline of tracking
    and the tracker's re-initialisation.
    """
    result, corr, _ = cold_fit(provider, observation, config, tracked_category(category, provider), rng)
    return result, corr


def cold_fit(provider, observation: Observation, config: TrackerConfig, category, rng):
    """:func:`fit_frame` and whether its result rests on the refinement network's correspondences:
    ``(FitResult, Correspondences or None, refined)`` (``category``: a loaded Category or ``None``)."""
    config = with_provider_fit(config, provider)  # TrackerConfig.fit None: the provider's FitConfig
    if observation.num_points < config.min_points:
        return FitResult.failure(FitStatus.TOO_FEW_POINTS, f"{observation.num_points} points, at least {config.min_points} "
                                 "are needed for a fit", formulation=config.formulation, solver="none",
                                 num_points=observation.num_points), None, False
    corr = provider.correspond(observation)
    result = fit(observation, corr, config.formulation, config.solver, config.fit, rng=rng)
    checked = check_fit(result, observation.points_cam, corr, category, config.max_relative_residual)
    if config.refine_network and checked.ok:  # the refined fit where it passes the checks too
        from ..learned.inference.refine_network import refine_with_network

        ref = refine_with_network(provider.refiner, observation, result, formulation=config.formulation,
                                  config=config.fit, rng=rng)
        if ref.accepted:
            refined = check_fit(ref.result, observation.points_cam, ref.inference.correspondences, category,
                                config.max_relative_residual)
            if refined.ok:
                return refined, ref.inference.correspondences, True
    return checked, corr, False
