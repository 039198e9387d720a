"""Energy terms and constraints of articulated fitting, each defined ONCE in CasADi.

One module per family: :mod:`.context` (the symbolic context, the term base class and registry), :mod:`.data`
(point-to-point and point-to-plane data terms), :mod:`.joints` (soft and exact joints, joint limits), :mod:`.scale`
(the common object scale) and :mod:`.priors` (canonical-parameter, NPCS-bias and temporal priors).

Every term is a small class that turns the symbolic part poses of a :class:`Context` into a
CasADi expression: a least-squares residual ``r`` (energy ``|r|^2``), an equality ``g == 0``
or an inequality ``lower <= g <= upper``. The IPOPT backend puts the same expressions into
an NLP; the scipy backend evaluates CasADi Functions built from them (residuals and exact
Jacobians). Adding a term = one subclass registered with :func:`register_term`.

A term declares the named parameters it uses (``ctx.params.get(name)`` in :meth:`EnergyTerm.expression`)
and fills them, in :meth:`EnergyTerm.fill`, from the typed :class:`ProgramInputs` of one frame
(:class:`CanonicalParameters`, :class:`ProgramStart`, :class:`PartMoments`, :class:`TermWeights`; those
dataclasses live in :mod:`ancsh.solvers.inputs`). Parameter names never leave this package and :mod:`ancsh.solvers.program`.

Symbols (all CasADi ``SX``), part ``j``, joint ``k`` (parent ``p``, child ``c``):

- part pose ``p_cam = s_j R_j c + t_j`` (NPCS ``c`` -> camera, metres);
- NPCS -> NAOCS ``g = Gs_j c + Gt_j``; hence NAOCS -> camera through part ``j`` is
  ``X_j(g) = (s_j / Gs_j) R_j (g - Gt_j) + t_j``; ``o_j = X_j(0)`` is the NAOCS origin;
- joint axis ``u_k``, pivot ``q_k`` (NAOCS, rest state) and two unit vectors ``a_k, b_k``
  completing ``u_k`` to an orthonormal basis;
- ``L``: the object's scale in metres (NAOCS diagonal); residuals in metres are divided by
  ``L`` so energies are in object-normalised units.
"""

from __future__ import annotations

from ..inputs import (  # the programs' typed inputs, importable from here as before
    CanonicalOffsets,
    CanonicalParameters,
    KinematicStructure,
    PartMoments,
    PreviousSolution,
    ProgramInputs,
    ProgramStart,
    TermWeights,
    canonical_parameter_values,  # noqa: F401
    perpendiculars,  # noqa: F401
    state_reference,  # noqa: F401
)
from .context import (
    TERMS,
    Canonical,
    Context,
    EnergyTerm,
    Params,  # noqa: F401
    PoseExpr,  # noqa: F401
    axis_angle_sx,  # noqa: F401
    exp_so3_sx,
    hat_sx,  # noqa: F401
    joint_state_expr,
    register_term,
    stretch_sx,  # noqa: F401
    vee_sx,  # noqa: F401
)
from .data import DataTerm, PointToPlaneTerm, part_moments, parts_moments, plane_moments
from .joints import ExactJointTerm, JointLimitTerm, SoftJointTerm
from .priors import CanonicalPriorTerm, NpcsBiasPriorTerm, TemporalPriorTerm
from .scale import CommonScaleTerm, ExactCommonScaleTerm

__all__ = [
    "TERMS",
    "Canonical",
    "CanonicalOffsets",
    "CanonicalParameters",
    "CanonicalPriorTerm",
    "CommonScaleTerm",
    "Context",
    "DataTerm",
    "EnergyTerm",
    "ExactCommonScaleTerm",
    "ExactJointTerm",
    "JointLimitTerm",
    "KinematicStructure",
    "NpcsBiasPriorTerm",
    "PartMoments",
    "PointToPlaneTerm",
    "PreviousSolution",
    "ProgramInputs",
    "ProgramStart",
    "SoftJointTerm",
    "TemporalPriorTerm",
    "TermWeights",
    "exp_so3_sx",
    "joint_state_expr",
    "part_moments",
    "parts_moments",
    "plane_moments",
    "register_term",
]
