"""The configuration of articulated fitting: :class:`FitConfig` (validated settings) and the formulations
(:data:`FORMULATIONS`: which program, which terms, which backends), read by the driver :func:`ancsh.solvers.fit.fit`.

Formulations: ``per_part`` (Umeyama + RANSAC), ``soft`` (paper Sec. 4.3: data + lambda soft joint energies),
``exact_maximal`` (every part SE(3)+scale with exact joint equalities and limit inequalities, IPOPT),
``exact_reduced`` (object pose + joint states, joints exact by construction, limits as bounds; the projected
Levenberg-Marquardt ``lm`` by default -- the same solutions as IPOPT on the benchmark's frames, without IPOPT's fixed
cost of about a millisecond per solve (``docs/results/fit_profile.md``) -- or IPOPT, or scipy least squares).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..geometry._checks import check_bool, check_choice, check_int, check_number
from .terms import (
    CanonicalPriorTerm, CommonScaleTerm, DataTerm, ExactCommonScaleTerm, ExactJointTerm, JointLimitTerm, NpcsBiasPriorTerm,
    SoftJointTerm,
)
from .types import Correspondences

__all__ = ["FIT_ROBUST_KERNELS", "FORMULATIONS", "SCALE_ESTIMATORS", "FitConfig", "Formulation", "has_limits"]

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


def has_limits(config: FitConfig, corr: Correspondences) -> bool:
    """Whether the fit enforces joint limits: switched on and finite limits given."""
    return config.enforce_limits and corr.joint_limits is not None and bool(np.any(np.isfinite(corr.joint_limits)))


_TERM_ENABLED = {
    # A formulation's term is in its program unless this says otherwise for the config / data.
    CommonScaleTerm: lambda config, corr: config.optimize_scale and config.common_scale_weight > 0,
    # Optimised scales: one object scale, exactly (as in the reduced parameterisation).
    ExactCommonScaleTerm: lambda config, corr: config.optimize_scale,
    JointLimitTerm: has_limits,
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
            "exact_reduced", "object pose + joint states, joints exact by construction", ("lm", "ipopt", "lsq"), "reduced",
            (DataTerm, CanonicalPriorTerm, NpcsBiasPriorTerm),
        ),
    )
}
"""Formulations by name; loop over it to compare them."""
