"""Articulated fitting: RANSAC initialisation, the formulations, and post-processing.

:func:`fit` is the one entry point::

    result = fit(observation, correspondences, formulation="exact_reduced", solver="lm",
                 config=FitConfig(), rng=0)

Every formulation shares the same pipeline:

1. **RANSAC** (:func:`ancsh.solvers.hypotheses.articulated_ransac`): a hypothesis draws 3
   points per part, fits every part by Umeyama (with scale) and is scored on all parts
   jointly by the mean per-part inlier ratio (inlier: distance below ``inlier_threshold``
   object diagonals).
   The best hypothesis is refitted on its inliers: these per-part poses are the
   initialisation (and the whole answer of ``per_part``, the paper's NPCS baseline).
2. **Solve** the formulation's program (built once per kinematic structure, see
   :mod:`ancsh.solvers.program`) on the inliers' moments; optionally re-score the inliers
   with the solved poses and solve again, and/or iterate a robust kernel (IRLS).
3. **Post-process** (paper Sec. 4.4): camera-space joint axes and pivots, joint states
   relative to rest, amodal boxes.

The configuration (:class:`FitConfig`, the formulations :data:`FORMULATIONS`) is :mod:`ancsh.solvers.formulations`;
the result's assembly (camera-space joints, boxes, violations) is :mod:`ancsh.solvers.fit_result`. This module is the
driver: validation of the call, RANSAC or the warm start, the solve loop, the covariances.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ..geometry._checks import check_generator
from ..geometry.robust import robust_loss, robust_weights
from ..geometry.transforms import Sim3
from ..geometry.umeyama import umeyama
from .fit_result import closed_form_costs, fit_result, postprocess
from .formulations import FORMULATIONS, FitConfig, Formulation, has_limits
from .stages import StageClock
from .terms import (
    CanonicalParameters, DataTerm, JointLimitTerm, PreviousSolution, ProgramInputs, ProgramStart, TemporalPriorTerm,
    TermWeights,
)
from .types import Correspondences, FitResult, FitStatus, Observation

__all__ = ["FORMULATIONS", "FitConfig", "Formulation", "fit"]

_MIN_POINTS = 3


# ---------------------------------------------------------------------------------------------
def fit(
    observation: Observation,
    correspondences: Correspondences,
    formulation: str = "exact_reduced",
    solver: str | None = None,
    config: FitConfig | None = None,
    rng=0,
    *,
    warm_start: FitResult | None = None,
    previous: PreviousSolution | None = None,
) -> FitResult:
    """Fit the part poses and joints of an articulated object to one observation.

    Parameters
    ----------
    observation : Observation
        ``N`` points in the camera frame (metres).
    correspondences : Correspondences
        For the same ``N`` points: part labels and NPCS coordinates; NPCS -> NAOCS maps; joints.
    formulation : str
        A key of :data:`FORMULATIONS`.
    solver : str, optional
        A backend supported by the formulation (default: its first).
    config : FitConfig, optional
    rng : numpy.random.Generator or int
        RANSAC randomness.
    warm_start : FitResult, optional
        A successful fit of the same object (e.g. the previous frame's, tracking): its part poses
        replace RANSAC as the initialisation (the inliers are the points within
        ``config.inlier_threshold`` of them; all of a part's points where fewer than 3 are) and
        its object scale is kept.
    previous : PreviousSolution, optional
        Adds :class:`~ancsh.solvers.terms.TemporalPriorTerm` toward this prediction to the
        program (formulations with a program; ``per_part`` refuses it).

    Returns
    -------
    FitResult
        With a failure status (never an exception) when the data cannot be fitted: too few
        points on a part, degenerate samples, solver failure.

    Raises
    ------
    ValueError
        For bad arguments: wrong types, mismatched point counts, unknown formulation/solver.
    """
    clock = StageClock()  # records the stages inside ancsh.solvers.stages.record_stages (else idle)
    try:
        return _fit(clock, observation, correspondences, formulation, solver, config, rng, warm_start, previous)
    finally:
        clock.close()


def _fit(clock, observation, correspondences, formulation, solver, config, rng, warm_start, previous) -> FitResult:
    """:func:`fit` (same arguments) with its stage clock."""
    start = time.perf_counter()
    if not isinstance(observation, Observation):
        raise ValueError(f"observation: expected an Observation, got {type(observation).__name__}")
    if not isinstance(correspondences, Correspondences):
        raise ValueError(f"correspondences: expected Correspondences, got {type(correspondences).__name__}")
    if correspondences.num_points != observation.num_points:
        raise ValueError(
            f"correspondences: {correspondences.num_points} points do not match the observation's {observation.num_points}"
        )
    if formulation not in FORMULATIONS:
        raise ValueError(f"formulation: expected one of {sorted(FORMULATIONS)}, got {formulation!r}")
    form = FORMULATIONS[formulation]
    solver = form.solvers[0] if solver is None else solver
    if solver not in form.solvers:
        raise ValueError(f"solver: formulation {formulation!r} supports {list(form.solvers)}, got {solver!r}")
    config = FitConfig() if config is None else config
    if not isinstance(config, FitConfig):
        raise ValueError(f"config: expected a FitConfig, got {type(config).__name__}")
    rng = check_generator(rng)
    if warm_start is not None:
        if not isinstance(warm_start, FitResult):
            raise ValueError(f"warm_start: expected a FitResult, got {type(warm_start).__name__}")
        if not warm_start.ok or warm_start.num_parts != correspondences.num_parts:
            raise ValueError(f"warm_start: expected a successful fit of {correspondences.num_parts} parts, got status "
                             f"{warm_start.status.value} with {warm_start.num_parts} parts")
    if (warm_start is not None or previous is not None) and form.parameterisation is None:
        raise ValueError(f"warm_start, previous: formulation {formulation!r} has no program to warm-start or to add "
                         "a temporal prior to")
    if previous is not None:
        if not isinstance(previous, PreviousSolution):
            raise ValueError(f"previous: expected a PreviousSolution, got {type(previous).__name__}")
        if len(previous.joint_states) != correspondences.num_joints:
            raise ValueError(f"previous.joint_states: expected {correspondences.num_joints} states, "
                             f"got {len(previous.joint_states)}")
    clock.mark("validate")
    fitter = _Fit(observation, correspondences, form, solver, config, rng, start, clock)
    fitter.warm_start, fitter.previous = warm_start, previous
    result = fitter.run()
    if not (result.ok and has_limits(config, correspondences)):
        return result
    from .limits import check_joint_range

    bounded = JointLimitTerm in form.term_classes or form.parameterisation == "reduced"
    # The unbounded refit only says where the data put the states: no covariance for it.
    checked = check_joint_range(
        result, correspondences.joint_limits, [t.value == "revolute" for t in correspondences.joint_types],
        bounded=bounded, unbounded=lambda: fit(observation, correspondences, formulation, solver,
                                               replace(config, enforce_limits=False, uncertainty=False), 0,
                                               warm_start=result, previous=previous))
    clock.mark("limits")
    return checked


_PROGRAMS: dict = {}


def _cached_program(structure, form: Formulation, config: FitConfig, corr: Correspondences, temporal: bool,
                    covariance: bool):
    """The program of a solve (``covariance=False``: the formulation's terms for ``config`` and ``corr``, with the
    temporal prior when ``temporal``) or of its covariance (``covariance=True``: the same with the scale a variable),
    memoised per call signature (building the key re-validated a ``FitConfig`` and hashed the terms on every fit).
    The terms depend on ``corr`` only through :func:`has_limits`, which the memo's key holds.
    """
    memo = (structure, form.name, config, has_limits(config, corr), temporal, covariance)
    prog = _PROGRAMS.get(memo)
    if prog is not None:
        return prog
    from .program import ProgramKey, get_program

    cfg = replace(config, optimize_scale=True) if covariance else config
    terms = form.terms(cfg, corr) + ((TemporalPriorTerm,) if temporal else ())
    key = ProgramKey(structure, form.parameterisation, bool(cfg.optimize_scale), terms,
                     free_canonical=cfg.naocs_prior_weight > 0, npcs_bias=cfg.npcs_bias_weight > 0,
                     npcs_scale_bias=cfg.npcs_scale_bias, npcs_stretch_bias=cfg.npcs_stretch_bias)
    prog = get_program(key)
    if len(_PROGRAMS) > 256:  # a bound for long-lived processes trying many configurations
        _PROGRAMS.clear()
    _PROGRAMS[memo] = prog
    return prog


class _FitFailure(Exception):
    """Raised inside :class:`_Fit` when the data cannot be fitted; :meth:`_Fit.run` turns it into
    a failed :class:`FitResult` (the one failure path)."""

    def __init__(self, status: FitStatus, message: str):
        super().__init__(message)
        self.status, self.message = status, message


@dataclass
class _SolveRun:
    """The state of one program solve: the program, its fixed inputs, the current iterate."""

    program: object
    start: ProgramStart
    x: np.ndarray
    bounds: object  # backends.Bounds
    p: np.ndarray | None = None
    outcome: object = None
    iterations: int = 0
    weights: np.ndarray | None = None  # the point weights of the last solve
    moments: tuple | None = None  # and their per-part moments


class _Fit:
    """One call of :func:`fit` (keeps the per-frame arrays together)."""

    def __init__(self, obs, corr, form, solver, config, rng, start, clock: StageClock | None = None):
        self.corr, self.form, self.solver, self.config, self.rng, self.start = corr, form, solver, config, rng, start
        self.clock = StageClock() if clock is None else clock
        self.points = obs.points_cam
        self.npcs = corr.npcs
        self.labels = corr.part_labels
        self.weights = np.ones(corr.num_points) if corr.weights is None else np.asarray(corr.weights, dtype=float)
        self.M, self.K, self.N = corr.num_parts, corr.num_joints, corr.num_points
        from .terms import KinematicStructure

        self.structure = KinematicStructure.from_correspondences(corr)
        self.canonical = CanonicalParameters.of(corr, self._limits())
        self.term_weights = TermWeights(
            config.soft_weight, config.soft_mu, config.common_scale_weight, config.naocs_prior_weight,
            config.npcs_bias_weight,
        )
        self.warm_start: FitResult | None = None
        self.previous: PreviousSolution | None = None
        self.clock.mark("setup")

    def run(self) -> FitResult:
        """The fit's result; every failure raised below (:class:`_FitFailure`) becomes a status here."""
        try:
            return self._run()
        except _FitFailure as failure:
            return FitResult.failure(
                failure.status, failure.message, formulation=self.form.name, solver=self.solver, num_joints=self.K,
                num_points=self.N, time_s=time.perf_counter() - self.start,
            )

    def _run(self) -> FitResult:
        active = self.weights > 0
        counts = np.bincount(self.labels[active], minlength=self.M)
        if self.N == 0:
            raise _FitFailure(FitStatus.TOO_FEW_POINTS, "the observation has no points")
        short = np.flatnonzero(counts < _MIN_POINTS)
        if short.size:
            raise _FitFailure(
                FitStatus.TOO_FEW_POINTS,
                f"part(s) {short.tolist()} have fewer than {_MIN_POINTS} points (counts {counts[short].tolist()})",
            )
        clock = self.clock
        if self.warm_start is not None:
            poses, inliers = self._warm_poses(active)
            clock.mark("ransac")
        else:
            poses, inliers = self._initial_poses(active)
            clock.mark("ransac")
            if self.config.scale_estimator != "umeyama":
                poses = self._rescale(poses, inliers)
        L = float(np.median([T.scale / g for T, g in zip(poses, self.corr.npcs_scale)]))
        clock.mark("rescale")
        if self.form.parameterisation is None:
            moments = self._moments(inliers, self.weights, L)
            clock.mark("moments")
            costs = closed_form_costs(self.structure, self.canonical, poses, L, moments)
            clock.mark("extract")
            uncertainty = self._uncertainty(poses, None, inliers, self.weights, moments, L)
            clock.mark("covariance")
            return self._finish(poses, inliers, L, FitStatus.SUCCESS, "per-part Umeyama on RANSAC inliers", 0, costs,
                                self.canonical, uncertainty)
        run = self._start_solve(poses, L)
        clock.mark("program")
        inliers = self._solve_loop(run, inliers, L)
        return self._extract(run, inliers, L)

    # -- RANSAC + per-part Umeyama ------------------------------------------------------------
    def _initial_poses(self, active: np.ndarray) -> tuple[list, np.ndarray]:
        """Per-part poses (RANSAC + Umeyama, or Umeyama on all points) and the inlier mask ``(N,)``."""
        from .hypotheses import articulated_ransac

        idx_active = np.flatnonzero(active)
        pts, c, lab = self.points[active], self.npcs[active], self.labels[active]
        w = self.weights[active] if self.corr.weights is not None else None
        cfg = self.config
        if cfg.ransac:
            res = articulated_ransac(
                pts, c, lab, self.M, None, self.rng, relative_threshold=cfg.inlier_threshold,
                npcs_scale=self.corr.npcs_scale, weights=w,
                max_hypotheses=cfg.ransac_iterations, confidence=cfg.ransac_confidence,
            )
            if not res.success:
                raise _FitFailure(FitStatus.DEGENERATE, f"RANSAC: {res.message}")
            model, inl = res.poses, res.inliers
            counts = np.bincount(lab[inl], minlength=self.M)
            if np.any(counts < _MIN_POINTS):
                raise _FitFailure(
                    FitStatus.TOO_FEW_POINTS,
                    f"RANSAC left part(s) {np.flatnonzero(counts < _MIN_POINTS).tolist()} with < {_MIN_POINTS} inliers",
                )
        else:
            model = []
            for j in range(self.M):
                sel = lab == j
                try:
                    model.append(umeyama(c[sel], pts[sel], weights=None if w is None else w[sel]))
                except ValueError as exc:
                    raise _FitFailure(FitStatus.DEGENERATE, f"part {j}: {exc}") from exc
            inl = np.ones(len(pts), dtype=bool)
        inliers = np.zeros(self.N, dtype=bool)
        inliers[idx_active[inl]] = True
        return list(model), inliers

    def _warm_poses(self, active: np.ndarray) -> tuple[list, np.ndarray]:
        """The warm start's part poses and the inliers ``(N,)`` within the inlier threshold of them
        (all of a part's active points where fewer than 3 are)."""
        poses = list(self.warm_start.T_cam_npcs)
        L = float(np.median([T.scale / g for T, g in zip(poses, self.corr.npcs_scale)]))
        inliers = active & (self._point_distances(poses) <= self.config.inlier_threshold * L)
        for j in range(self.M):
            sel = active & (self.labels == j)
            if np.count_nonzero(inliers & sel) < _MIN_POINTS:
                inliers |= sel
        return poses, inliers

    def _rescale(self, poses: list, inliers: np.ndarray) -> list:
        """``poses`` with the RMS-spread-ratio (``symmetric``) or reverse-regression (``reverse``) scale of each
        part's inliers and the matching translation (all parts in one pass; a part without spread keeps its pose)."""
        lab, w = self.labels[inliers], self.weights[inliers]
        p, c = self.points[inliers], self.npcs[inliers]
        W = np.zeros((self.M, len(lab)))
        W[lab, np.arange(len(lab))] = w
        W /= W.sum(axis=1, keepdims=True)  # (M, n): each part's normalised weights
        pbar, cbar = W @ p, W @ c
        dp, dc = p - pbar[lab], c - cbar[lab]
        var_p, var_c = W @ np.einsum("ij,ij->i", dp, dp), W @ np.einsum("ij,ij->i", dc, dc)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.sqrt(var_p / var_c)
            if self.config.scale_estimator == "reverse":
                R = np.stack([T.rotation for T in poses])
                cross = (W[:, :, None] * dp).transpose(0, 2, 1) @ dc  # (M, 3, 3): sum w (p - pbar)(c - cbar)^T
                cov = np.sum(cross * R, axis=(1, 2))  # tr(R^T cov(p, c))
                # = s_sym^2 / s_umeyama; capped at 2 s_sym (correlation below 0.5: no usable match)
                s = var_p / np.maximum(cov, 0.5 * np.sqrt(var_p * var_c))
        return [T if not (var_c[j] > 0 and var_p[j] > 0) else
                Sim3.unchecked(T.rotation, pbar[j] - s[j] * (T.rotation @ cbar[j]), s[j]) for j, T in enumerate(poses)]

    # -- program solve --------------------------------------------------------------------------
    def _start_solve(self, poses: list, L: float) -> _SolveRun:
        """The formulation's program, its start (per-part poses moved onto the joints for
        ``exact_maximal``) and bounds."""
        from .backends import Bounds

        prog = _cached_program(self.structure, self.form, self.config, self.corr, self.previous is not None, False)
        limits = self._limits()
        if self.form.name == "exact_maximal" and self.K:
            poses = self._onto_joints(poses, L, limits)
        return _SolveRun(prog, self._start(poses, L), self._x_start(prog, poses, limits), Bounds.of(prog, limits))

    def _solve_loop(self, run: _SolveRun, inliers: np.ndarray, L: float) -> np.ndarray:
        """Solve; optionally reweight (IRLS) and re-score the inliers and solve again.

        Leaves the last outcome (and its parameters) in ``run``; returns the final inliers.
        """
        from .backends import SolverOptions, solve

        cfg, clock = self.config, self.clock
        prog = run.program
        opts = SolverOptions(cfg.max_iterations, cfg.tol)
        weights = self.weights.copy()
        rounds = cfg.irls_iterations if cfg.robust else 1
        for rescore in range(cfg.rescore_rounds + 1):
            for _ in range(rounds):
                run.weights, run.moments = weights, self._moments(inliers, weights, L)
                clock.mark("moments")
                inputs = ProgramInputs(L, self.canonical, run.start, run.moments, self.term_weights, self.previous)
                run.p = prog.pack(inputs)
                clock.mark("pack")
                run.outcome = solve(self.solver, prog, run.p, run.x, run.bounds, opts)
                clock.mark("solve")
                clock.solver(run.outcome.timings)
                run.iterations += run.outcome.iterations
                if run.outcome.status != FitStatus.SUCCESS:
                    return inliers
                run.x = run.outcome.x
                if cfg.robust:
                    weights = self._irls_weights(prog.unpack(run.x, run.p).T_cam_npcs, L)
            if rescore == cfg.rescore_rounds:
                return inliers
            new_inliers = self._rescore(prog.unpack(run.x, run.p).T_cam_npcs, L, inliers)
            if np.array_equal(new_inliers, inliers):
                return inliers
            inliers = new_inliers
        return inliers

    def _extract(self, run: _SolveRun, inliers: np.ndarray, L: float) -> FitResult:
        """The result of the last solve: poses, costs, joints (with adjusted canonical parameters)."""
        prog, outcome = run.program, run.outcome
        solution = prog.unpack(outcome.x, run.p)
        solved = list(solution.T_cam_npcs)
        if not all(np.all(np.isfinite(T.rotation)) and np.all(np.isfinite(T.translation)) and np.isfinite(T.scale) and T.scale > 0
                   for T in solved):
            raise _FitFailure(FitStatus.NUMERICAL_FAILURE, f"non-finite or non-positive pose after solve ({outcome.message})")
        costs = dict(zip(prog.cost_names, np.asarray(prog.term_costs(outcome.x, run.p)).ravel().tolist()))
        if self.config.robust:
            costs["robust_data"] = self._robust_energy(solved, inliers, L)
        canonical = self.canonical
        if solution.canonical_offsets is not None:  # report joints with the adjusted canonical parameters
            canonical = canonical.with_offsets(solution.canonical_offsets)
        self.clock.mark("extract")
        uncertainty = self._uncertainty(solved, solution, inliers, run.weights, run.moments, L)
        self.clock.mark("covariance")
        return self._finish(solved, inliers, L, outcome.status, outcome.message, run.iterations, costs, canonical,
                            uncertainty)

    def _uncertainty(self, poses: list, solution, inliers: np.ndarray, weights: np.ndarray, moments: tuple, L: float):
        """The covariances at the solution (:mod:`.uncertainty`), in the formulation's program with the
        object scale (per part: every scale) as a variable; ``None`` when switched off.

        ``solution``: the program's :class:`~ancsh.solvers.program.Solution` (``None`` for ``per_part``,
        whose coordinates are each part's own SE(3) + scale).
        """
        if not self.config.uncertainty:
            return None
        from .program import ProgramKey, get_program
        from .uncertainty import effective_points, fit_covariance

        if solution is None:
            prog = get_program(ProgramKey(self.structure, "maximal", True, (DataTerm,)))
        else:
            prog = _cached_program(self.structure, self.form, self.config, self.corr, False, True)
        states = offsets = bias = None
        if solution is not None:
            states = solution.joint_states if prog.has_joint_states else None
            offsets, bias = solution.canonical_offsets, solution.npcs_bias
        x = prog.initial_x(states, offsets, bias)
        start = ProgramStart(tuple(poses), None if solution is None else solution.T_cam_naocs)
        p = prog.pack(ProgramInputs(L, self.canonical, start, moments, self.term_weights))
        points = [effective_points(weights[inliers & (self.labels == j) & (weights > 0)]) for j in range(self.M)]
        return fit_covariance(prog, x, p, points)

    def _onto_joints(self, poses: list, L: float, limits: np.ndarray) -> list:
        """The per-part poses moved onto the joints: the root part's pose and each joint's state
        (from the per-part poses, clipped to the limits) through forward kinematics; scales kept.

        The exact maximal program starts there, feasible, as the reduced one does: started from
        the raw per-part poses, a thin part fitted upside down stays in that basin (the joint
        equalities then hold with the part turned about its axis).
        """
        from .program import ProgramKey, get_program

        prog = get_program(ProgramKey(self.structure, "reduced", False, ()))
        x0 = self._x_start(prog, poses, limits)
        moved = prog.unpack(x0, prog.pack(ProgramInputs(L, self.canonical, self._start(poses, L)))).T_cam_npcs
        return [Sim3.unchecked(M.rotation, M.translation, T.scale) for M, T in zip(moved, poses)]

    def _limits(self) -> np.ndarray:
        if self.config.enforce_limits and self.corr.joint_limits is not None:
            return np.asarray(self.corr.joint_limits, dtype=float)
        return np.tile([-np.inf, np.inf], (self.K, 1))

    def _start(self, poses: list, L: float) -> ProgramStart:
        """Both parameterisations' start from the per-part poses (the object pose through the root part)."""
        r = self.structure.root
        T = poses[r]
        sigma_root = T.scale / self.corr.npcs_scale[r]
        tau0 = T.translation - sigma_root * (T.rotation @ self.corr.npcs_translation[r])
        return ProgramStart(tuple(poses), Sim3.unchecked(T.rotation, tau0, L))

    def _x_start(self, prog, poses, limits) -> np.ndarray:
        """The start ``x``: joint states (reduced) read off the per-part poses, clipped to the limits."""
        states = None
        if prog.has_joint_states:
            _, _, states = postprocess(self.structure, poses, self.canonical)
            states = np.clip(states, limits[:, 0], limits[:, 1])
        return prog.initial_x(states)

    def _moments(self, inliers: np.ndarray, weights: np.ndarray, L: float) -> tuple:
        from .terms import parts_moments

        sel = inliers & (weights > 0)
        return parts_moments(self.points[sel], self.npcs[sel], self.labels[sel], weights[sel], self.M, L)

    def _point_distances(self, poses: list) -> np.ndarray:
        d = np.empty(self.N)
        for j, T in enumerate(poses):
            sel = self.labels == j
            d[sel] = np.linalg.norm(self.points[sel] - (T.scale * self.npcs[sel] @ T.rotation.T + T.translation), axis=1)
        return d

    def _rescore(self, poses: list, L: float, current: np.ndarray) -> np.ndarray:
        """Inliers of the solved poses (``current`` if some part would keep < 3)."""
        inl = (self._point_distances(poses) <= self.config.inlier_threshold * L) & (self.weights > 0)
        counts = np.bincount(self.labels[inl], minlength=self.M)
        return current if np.any(counts < _MIN_POINTS) else inl

    def _irls_weights(self, poses: list, L: float) -> np.ndarray:
        r = self._point_distances(poses) / L
        return self.weights * robust_weights(r, self.config.robust, self.config.robust_scale)

    def _robust_energy(self, poses: list, inliers: np.ndarray, L: float) -> float:
        rho = robust_loss(self._point_distances(poses) / L, self.config.robust, self.config.robust_scale)
        total = 0.0
        for j in range(self.M):
            sel = inliers & (self.labels == j)
            w = self.weights[sel]
            total += float(w @ rho[sel] / w.sum())
        return total

    # -- post-processing ------------------------------------------------------------------------

    # -- the result ---------------------------------------------------------------------------
    def _finish(self, poses, inliers, L, status, message, iterations, costs: dict, canonical, uncertainty=None) -> FitResult:
        result = fit_result(
            self.structure, self.corr, poses, inliers, L, canonical, self._limits(), formulation=self.form.name,
            solver=self.solver, status=status, message=message, iterations=iterations, costs=costs,
            uncertainty=uncertainty, box_extents=self.config.box_extents, time_s=time.perf_counter() - self.start)
        self.clock.mark("result")
        return result
