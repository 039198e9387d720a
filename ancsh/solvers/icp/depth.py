"""Fitting a known model to one depth image: what ``ancsh fit-cad`` runs (and ``ancsh bench cad-auto`` measures)."""

from __future__ import annotations

import numpy as np

from ...geometry._checks import check_generator, check_int
from ...model.articulated import ArticulatedModel
from ..types import Observation
from .articulated import ArticulatedIcpConfig, articulated_icp, auto_init
from .result import CadFitResult
from .template import ArticulatedPose, ModelSurface

__all__ = ["depth_points", "fit_depth"]


def depth_points(depth, intrinsics, *, max_depth: float | None = None) -> np.ndarray:
    """Camera-frame points ``(N, 3)`` (model units) of every valid pixel of ``depth`` (``> 0``, finite, at most
    ``max_depth``), in row-major pixel order.

    Raises
    ------
    ValueError
        ``depth`` has no valid pixel.
    """
    from ...data.render import backproject

    depth = np.asarray(depth, dtype=np.float64)
    mask = np.isfinite(depth) & (depth > 0)
    if max_depth is not None:
        mask &= depth <= max_depth
    if not mask.any():
        raise ValueError("depth: the image has no valid depth pixel")
    return backproject(np.where(mask, depth, 0.0), intrinsics, mask)


def fit_depth(model: ArticulatedModel, points_cam, *, points: int = 3000, rng=0, init: ArticulatedPose | None = None,
              config: ArticulatedIcpConfig | None = None, surface: ModelSurface | None = None) -> CadFitResult:
    """Fit ``model`` to back-projected depth points as ``ancsh fit-cad`` does.

    A random subset of ``points`` points (all when fewer) is fitted by :func:`articulated_icp`, from ``init`` or,
    without one, from the automatic start :func:`auto_init`.

    Parameters
    ----------
    model : ArticulatedModel
    points_cam : (N, 3) array_like
        Observed points (camera frame, model units), e.g. :func:`depth_points`.
    points : int
        Size of the subset, ``>= 1``.
    rng : numpy.random.Generator or int
        Draws the subset (and is passed on to :func:`articulated_icp`).
    init : ArticulatedPose, optional
    config : ArticulatedIcpConfig, optional
        Default :meth:`ArticulatedIcpConfig.instance` (symmetric starts, status at the sensor noise).
    surface : ModelSurface, optional
        A reusable closest-point structure of ``model``.
    """
    check_int(points, "points", minimum=1)
    rng = check_generator(rng)
    pts = Observation(points_cam).points_cam
    if pts.shape[0] > points:
        pts = pts[rng.choice(pts.shape[0], points, replace=False)]
    start = init if init is not None else auto_init(model, pts)
    config = ArticulatedIcpConfig.instance() if config is None else config
    return articulated_icp(model, Observation(pts), start, config=config, rng=rng, surface=surface)
