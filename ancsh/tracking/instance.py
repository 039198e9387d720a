"""Instance-level tracking of a known articulated model (URDF): warm-started articulated ICP.

:class:`InstanceTracker` fits every frame by a few iterations of articulated ICP
(:func:`ancsh.solvers.icp.articulated.reduced_step` on closest visible model points,
:class:`~ancsh.solvers.icp.template.TemplateProvider`) started at the constant-velocity
prediction of the last two frames, with a shrinking gate and the
:class:`~ancsh.solvers.terms.TemporalPriorTerm` toward that prediction. No multi-start: that is
what makes it fast. When fewer than ``accept_inliers`` of the points lie within the final gate of
the fitted model (the object moved away, or the fit slipped), the frame is fitted cold -- the full
multi-start :func:`~ancsh.solvers.icp.articulated.articulated_icp` from :func:`auto_init` views and
the prediction -- and is ``reinitialised`` when that explains the points, else ``lost``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..geometry._checks import check_bool, check_generator, check_int, check_number, check_positive
from ..geometry.rotations import exp_so3, geodesic_angle, log_so3
from ..geometry.transforms import Sim3
from ..solvers.icp.articulated import (ArticulatedIcpConfig, articulated_icp, auto_init, icp_uncertainty, part_evidence,
                                       reduced_step, unsupported_parts)
from ..solvers.icp.result import CadFitResult
from ..solvers.icp.template import ArticulatedPose, ModelTemplate, TemplateProvider
from ..solvers.types import FitStatus, Observation
from .records import TrackedFrame, TrackStatus

__all__ = ["InstanceTracker", "InstanceTrackerConfig"]


@dataclass(frozen=True)
class InstanceTrackerConfig:
    """Settings of :class:`InstanceTracker`; distances in model diagonals with a floor in metres.

    Attributes
    ----------
    iterations : int
        ICP iterations per warm frame (at most; fewer when it converges).
    extra_iterations : int
        More iterations, only for a frame whose fit does not yet explain ``accept_inliers`` of the
        points after ``iterations`` (a fast motion), before it is fitted cold.
    gate, gate_decay, gate_floor : float
        Gate of the first warm iteration (diagonals), its decay per iteration, its floor (metres).
    tolerance : float
        A warm frame stops when no part moves more than this many diagonals.
    num_points : int
        Random subsample of the observation used per frame.
    solver_iterations : int
        Backend iterations per ICP iteration.
    accept_inliers : float
        Smallest share of points within ``accept_gate`` of the fitted model for a frame to count as
        tracked, in ``(0, 1]``.
    accept_gate : float
        That distance (diagonals; at least twice ``gate_floor``): a few times the sensor noise.
    temporal_weight, temporal_state_weight : float
        Weights of the temporal prior (pose, joint states); both 0 turns it off. Small: at 0.01
        the prior held the fit near the (lagging) prediction (laptop 10101: 3.2 deg mean rotation
        error from a known start vs 0.7 deg at 1e-4, ``docs/results/tracking.md``).
    velocity : float
        Damping of the constant-velocity prediction, in ``[0, 1]``.
    min_points : int
        Fewer observed points: the frame is lost.
    cold : ArticulatedIcpConfig
        The re-initialisation's multi-start ICP.
    uncertainty : bool
        Report the covariances of each warm fit (:func:`~ancsh.solvers.icp.articulated.icp_uncertainty`,
        one more closest-point match); the cold fits follow ``cold.uncertainty``.
    reinitialise : bool
        Fit a frame cold when the warm fit does not explain it (default); ``False``: that frame is
        ``lost`` at once, for a caller that re-initialises by other means (the category tracker
        carrying a category template, :class:`~ancsh.tracking.tracker.CategoryTracker`).
    """

    iterations: int = 2
    extra_iterations: int = 4
    gate: float = 0.05
    gate_decay: float = 0.6
    gate_floor: float = 0.01
    tolerance: float = 1e-3
    num_points: int = 400
    solver_iterations: int = 5
    accept_inliers: float = 0.6
    accept_gate: float = 0.03
    temporal_weight: float = 1e-4
    temporal_state_weight: float = 1e-4
    velocity: float = 1.0
    min_points: int = 30
    cold: ArticulatedIcpConfig = field(default_factory=ArticulatedIcpConfig)
    uncertainty: bool = True
    reinitialise: bool = True

    def __post_init__(self):
        for name, lo in (("iterations", 1), ("extra_iterations", 0), ("num_points", 6), ("solver_iterations", 1),
                         ("min_points", 6)):
            object.__setattr__(self, name, check_int(getattr(self, name), name, minimum=lo))
        for name in ("gate", "gate_floor", "tolerance", "accept_gate"):
            check_positive(getattr(self, name), name)
        for name in ("gate_decay", "accept_inliers"):
            check_number(getattr(self, name), name, minimum=0.0, maximum=1.0, lower_open=True)
        for name in ("temporal_weight", "temporal_state_weight"):
            check_number(getattr(self, name), name, minimum=0.0)
        check_number(self.velocity, "velocity", minimum=0.0, maximum=1.0)
        check_bool(self.uncertainty, "uncertainty")
        check_bool(self.reinitialise, "reinitialise")
        if not isinstance(self.cold, ArticulatedIcpConfig):
            raise ValueError(f"cold: expected an ArticulatedIcpConfig, got {type(self.cold).__name__}")


class InstanceTracker:
    """Tracks a known articulated model through a sequence of observations (see the module docstring).

    Parameters
    ----------
    model : ArticulatedModel
        The instance (e.g. :func:`ancsh.data.urdf.load_urdf`), with a movable joint and meshes.
    config : InstanceTrackerConfig, optional
    rng : int or numpy.random.Generator
        Point subsampling.
    initial : ArticulatedPose, optional
        A known pose of the first frame: it is tracked (warm) from there instead of fitted cold.
    """

    def __init__(self, model, config: InstanceTrackerConfig | None = None, *, rng=0, initial: ArticulatedPose | None = None):
        self.config = InstanceTrackerConfig() if config is None else config
        if not isinstance(self.config, InstanceTrackerConfig):
            raise ValueError(f"config: expected an InstanceTrackerConfig, got {type(self.config).__name__}")
        self.template = ModelTemplate(model)
        self.model = model
        self.diagonal = self.template.T_cam_naocs_scale
        self.radii = [float(np.max(np.linalg.norm(p.vertices, axis=1))) for p in model.parts]
        self.provider = TemplateProvider(self.template, max_distance=1.0, loss="huber",
                                         loss_scale=max(0.01 * self.diagonal, self.config.gate_floor / 3))
        self.rng = check_generator(rng)
        self._last: ArticulatedPose | None = None
        self._before: ArticulatedPose | None = None
        self._index = 0
        self._started = initial is not None
        if initial is not None:
            if not isinstance(initial, ArticulatedPose):
                raise ValueError(f"initial: expected an ArticulatedPose, got {type(initial).__name__}")
            self._last = ArticulatedPose(initial.T_cam_base, model.check_states(initial.q, "initial.q"))

    def reset(self) -> None:
        """Forget the track (the next frame starts cold)."""
        self._last = self._before = None

    def predict(self) -> ArticulatedPose | None:
        """The constant-velocity prediction of the next frame's pose (``None`` without a track)."""
        if self._last is None:
            return None
        if self._before is None or self.config.velocity == 0:
            return self._last
        a, b, damp = self._last.T_cam_base, self._before.T_cam_base, self.config.velocity
        dR = exp_so3(damp * log_so3(a.rotation @ b.rotation.T))
        T = Sim3(dR @ a.rotation, a.translation + damp * (a.translation - b.translation))  # about the base origin
        q = self._last.q + damp * (self._last.q - self._before.q)
        return ArticulatedPose(T, np.clip(q, self.model.lower_limits, self.model.upper_limits))

    def step(self, observation) -> TrackedFrame:
        """Track one more frame.

        Parameters
        ----------
        observation : Observation or (N, 3) array_like
            Observed points (camera frame, metres).
        """
        t0 = time.perf_counter()
        points = observation.points_cam if isinstance(observation, Observation) else Observation(observation).points_cam
        if points.shape[0] and np.any(points[:, 2] <= 0):
            raise ValueError("observation: every point must be in front of the camera (z > 0); points are camera-frame")
        index = self._index
        self._index += 1
        cfg = self.config
        if points.shape[0] < cfg.min_points:
            self.reset()
            return self._lost(index, f"too_few_points: {points.shape[0]} points, at least {cfg.min_points} are needed "
                                     "(object out of view or an empty frame)", t0)
        if points.shape[0] > cfg.num_points:
            points = points[np.sort(self.rng.choice(points.shape[0], cfg.num_points, replace=False))]
        why = ""
        prediction = self.predict()
        if prediction is not None:
            result = self._warm(points, prediction, t0)
            if result.inlier_ratio >= cfg.accept_inliers and result.status != FitStatus.TOO_FEW_INLIERS:
                self._accept(result)
                return self._frame(index, TrackStatus.TRACKED, result.message, result, t0)
            why = (f"warm fit failed ({result.message}); " if result.status == FitStatus.TOO_FEW_INLIERS else
                   f"warm fit lost the object ({result.inlier_ratio:.0%} of the points within the gate); ")
            if not cfg.reinitialise:
                self.reset()
                return self._lost(index, why + "no cold fit (reinitialise is off)", t0)
        inits = auto_init(self.model, points) + ([prediction] if prediction is not None else [])
        result = articulated_icp(self.model, points, inits, config=cfg.cold, rng=self.rng, surface=self.template.surface)
        if result.status not in (FitStatus.SUCCESS, FitStatus.MAX_ITER) or result.inlier_ratio < cfg.accept_inliers:
            self.reset()
            return self._lost(index, f"{why}cold fit failed ({result.status.value}, {result.inlier_ratio:.0%} of the "
                                     f"points within the gate: {result.message})", t0)
        status = TrackStatus.REINITIALISED if self._started else TrackStatus.INITIALISED
        self._started = True
        self.reset()
        self._accept(result)
        return self._frame(index, status, why + "cold fit (multi-start articulated ICP)", result, t0)

    def _warm(self, points, prediction: ArticulatedPose, t0) -> CadFitResult:
        """A few ICP iterations from the prediction, with the temporal prior toward it."""
        cfg = self.config
        prior = None
        if cfg.temporal_weight > 0 or cfg.temporal_state_weight > 0:
            prior = (prediction, cfg.temporal_weight, cfg.temporal_state_weight)
        accept = max(cfg.accept_gate * self.diagonal, 2 * cfg.gate_floor)
        est = prediction
        status, iterations, ratio, rmse = FitStatus.MAX_ITER, 0, 0.0, float("inf")
        for i in range(cfg.iterations + cfg.extra_iterations):
            if i >= cfg.iterations and ratio >= cfg.accept_inliers:
                break  # the extra iterations only for a frame not yet explained
            gate = max(cfg.gate * self.diagonal * cfg.gate_decay**i, cfg.gate_floor)
            prov = self.provider.at(est, max_distance=gate)
            corr = prov.correspond(points)
            inl = corr.distances <= accept
            ratio = float(inl.mean())
            rmse = float(np.sqrt(np.mean(corr.distances[inl] ** 2))) if inl.any() else float("inf")
            if not np.any(corr.weights > 0):
                break
            new, _ = reduced_step(prov, points, corr, solver="lsq", max_iterations=cfg.solver_iterations, prior=prior)
            iterations += 1
            move = max(np.linalg.norm(A.translation - B.translation) + r * geodesic_angle(A.rotation, B.rotation)
                       for A, B, r in zip(new.part_poses(self.model), est.part_poses(self.model), self.radii))
            est = new
            if move < cfg.tolerance * self.diagonal and gate <= cfg.gate_floor + 1e-12:
                status = FitStatus.SUCCESS
                break
        message = "converged" if status == FitStatus.SUCCESS else f"stopped after {iterations} warm iterations"
        near, inl = part_evidence(self.provider, est, points, max(cfg.gate * self.diagonal, cfg.gate_floor), accept)
        weak = unsupported_parts(self.model, near, inl, accept)
        if weak:  # a warm fit always stops after a few iterations (max_iter): the parts' evidence decides
            status, message = FitStatus.TOO_FEW_INLIERS, f"{message}, but {weak}"
        uncertainty = None
        if cfg.uncertainty and iterations:  # at the fit, on the last iteration's correspondences (model points: still valid)
            uncertainty = icp_uncertainty(self.provider.at(est, max_distance=gate), points, corr)
        return CadFitResult("articulated_icp_warm", tuple(est.part_poses(self.model)), est.q.copy(), est.T_cam_base, status,
                            message, inlier_ratio=ratio, rmse=rmse, iterations=iterations, time_s=time.perf_counter() - t0,
                            uncertainty=uncertainty, part_points=tuple(int(n) for n in near),
                            part_inliers=tuple(int(n) for n in inl))

    def _accept(self, result: CadFitResult) -> None:
        self._before = self._last
        self._last = ArticulatedPose(result.T_cam_base, np.clip(result.q, self.model.lower_limits, self.model.upper_limits))

    def _frame(self, index, status, message, result: CadFitResult, t0) -> TrackedFrame:
        return TrackedFrame(index, status, message, result, result.joint_states(self.model), "model", int(result.iterations),
                            time.perf_counter() - t0)

    def _lost(self, index, message, t0) -> TrackedFrame:
        return TrackedFrame(index, TrackStatus.LOST, message, None, np.full(self.model.num_joints, np.nan), "none", 0,
                            time.perf_counter() - t0)
