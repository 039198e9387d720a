"""Rigid ICP baselines for CAD-based fitting (open3d ``registration_icp``).

- :func:`whole_object_icp` registers the model, frozen at the initial joint states, as one
  rigid body (joints ignored).
- :func:`per_part_icp` registers every part separately to its own segment of the
  observation. It needs a segmentation: by default the part labels of the template's
  closest points at the *initial* estimate (what a CAD-only pipeline has); ground-truth
  labels may be passed instead (an upper bound for this baseline).

In both, the observation is the ICP source and dense samples of the model surface (with
face normals) the target, because the observation covers only the visible side of the
model: every observed point has a model point near it, not vice versa.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ...geometry._checks import as_points, check_bool, check_generator, check_int, check_positive
from ...geometry.transforms import Sim3
from ...model.articulated import ArticulatedModel, sample_surface_with_normals
from ..types import FitStatus
from .result import CadFitResult, joint_states_from_part_poses
from .template import ArticulatedPose, ModelSurface

__all__ = ["RigidIcpConfig", "per_part_icp", "sample_with_normals", "whole_object_icp"]


@dataclass(frozen=True)
class RigidIcpConfig:
    """Settings of the rigid baselines.

    Attributes
    ----------
    max_distance : float
        Correspondence gating distance (metres).
    point_to_plane : bool
        Point-to-plane instead of point-to-point error.
    max_iterations : int
    samples_per_part : int
        Model surface samples per part (the ICP target).
    min_points : int
        Per-part ICP leaves a part with fewer observed points at its initial pose.
    """

    max_distance: float = 0.1
    point_to_plane: bool = True
    max_iterations: int = 60
    samples_per_part: int = 4000
    min_points: int = 10

    def __post_init__(self):
        check_positive(self.max_distance, "max_distance")
        check_bool(self.point_to_plane, "point_to_plane")
        check_int(self.max_iterations, "max_iterations", minimum=1)
        check_int(self.samples_per_part, "samples_per_part", minimum=10)
        check_int(self.min_points, "min_points", minimum=3)


# Surface samples with face normals (one definition, in the model package).
sample_with_normals = sample_surface_with_normals


def _cloud(points, normals=None):
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points)))
    if normals is not None:
        pc.normals = o3d.utility.Vector3dVector(np.ascontiguousarray(normals))
    return pc


_RELATIVE_CHANGE = 1e-8  # open3d's convergence test: fitness and inlier RMSE change by less than this


def _register(source_cam, target_pts, target_normals, T_cam_target_init: Sim3, config: RigidIcpConfig):
    """ICP of observed points onto model samples.

    Returns ``(T_cam_target, fitness, rmse, converged)``. open3d reports neither the iteration
    count nor whether its convergence test stopped the loop, so ``converged`` is that test applied
    to one more iteration from the result (whose pose is not used).
    """
    import open3d as o3d

    reg = o3d.pipelines.registration
    method = reg.TransformationEstimationPointToPlane() if config.point_to_plane else reg.TransformationEstimationPointToPoint()
    crit = reg.ICPConvergenceCriteria(
        relative_fitness=_RELATIVE_CHANGE, relative_rmse=_RELATIVE_CHANGE, max_iteration=int(config.max_iterations)
    )
    init = T_cam_target_init.inverse().matrix()
    source, target = _cloud(source_cam), _cloud(target_pts, target_normals)
    r = reg.registration_icp(source, target, float(config.max_distance), init, method, crit)
    again = reg.registration_icp(
        source, target, float(config.max_distance), r.transformation, method, reg.ICPConvergenceCriteria(max_iteration=1)
    )
    converged = (abs(again.fitness - r.fitness) < _RELATIVE_CHANGE
                 and abs(again.inlier_rmse - r.inlier_rmse) < _RELATIVE_CHANGE)
    T_target_cam = Sim3.from_matrix(np.asarray(r.transformation))
    return Sim3(T_target_cam.rotation, T_target_cam.translation).inverse(), float(r.fitness), float(r.inlier_rmse), converged


def _check(model, points_cam, init):
    if not isinstance(model, ArticulatedModel):
        raise ValueError(f"model: expected an ArticulatedModel, got {type(model).__name__}")
    pts = as_points(points_cam, "points_cam")
    if not isinstance(init, ArticulatedPose):
        raise ValueError(f"init: expected an ArticulatedPose, got {type(init).__name__}")
    model.check_states(init.q, "init.q")
    return pts


def whole_object_icp(model: ArticulatedModel, points_cam, init: ArticulatedPose, *,
                     config: RigidIcpConfig = RigidIcpConfig(), rng=0) -> CadFitResult:
    """Rigid ICP of the whole model, frozen at ``init.q`` (joints ignored).

    Parameters
    ----------
    model : ArticulatedModel
    points_cam : (N, 3) array_like
        Observed points in the camera frame (metres).
    init : ArticulatedPose
        Initial base pose; its joint states stay fixed.
    config : RigidIcpConfig
    rng : numpy.random.Generator or int
        Seeds the model surface sampling.
    """
    t0 = time.perf_counter()
    pts = _check(model, points_cam, init)
    rng = check_generator(rng)
    fk = model.forward_kinematics(init.q)
    if pts.shape[0] < 3:
        return _failed("whole_object_icp", model, init, f"need at least 3 observed points, got {pts.shape[0]}", t0)
    samples, normals = [], []
    for j, part in enumerate(model.parts):
        p, n = sample_with_normals(part.mesh, config.samples_per_part, rng)
        samples.append(fk[j].apply(p))
        normals.append(fk[j].apply_direction(n))
    T_cam_base, fitness, rmse, converged = _register(
        pts, np.concatenate(samples), np.concatenate(normals), init.T_cam_base, config
    )
    parts = tuple(T_cam_base @ T for T in fk)
    if fitness <= 0:
        status, message = FitStatus.TOO_FEW_POINTS, "no observed point within max_distance of the model"
    elif not converged:
        status, message = FitStatus.MAX_ITER, f"not converged within {config.max_iterations} iterations"
    else:
        status, message = FitStatus.SUCCESS, "converged"
    return CadFitResult(
        method="whole_object_icp", T_cam_parts=parts, q=init.q.copy(), T_cam_base=T_cam_base, status=status,
        message=message, inlier_ratio=fitness, rmse=rmse, iterations=_NOT_REPORTED, time_s=time.perf_counter() - t0,
    )


def per_part_icp(model: ArticulatedModel, points_cam, init: ArticulatedPose, *, labels=None,
                 config: RigidIcpConfig = RigidIcpConfig(), rng=0, surface: ModelSurface | None = None) -> CadFitResult:
    """Rigid ICP of every part separately (joints ignored).

    Parameters
    ----------
    model : ArticulatedModel
    points_cam : (N, 3) array_like
        Observed points in the camera frame (metres).
    init : ArticulatedPose
        Initial estimate; every part starts at its pose under it.
    labels : (N,) array_like of int, optional
        Part of each observed point. Default: the part of the closest model point at ``init``
        (closer than ``config.max_distance``; farther points are dropped).
    config : RigidIcpConfig
    rng : numpy.random.Generator or int
    surface : ModelSurface, optional
        Reused closest-point structure of ``model``.

    Returns
    -------
    CadFitResult
        Joint states read off the relative part poses; ``T_cam_base`` is the base part's pose.
    """
    t0 = time.perf_counter()
    pts = _check(model, points_cam, init)
    rng = check_generator(rng)
    T_init = init.part_poses(model)
    if pts.shape[0] < 3:
        return _failed("per_part_icp", model, init, f"need at least 3 observed points, got {pts.shape[0]}", t0)
    if labels is None:
        surface = surface if surface is not None else ModelSurface(model)
        cp = surface.closest(pts, T_init)
        labels = np.where(cp.distances <= config.max_distance, cp.labels, -1)
    else:
        labels = np.asarray(labels)
        if labels.shape != (pts.shape[0],) or not np.issubdtype(labels.dtype, np.integer):
            raise ValueError(f"labels: expected ({pts.shape[0]},) integer part labels, got {labels.shape} {labels.dtype}")
    poses, fits, rmses, weights, skipped, unconverged = [], [], [], [], [], []
    for j, part in enumerate(model.parts):
        sel = labels == j
        if sel.sum() < config.min_points:
            poses.append(T_init[j])
            skipped.append(part.name)
            continue
        p, n = sample_with_normals(part.mesh, config.samples_per_part, rng)
        T, fit, rmse, converged = _register(pts[sel], p, n, T_init[j], config)
        if not converged:
            unconverged.append(part.name)
        poses.append(T)
        fits.append(fit)
        rmses.append(rmse)
        weights.append(sel.sum())
    if not fits:
        return _failed("per_part_icp", model, init, "no part has enough observed points near the initial estimate", t0)
    w = np.asarray(weights, dtype=float)
    q = joint_states_from_part_poses(model, poses)
    notes = []
    if skipped:
        notes.append(f"parts left at the initial pose (too few points): {skipped}")
    if unconverged:
        notes.append(f"parts not converged within {config.max_iterations} iterations: {unconverged}")
    if all(f == 0 for f in fits):
        status = FitStatus.TOO_FEW_POINTS
        notes.append("no observed point within max_distance of any registered part")
    else:
        status = FitStatus.MAX_ITER if unconverged else FitStatus.SUCCESS
    return CadFitResult(
        method="per_part_icp", T_cam_parts=tuple(poses), q=q, T_cam_base=poses[model.base_index],
        status=status, message="; ".join(notes) or "converged",
        inlier_ratio=float(np.sum(w * np.asarray(fits)) / pts.shape[0]),
        rmse=float(np.sqrt(np.sum(w * np.asarray(rmses) ** 2) / w.sum())), iterations=_NOT_REPORTED,
        time_s=time.perf_counter() - t0,
    )


_NOT_REPORTED = -1  # CadFitResult.iterations of the rigid baselines: open3d does not report the count


def _failed(method, model, init, message, t0, status=FitStatus.TOO_FEW_POINTS) -> CadFitResult:
    return CadFitResult(
        method=method, T_cam_parts=tuple(init.part_poses(model)), q=init.q.copy(), T_cam_base=init.T_cam_base,
        status=status, message=message, time_s=time.perf_counter() - t0,
    )
