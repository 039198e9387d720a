"""Articulated fitting: RANSAC initialisation, the formulations, and post-processing.
Long: the fit's validated settings (FitConfig) and the one procedure that reads them (_Fit) belong together.

:func:`fit` is the one entry point::

    result = fit(observation, correspondences, formulation="exact_reduced", solver="ipopt",
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

Formulations (:data:`FORMULATIONS`): ``per_part`` (Umeyama + RANSAC), ``soft`` (paper Sec.
4.3: data + lambda soft joint energies), ``exact_maximal`` (every part SE(3)+scale with exact
joint equalities and limit inequalities, IPOPT), ``exact_reduced`` (object pose + joint
states, joints exact by construction, limits as bounds; IPOPT, least squares or the projected Levenberg-Marquardt ``lm``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, fields, replace

import numpy as np

from ..geometry._checks import check_bool, check_choice, check_generator, check_int, check_number
from ..geometry.robust import robust_loss, robust_weights
from ..geometry.boxes import OrientedBox, unit_diagonal
from ..geometry.transforms import Sim3
from ..geometry.umeyama import umeyama
from .terms import (
    CanonicalParameters, CanonicalPriorTerm, CommonScaleTerm, DataTerm, ExactCommonScaleTerm, ExactJointTerm, JointLimitTerm,
    NpcsBiasPriorTerm, PreviousSolution, ProgramInputs, ProgramStart, SoftJointTerm, TemporalPriorTerm, TermWeights,
)
from .types import Correspondences, FitResult, FitStatus, Observation

__all__ = ["FORMULATIONS", "FitConfig", "Formulation", "fit"]

_MIN_POINTS = 3
SCALE_ESTIMATORS = ("umeyama", "symmetric", "reverse")
FIT_ROBUST_KERNELS = ("huber", "cauchy")
"""The kernels of :data:`ancsh.geometry.robust.ROBUST_LOSSES` that ``FitConfig.robust`` accepts
(Tukey's zero weights could leave a part without points)."""


@dataclass(frozen=True)
class FitConfig:
    """Settings of :func:`fit`, validated on construction.

    Attributes
    ----------
    ransac : bool
        Run RANSAC; ``False`` fits every part on all its points.
    ransac_iterations : int
        Maximum number of minimal samples (the loop stops early at ``ransac_confidence``).
    ransac_confidence : float
        In ``(0, 1]``.
    inlier_threshold : float
        Inlier distance in object diagonals (NAOCS units; the object's size in metres is
        estimated from the RANSAC minimal-sample scales), ``> 0``.
    rescore_rounds : int
        After a solve, recompute the inliers with the solved poses and solve again (at most
        this many times, stopping when the inliers do not change).
    optimize_scale : bool
        ``False`` keeps the initial per-part scales fixed as in the paper (reduced: one object
        scale, the median over parts); ``True`` optimises log-scales.
    scale_estimator : str
        Initial per-part scale on the RANSAC inliers: ``"umeyama"`` (the least-squares scale of
        the Umeyama fit, as in the paper; shrunk by noise on the NPCS coordinates) or
        ``"symmetric"`` (the geometric mean of the forward and reverse least-squares scales,
        i.e. the ratio of RMS spreads ``sqrt(var(p) / var(c))``: half the shrinkage under NPCS
        noise) or ``"reverse"`` (default: the least-squares scale of the reverse regression, camera
        onto NPCS, ``var(p) / tr(R^T cov(p, c))``; NPCS noise does not shrink it, and the
        translation of the NPCS origin, which carries the scale error times the distance from the
        observed points to that origin, comes out lower: ``docs/results/fit_translation.md``).
        The translation is re-centred for the chosen scale.
    soft_weight : float
        ``lambda`` of the paper's soft joint energies (``soft``), ``>= 0``.
    soft_mu : float
        ``mu`` of the prismatic soft energy, ``>= 0``.
    common_scale_weight : float
        Weight of the soft common-object-scale term (``soft`` with ``optimize_scale``); 0 = off.
        (``exact_maximal`` with ``optimize_scale`` holds one object scale exactly.)
    naocs_prior_weight : float
        0: the provider's canonical parameters (NPCS -> NAOCS translations ``G_t``, revolute
        pivots) are taken as exact (as in the paper, :meth:`paper`). ``> 0`` (default 0.1): they
        get offset variables with this prior weight (energy ``w |offset|^2`` in NAOCS units beside the data energies), so the joints
        hold exactly for adjusted parameters that the data may move -- useful when the
        provider's NAOCS parameters are noisy; the reported pivots use the adjusted values.
    npcs_bias_weight : float
        0 (default): off. ``> 0``: per-part NPCS-bias rotations about the NPCS origins in the data term,
        prior ``w |b_j|^2`` (:class:`~ancsh.solvers.terms.NpcsBiasPriorTerm`; ``docs/results/fit_translation.md``).
    npcs_scale_bias : bool
        With ``npcs_bias_weight > 0``: each part's NPCS bias also scales about its origin (a log-scale under the
        same prior, the data term weighted as the reverse regression in it; :meth:`~ancsh.solvers.terms.Context.data_pose`).
        Default ``False``.
    npcs_stretch_bias : bool
        With ``npcs_scale_bias``: each part's NPCS bias also stretches about its origin (a symmetric traceless
        matrix under the same prior), so the bias is any linear map near the identity -- what a per-part affine fit
        absorbs. Point-to-point data term only. Default ``False``.
    robust : str or None
        ``None`` (least squares), ``"huber"`` or ``"cauchy"``: the robust data term, by IRLS on
        the moments (each round reweights the points and re-solves with the same program).
    robust_scale : float
        Kernel scale in object diagonals, ``> 0``.
    irls_iterations : int
        IRLS rounds when ``robust`` is set, ``>= 1``.
    enforce_limits : bool
        Use the correspondences' joint limits (inequalities / bounds) when present.
    max_iterations : int
        Backend iteration limit.
    tol : float
        Backend tolerance.
    box_extents : str
        Amodal part boxes where the correspondences carry no NPCS extents (a learned provider): ``"max"``
        (default: twice the largest |NPCS| of the part's inliers per axis) or ``"unit_diagonal"`` (the same, scaled
        to the unit diagonal every NPCS box has: noise no longer inflates it; ``docs/results/box_extents.md``).
    uncertainty : bool
        Compute :attr:`FitResult.uncertainty` (Gauss-Newton covariances from the program's
        Jacobian at the solution, :mod:`ancsh.solvers.uncertainty`; about 5 ms on a ~50 ms fit,
        ``docs/results/uncertainty_calibration.md``).
    """

    ransac: bool = True
    ransac_iterations: int = 200
    ransac_confidence: float = 0.99
    inlier_threshold: float = 0.1
    rescore_rounds: int = 0
    optimize_scale: bool = False
    scale_estimator: str = "reverse"
    soft_weight: float = 1.0
    soft_mu: float = 1.0
    common_scale_weight: float = 0.0
    naocs_prior_weight: float = 0.1
    npcs_bias_weight: float = 0.0
    npcs_scale_bias: bool = False
    npcs_stretch_bias: bool = False
    robust: str | None = None
    robust_scale: float = 0.02
    irls_iterations: int = 5
    enforce_limits: bool = True
    max_iterations: int = 100
    tol: float = 1e-10
    box_extents: str = "max"
    uncertainty: bool = True

    def __post_init__(self):
        for name in ("ransac", "optimize_scale", "enforce_limits", "uncertainty", "npcs_scale_bias", "npcs_stretch_bias"):
            check_bool(getattr(self, name), name)
        for name, lo in (("ransac_iterations", 1), ("rescore_rounds", 0), ("irls_iterations", 1), ("max_iterations", 1)):
            check_int(getattr(self, name), name, minimum=lo)
        for name, positive in (
            ("inlier_threshold", True), ("soft_weight", False), ("soft_mu", False),
            ("common_scale_weight", False), ("naocs_prior_weight", False), ("npcs_bias_weight", False), ("robust_scale", True), ("tol", True),
        ):
            check_number(getattr(self, name), name, minimum=0.0, lower_open=positive)
        check_number(self.ransac_confidence, "ransac_confidence", minimum=0.0, maximum=1.0, lower_open=True)
        check_choice(self.scale_estimator, "scale_estimator", SCALE_ESTIMATORS)
        check_choice(self.box_extents, "box_extents", ("max", "unit_diagonal"))
        if self.robust is not None and self.robust not in FIT_ROBUST_KERNELS:
            raise ValueError(f"robust: expected None or one of {FIT_ROBUST_KERNELS}, got {self.robust!r}")
        if self.npcs_scale_bias and not self.npcs_bias_weight > 0:
            raise ValueError("npcs_scale_bias: needs the NPCS biases (npcs_bias_weight > 0)")
        if self.npcs_stretch_bias and not self.npcs_scale_bias:
            raise ValueError("npcs_stretch_bias: needs the NPCS scale biases (npcs_scale_bias=True)")

    @classmethod
    def paper(cls, **overrides) -> "FitConfig":
        """The paper's choices: Umeyama scales kept fixed, canonical parameters taken as exact.

        (RANSAC threshold 0.1 object diagonals as in the official code.) The defaults differ in
        ``scale_estimator="reverse"`` and ``naocs_prior_weight=0.1``, which measured better on
        oracle-corrupted procedural frames (lower rotation and translation errors;
        ``docs/results/fit_translation.md``).
        ``max_iterations=1000``: the official code runs ``scipy.optimize.least_squares`` with its
        default evaluation budget (``100·n·(n+1)`` for finite-difference ``lm``, thousands here);
        at the default 100, the soft energies stop short of convergence on a few percent of
        learned eyeglasses frames, which would count as failures the paper's method does not have.
        """
        values = dict(scale_estimator="umeyama", naocs_prior_weight=0.0, optimize_scale=False, inlier_threshold=0.1,
                      max_iterations=1000)
        values.update(overrides)
        return cls.from_dict(values)

    @classmethod
    def from_dict(cls, values: dict) -> "FitConfig":
        """Build from a mapping; unknown keys raise ``ValueError`` naming them."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"config: unknown key(s) {unknown}; known: {sorted(known)}")
        return cls(**values)


def _has_limits(config: FitConfig, corr: Correspondences) -> bool:
    return config.enforce_limits and corr.joint_limits is not None and bool(np.any(np.isfinite(corr.joint_limits)))


_TERM_ENABLED = {
    # A formulation's term is in its program unless this says otherwise for the config / data.
    CommonScaleTerm: lambda config, corr: config.optimize_scale and config.common_scale_weight > 0,
    # Optimised scales: one object scale, exactly (as in the reduced parameterisation).
    ExactCommonScaleTerm: lambda config, corr: config.optimize_scale,
    JointLimitTerm: _has_limits,
    CanonicalPriorTerm: lambda config, corr: config.naocs_prior_weight > 0,
    NpcsBiasPriorTerm: lambda config, corr: config.npcs_bias_weight > 0,
}
"""Conditions of the optional terms (a term not listed is always used)."""


@dataclass(frozen=True)
class Formulation:
    """A fitting formulation: which program (parameterisation + terms) and which backends.

    Attributes
    ----------
    name : str
    description : str
    solvers : tuple of str
        Supported backends, the first being the default.
    parameterisation : str or None
        ``"maximal"``, ``"reduced"`` or ``None`` (closed form, no program).
    term_classes : tuple of EnergyTerm subclasses
        The program's terms in residual order; the optional ones (see ``_TERM_ENABLED``)
        are kept or dropped by :meth:`terms`.
    """

    name: str
    description: str
    solvers: tuple
    parameterisation: str | None
    term_classes: tuple = ()

    def terms(self, config: FitConfig, corr: Correspondences) -> tuple:
        """The term classes of this formulation's program for ``config`` and ``corr``."""
        return tuple(t for t in self.term_classes if _TERM_ENABLED.get(t, lambda *_: True)(config, corr))


FORMULATIONS: dict[str, Formulation] = {
    f.name: f
    for f in (
        Formulation("per_part", "per-part Umeyama + RANSAC (the paper's NPCS baseline)", ("umeyama",), None),
        Formulation(
            "soft", "paper Sec. 4.3: data + lambda * soft joint energies", ("lsq", "ipopt", "lm"), "maximal",
            (DataTerm, SoftJointTerm, CommonScaleTerm, CanonicalPriorTerm, NpcsBiasPriorTerm),
        ),
        Formulation(
            "exact_maximal", "every part SE(3)+scale, exact joint equalities, limit inequalities", ("ipopt",), "maximal",
            (DataTerm, ExactJointTerm, ExactCommonScaleTerm, JointLimitTerm, CanonicalPriorTerm, NpcsBiasPriorTerm),
        ),
        Formulation(
            "exact_reduced", "object pose + joint states, joints exact by construction", ("ipopt", "lsq", "lm"), "reduced",
            (DataTerm, CanonicalPriorTerm, NpcsBiasPriorTerm),
        ),
    )
}
"""Formulations by name; loop over it to compare them."""


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
    fitter = _Fit(observation, correspondences, form, solver, config, rng, start)
    fitter.warm_start, fitter.previous = warm_start, previous
    result = fitter.run()
    if not (result.ok and _has_limits(config, correspondences)):
        return result
    from .limits import check_joint_range

    bounded = JointLimitTerm in form.term_classes or form.parameterisation == "reduced"
    return check_joint_range(
        result, correspondences.joint_limits, [t.value == "revolute" for t in correspondences.joint_types],
        bounded=bounded, unbounded=lambda: fit(observation, correspondences, formulation, solver,
                                               replace(config, enforce_limits=False), 0, warm_start=result,
                                               previous=previous))


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

    def __init__(self, obs, corr, form, solver, config, rng, start):
        self.corr, self.form, self.solver, self.config, self.rng, self.start = corr, form, solver, config, rng, start
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

    # -- results ---------------------------------------------------------------------------
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
        if self.warm_start is not None:
            poses, inliers = self._warm_poses(active)
        else:
            poses, inliers = self._initial_poses(active)
            if self.config.scale_estimator != "umeyama":
                poses = [self._rescale(j, T, inliers) for j, T in enumerate(poses)]
        L = float(np.median([T.scale / g for T, g in zip(poses, self.corr.npcs_scale)]))
        if self.form.parameterisation is None:
            moments = self._moments(inliers, self.weights, L)
            costs = self._data_costs(poses, L, moments)
            uncertainty = self._uncertainty(poses, None, inliers, self.weights, moments, L)
            return self._finish(poses, inliers, L, FitStatus.SUCCESS, "per-part Umeyama on RANSAC inliers", 0, costs,
                                self.canonical, uncertainty)
        run = self._start_solve(poses, L)
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

    def _rescale(self, j: int, T: Sim3, inliers: np.ndarray) -> Sim3:
        """``T`` with the RMS-spread-ratio (``symmetric``) or reverse-regression (``reverse``) scale of
        part ``j``'s inliers and the matching translation."""
        sel = inliers & (self.labels == j)
        w = self.weights[sel] / self.weights[sel].sum()
        p, c = self.points[sel], self.npcs[sel]
        pbar, cbar = w @ p, w @ c
        var_p = float(w @ np.sum((p - pbar) ** 2, axis=1))
        var_c = float(w @ np.sum((c - cbar) ** 2, axis=1))
        if not var_c > 0 or not var_p > 0:
            return T
        s = np.sqrt(var_p / var_c)
        if self.config.scale_estimator == "reverse":
            cov = float(np.sum(((p - pbar) * w[:, None]).T @ (c - cbar) * T.rotation))  # tr(R^T cov(p, c))
            # = s_sym^2 / s_umeyama; capped at 2 s_sym (correlation below 0.5: no usable match)
            s = var_p / max(cov, 0.5 * np.sqrt(var_p * var_c))
        return Sim3.unchecked(T.rotation, pbar - s * (T.rotation @ cbar), s)

    # -- program solve --------------------------------------------------------------------------
    def _start_solve(self, poses: list, L: float) -> _SolveRun:
        """The formulation's program, its start (per-part poses moved onto the joints for
        ``exact_maximal``) and bounds."""
        from .backends import Bounds
        from .program import ProgramKey, get_program

        cfg = self.config
        key = ProgramKey(
            self.structure, self.form.parameterisation, bool(cfg.optimize_scale),
            self.form.terms(cfg, self.corr) + ((TemporalPriorTerm,) if self.previous is not None else ()),
            free_canonical=cfg.naocs_prior_weight > 0, npcs_bias=cfg.npcs_bias_weight > 0,
            npcs_scale_bias=cfg.npcs_scale_bias, npcs_stretch_bias=cfg.npcs_stretch_bias,
        )
        prog = get_program(key)
        limits = self._limits()
        if self.form.name == "exact_maximal" and self.K:
            poses = self._onto_joints(poses, L, limits)
        return _SolveRun(prog, self._start(poses, L), self._x_start(prog, poses, limits), Bounds.of(prog, limits))

    def _solve_loop(self, run: _SolveRun, inliers: np.ndarray, L: float) -> np.ndarray:
        """Solve; optionally reweight (IRLS) and re-score the inliers and solve again.

        Leaves the last outcome (and its parameters) in ``run``; returns the final inliers.
        """
        from .backends import SolverOptions, solve

        cfg = self.config
        prog = run.program
        opts = SolverOptions(cfg.max_iterations, cfg.tol)
        weights = self.weights.copy()
        rounds = cfg.irls_iterations if cfg.robust else 1
        for rescore in range(cfg.rescore_rounds + 1):
            for _ in range(rounds):
                run.weights, run.moments = weights, self._moments(inliers, weights, L)
                inputs = ProgramInputs(L, self.canonical, run.start, run.moments, self.term_weights, self.previous)
                run.p = prog.pack(inputs)
                run.outcome = solve(self.solver, prog, run.p, run.x, run.bounds, opts)
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
        uncertainty = self._uncertainty(solved, solution, inliers, run.weights, run.moments, L)
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

        cfg = self.config
        if solution is None:
            key = ProgramKey(self.structure, "maximal", True, (DataTerm,))
        else:
            key = ProgramKey(self.structure, self.form.parameterisation, True,
                             self.form.terms(replace(cfg, optimize_scale=True), self.corr),
                             free_canonical=cfg.naocs_prior_weight > 0, npcs_bias=cfg.npcs_bias_weight > 0,
                             npcs_scale_bias=cfg.npcs_scale_bias, npcs_stretch_bias=cfg.npcs_stretch_bias)
        prog = get_program(key)
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
            _, _, states = _postprocess(self.structure, poses, self.canonical)
            states = np.clip(states, limits[:, 0], limits[:, 1])
        return prog.initial_x(states)

    def _moments(self, inliers: np.ndarray, weights: np.ndarray, L: float) -> tuple:
        from .terms import part_moments

        out = []
        for j in range(self.M):
            sel = inliers & (self.labels == j) & (weights > 0)
            out.append(part_moments(self.points[sel], self.npcs[sel], weights[sel], L))
        return tuple(out)

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
    def _finish(self, poses, inliers, L, status, message, iterations, costs: dict, canonical, uncertainty=None) -> FitResult:
        axes, pivots, states = _postprocess(self.structure, poses, canonical)
        violation = self._violation(poses, canonical, L)
        boxes = tuple(self._box(j, T, inliers) for j, T in enumerate(poses))
        return FitResult(
            formulation=self.form.name, solver=self.solver, T_cam_npcs=tuple(poses), joint_axes_cam=axes,
            joint_pivots_cam=pivots, joint_states=states, boxes_cam=boxes, status=status, message=message,
            cost_per_term=costs, iterations=int(iterations), max_constraint_violation=violation, inliers=inliers,
            time_s=time.perf_counter() - self.start, uncertainty=uncertainty, canonical=canonical,
        )

    def _violation(self, poses, canonical, L) -> float:
        """Largest exact-joint or limit violation at the given poses."""
        from .program import ProgramKey, get_program

        prog = get_program(ProgramKey(self.structure, "maximal", False, (ExactJointTerm,) + ((JointLimitTerm,) if self.K else ())))
        p = prog.pack(ProgramInputs(L, canonical, ProgramStart(T_cam_npcs=tuple(poses))))
        g = np.asarray(prog.constraints(prog.initial_x(), p)).ravel()
        lo, hi = prog.constraint_bounds(self._limits())
        return float(np.max(np.concatenate([[0.0], lo - g, g - hi]))) if g.size else 0.0

    def _data_costs(self, poses, L, moments: tuple) -> dict:
        """``{"data": e}``: the data energy of the points with these moments at the given poses (closed-form fits)."""
        from .program import ProgramKey, get_program

        prog = get_program(ProgramKey(self.structure, "maximal", False, (DataTerm,)))
        inputs = ProgramInputs(L, self.canonical, ProgramStart(T_cam_npcs=tuple(poses)), moments)
        p = prog.pack(inputs)
        return dict(zip(prog.cost_names, np.asarray(prog.term_costs(prog.initial_x(), p)).ravel().tolist()))

    def _box(self, j: int, T: Sim3, inliers: np.ndarray) -> OrientedBox:
        """Amodal box: the NPCS box (centred at the NPCS origin) mapped by the part pose."""
        if self.corr.npcs_extents is not None:
            extents = self.corr.npcs_extents[j]
        else:
            sel = inliers & (self.labels == j)
            extents = 2.0 * np.max(np.abs(self.npcs[sel]), axis=0)  # NOCS: symmetric about the NPCS origin
            if self.config.box_extents == "unit_diagonal":
                extents = unit_diagonal(extents)
        return OrientedBox(T.translation, T.rotation, T.scale * extents)


def _postprocess(structure, poses: list, canonical: CanonicalParameters):
    from .program import postprocess_function

    return postprocess_function(structure)(poses, canonical)
