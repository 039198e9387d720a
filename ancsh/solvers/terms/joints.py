"""Joint terms: the paper's soft joint energies, exact joint equalities and joint-limit inequalities."""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..inputs import KinematicStructure, ProgramInputs
from .context import Context, EnergyTerm, joint_state_expr, register_term, vee_sx


@register_term
class SoftJointTerm(EnergyTerm):
    """The paper's soft joint energies ``lambda * e_k`` (Sec. 4.3), as residuals.

    Revolute: ``e_k = |R_p u - R_c u|^2``. Prismatic:
    ``e_k = mu |R_p R_c^T - I|_F^2 + sum_{j in p, c} |[R_j u]_x delta|^2`` with ``delta`` the
    offset between the NAOCS origins seen through the two parts (divided by ``L``). The paper
    writes ``delta = t_c - t_p + s_p R_p Gt_p - s_c R_c Gt_c``, which is this offset when the
    NPCS -> NAOCS map is ``g = Gs (c + Gt)``; with ``g = Gs c + Gt`` (ours) the origin of part
    ``j`` is ``t_j - (s_j / Gs_j) R_j Gt_j``.
    Parameters ``lambda`` (``soft_weight``) and ``mu`` (``soft_mu``).
    """

    name = "soft_joint"

    def expression(self, ctx: Context) -> ca.SX:
        lam = ctx.params.get("soft_weight")
        mu = ctx.params.get("soft_mu")
        out = []
        for k in range(ctx.structure.num_joints):
            p, c = ctx.joint_parts(k)
            u = ctx.axis(k)
            Rp, Rc = ctx.poses[p].R, ctx.poses[c].R
            if ctx.structure.is_revolute(k):
                out.append(ca.sqrt(lam) * (Rp @ u - Rc @ u))
            else:
                delta = ctx.origin_offset(k) / ctx.L
                out.append(ca.sqrt(lam * mu) * ca.vec(Rp @ Rc.T - ca.SX.eye(3)))
                out.append(ca.sqrt(lam) * ca.cross(Rp @ u, delta))
                out.append(ca.sqrt(lam) * ca.cross(Rc @ u, delta))
        return ca.vertcat(*out) if out else ca.SX(0, 1)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        w = inputs.require("weights", self.name)
        return {"soft_weight": w.soft_weight, "soft_mu": w.soft_mu}


@register_term
class ExactJointTerm(EnergyTerm):
    """Exact joint constraints ``g == 0``, as independent equations (full-rank Jacobian).

    Revolute (5 equations): the child's axis ``R_c u`` is perpendicular to ``R_p a`` and
    ``R_p b`` (same direction; two equations instead of the rank-deficient ``R_p u == R_c u``),
    and the pivot maps to the same camera point, ``(X_p(q) - X_c(q)) / L == 0``.
    Prismatic (5 equations): equal rotations, ``vee(R_p^T R_c) == 0``, and the NAOCS origins
    differ only along the axis, ``(R_p a) . delta / L == (R_p b) . delta / L == 0``.
    """

    name = "exact_joint"
    kind = "equality"

    def expression(self, ctx: Context) -> ca.SX:
        out = []
        for k in range(ctx.structure.num_joints):
            p, c = ctx.joint_parts(k)
            u = ctx.axis(k)
            a, b = ctx.perpendiculars(k)
            Rp, Rc = ctx.poses[p].R, ctx.poses[c].R
            if ctx.structure.is_revolute(k):
                uc = Rc @ u
                q = ctx.pivot(k)
                out += [ca.dot(Rp @ a, uc), ca.dot(Rp @ b, uc), (ctx.naocs_to_cam(p, q) - ctx.naocs_to_cam(c, q)) / ctx.L]
            else:
                delta = ctx.origin_offset(k) / ctx.L
                out += [vee_sx(Rp.T @ Rc), ca.dot(Rp @ a, delta), ca.dot(Rp @ b, delta)]
        return ca.vertcat(*out) if out else ca.SX(0, 1)


@register_term
class JointLimitTerm(EnergyTerm):
    """Joint limits as inequalities ``lower_k <= state_k <= upper_k`` (states from part poses)."""

    name = "joint_limits"
    kind = "inequality"

    def expression(self, ctx: Context) -> ca.SX:
        states = [joint_state_expr(ctx, k) for k in range(ctx.structure.num_joints)]
        return ca.vertcat(*states) if states else ca.SX(0, 1)

    def bounds(self, joint_limits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lim = np.asarray(joint_limits, dtype=np.float64)
        return lim[:, 0].copy(), lim[:, 1].copy()
