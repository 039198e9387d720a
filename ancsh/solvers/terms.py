"""Energy terms and constraints of articulated fitting, each defined ONCE in CasADi.
Long: the term registry and the symbolic context every term reads belong together (one definition per residual).

Every term is a small class that turns the symbolic part poses of a :class:`Context` into a
CasADi expression: a least-squares residual ``r`` (energy ``|r|^2``), an equality ``g == 0``
or an inequality ``lower <= g <= upper``. The IPOPT backend puts the same expressions into
an NLP; the scipy backend evaluates CasADi Functions built from them (residuals and exact
Jacobians). Adding a term = one subclass registered with :func:`register_term`.

A term declares the named parameters it uses (``ctx.params.get(name)`` in :meth:`EnergyTerm.expression`)
and fills them, in :meth:`EnergyTerm.fill`, from the typed :class:`ProgramInputs` of one frame
(:class:`CanonicalParameters`, :class:`ProgramStart`, :class:`PartMoments`, :class:`TermWeights`; those
dataclasses live in :mod:`ancsh.solvers.inputs`). Parameter names never leave this module and :mod:`ancsh.solvers.program`.

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

from dataclasses import dataclass

import casadi as ca
import numpy as np

from .inputs import (  # the programs' typed inputs, importable from here as before
    CanonicalOffsets,
    CanonicalParameters,
    KinematicStructure,
    PartMoments,
    PreviousSolution,
    ProgramInputs,
    ProgramStart,
    TermWeights,
    canonical_parameter_values,
    perpendiculars,  # noqa: F401
    state_reference,  # noqa: F401
)

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
    "plane_moments",
    "register_term",
]

_SMALL_ANGLE2 = 1e-8  # theta^2 below which exp(w) uses its Taylor series


class Params:
    """Named symbolic parameters of a program, packed into one vector ``p`` at solve time."""

    def __init__(self):
        self._syms: dict[str, ca.SX] = {}
        self._shapes: dict[str, tuple] = {}

    def get(self, name: str, rows: int = 1, cols: int = 1) -> ca.SX:
        """The parameter ``name`` (created on first use with shape ``(rows, cols)``)."""
        if name in self._syms:
            if self._shapes[name] != (rows, cols):
                raise ValueError(f"parameter {name!r}: shape {(rows, cols)} conflicts with {self._shapes[name]}")
            return self._syms[name]
        sym = ca.SX.sym(name, rows, cols)
        self._syms[name] = sym
        self._shapes[name] = (rows, cols)
        return sym

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._syms)

    def vector(self) -> ca.SX:
        return ca.vertcat(*[ca.vec(s) for s in self._syms.values()]) if self._syms else ca.SX(0, 1)

    def value(self, p: np.ndarray, name: str) -> np.ndarray:
        """The value of parameter ``name`` in the packed vector ``p`` (row-major ``(rows, cols)``
        array, ``(rows,)`` for a column, a 0-d array for a scalar)."""
        start = 0
        for n, (rows, cols) in self._shapes.items():
            if n == name:
                v = np.asarray(p, dtype=np.float64)[start : start + rows * cols]
                if cols > 1:
                    return v.reshape((rows, cols), order="F")
                return v.copy() if rows > 1 else v.reshape(())
            start += rows * cols
        raise KeyError(f"no parameter {name!r}")

    def pack(self, values: dict) -> np.ndarray:
        """Flatten ``values[name]`` for every parameter (column-major, as CasADi) into ``p``."""
        out = []
        for name, shape in self._shapes.items():
            if name not in values:
                raise KeyError(f"no value for parameter {name!r}")
            v = np.asarray(values[name], dtype=np.float64)
            if v.size != shape[0] * shape[1]:
                raise ValueError(f"parameter {name!r}: expected {shape[0] * shape[1]} values, got {v.shape}")
            out.append(v.reshape(shape, order="C").ravel(order="F") if v.ndim == 2 else v.ravel())
        return np.concatenate(out) if out else np.zeros(0)


@dataclass
class PoseExpr:
    """Symbolic part pose ``p_cam = s R c + t``."""

    R: ca.SX
    t: ca.SX
    s: ca.SX


class Canonical:
    """The canonical (NAOCS) parameters ``Gt_j`` and pivots ``q_k`` seen by the terms.

    Fixed parameters by default. With ``free=True`` each ``Gt_j`` and each revolute pivot
    ``q_k`` gets a decision-variable offset (``Gt_j + dGt_j``, ``q_k + dq_k``, NAOCS units), so
    the joints hold exactly for *adjusted* canonical parameters; :class:`CanonicalPriorTerm`
    keeps the offsets small (the provider's values are treated as noisy measurements).
    """

    def __init__(self, structure: KinematicStructure, params: Params, free: bool = False):
        self.structure, self.params, self.free = structure, params, free
        self.dGt = [ca.SX.sym(f"dGt{j}", 3) for j in range(structure.num_parts)] if free else []
        self.dq = {k: ca.SX.sym(f"dq{k}", 3) for k in range(structure.num_joints) if structure.is_revolute(k)} if free else {}

    def Gt(self, j: int) -> ca.SX:
        base = self.params.get(f"Gt{j}", 3)
        return base + self.dGt[j] if self.free else base

    def pivot(self, k: int) -> ca.SX:
        base = self.params.get(f"q{k}", 3)
        return base + self.dq[k] if k in self.dq else base

    def offsets(self) -> ca.SX:
        """All offset variables, ``dGt_0..dGt_{M-1}`` then ``dq_k`` of the revolute joints."""
        parts = self.dGt + [self.dq[k] for k in sorted(self.dq)]
        return ca.vertcat(*parts) if parts else ca.SX(0, 1)


class Context:
    """Symbolic part poses and the named parameters terms may use."""

    @staticmethod
    def fill(inputs: ProgramInputs) -> dict:
        """Values of the context's own parameters (``L`` and the canonical parameters)."""
        return {"L": inputs.scale, **canonical_parameter_values(inputs.canonical)}

    def __init__(self, structure: KinematicStructure, params: Params, poses: list, canonical: Canonical | None = None,
                 npcs_bias: list | None = None):
        self.structure = structure
        self.params = params
        self.poses = poses
        self.canonical = Canonical(structure, params) if canonical is None else canonical
        self.npcs_bias = npcs_bias

    def data_pose(self, j: int) -> PoseExpr:
        """The pose the observed points of part ``j`` are compared with: the part pose, or with an NPCS
        bias (:class:`NpcsBiasPriorTerm`) ``s_j R_j exp(b_j) c + t_j``, the provider's NPCS of part ``j`` taken as
        rotated by ``exp(-b_j)`` about the NPCS origin; with a scale bias ``beta_j`` (a fourth bias variable)
        ``s_j exp(beta_j) R_j exp(b_j) c + t_j``, also scaled by ``exp(-beta_j)`` about it; with a stretch bias
        (five more, :func:`stretch_sx`) ``s_j exp(beta_j) R_j exp(b_j) (I + S_j) c + t_j``: any linear distortion near
        the identity about the NPCS origin. Then ``R`` of the returned pose is not a rotation."""
        P = self.poses[j]
        if self.npcs_bias is None:
            return P
        b = self.npcs_bias[j]
        if b.numel() == 9:
            return PoseExpr(P.R @ exp_so3_sx(b[:3]) @ (ca.SX.eye(3) + stretch_sx(b[4:])), P.t, P.s * ca.exp(b[3]))
        if b.numel() == 4:
            return PoseExpr(P.R @ exp_so3_sx(b[:3]), P.t, P.s * ca.exp(b[3]))
        return PoseExpr(P.R @ exp_so3_sx(b), P.t, P.s)

    @property
    def npcs_stretch(self) -> bool:
        """Whether the data poses carry stretch biases (their ``R`` is then not a rotation)."""
        return self.npcs_bias is not None and self.npcs_bias[0].numel() == 9

    def data_weight(self, j: int):
        """Factor of part ``j``'s point-to-point data residual: 1, or with a scale bias ``exp(-beta_j)``, which
        makes the data term the reverse regression in ``beta_j`` (camera points onto NPCS:
        ``|exp(-beta_j) (p - t_j) / s_j - R_j exp(b_j) c|``, up to the fixed ``s_j``), so that per-point NPCS noise
        does not shrink the part's scale (the forward least-squares scale is shrunk by it; see
        ``docs/results/fit_translation.md``)."""
        if self.npcs_bias is None or self.npcs_bias[j].numel() < 4:
            return 1.0
        return ca.exp(-self.npcs_bias[j][3])

    # -- per part ---------------------------------------------------------------------
    def Gs(self, j: int) -> ca.SX:
        return self.params.get(f"Gs{j}")

    def Gt(self, j: int) -> ca.SX:
        return self.canonical.Gt(j)

    @property
    def L(self) -> ca.SX:
        return self.params.get("L")

    def object_scale(self, j: int) -> ca.SX:
        """``s_j / Gs_j``: metres per NAOCS unit seen through part ``j``."""
        return self.poses[j].s / self.Gs(j)

    def naocs_to_cam(self, j: int, g) -> ca.SX:
        """``X_j(g)``: a NAOCS point mapped to the camera through part ``j``."""
        P = self.poses[j]
        return self.object_scale(j) * (P.R @ (g - self.Gt(j))) + P.t

    # -- per joint ----------------------------------------------------------------------
    def axis(self, k: int) -> ca.SX:
        return self.params.get(f"u{k}", 3)

    def pivot(self, k: int) -> ca.SX:
        return self.canonical.pivot(k)

    def perpendiculars(self, k: int) -> tuple[ca.SX, ca.SX]:
        return self.params.get(f"a{k}", 3), self.params.get(f"b{k}", 3)

    def joint_parts(self, k: int) -> tuple[int, int]:
        return self.structure.joint_parents[k], self.structure.joint_children[k]

    def origin_offset(self, k: int) -> ca.SX:
        """``delta_k = o_child - o_parent`` (metres): the paper's prismatic ``delta``."""
        p, c = self.joint_parts(k)
        zero = ca.DM.zeros(3)
        return self.naocs_to_cam(c, zero) - self.naocs_to_cam(p, zero)


# --------------------------------------------------------------------------------------------
# Small symbolic helpers
# --------------------------------------------------------------------------------------------
def hat_sx(v) -> ca.SX:
    return ca.vertcat(
        ca.horzcat(0, -v[2], v[1]),
        ca.horzcat(v[2], 0, -v[0]),
        ca.horzcat(-v[1], v[0], 0),
    )


def vee_sx(W) -> ca.SX:
    """Antisymmetric part of ``W`` as a vector (``sin(theta) * axis`` for a rotation)."""
    return 0.5 * ca.vertcat(W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1])


def exp_so3_sx(w) -> ca.SX:
    """Rodrigues' formula, smooth (with derivatives) at ``w = 0``."""
    th2 = ca.dot(w, w)
    small = th2 < _SMALL_ANGLE2
    th2_safe = ca.if_else(small, 1.0, th2)  # keeps the exact branch finite at 0 (and its derivative)
    th = ca.sqrt(th2_safe)
    a = ca.if_else(small, 1.0 - th2 / 6.0 + th2 * th2 / 120.0, ca.sin(th) / th)
    b = ca.if_else(small, 0.5 - th2 / 24.0 + th2 * th2 / 720.0, (1.0 - ca.cos(th)) / th2_safe)
    K = hat_sx(w)
    return ca.SX.eye(3) + a * K + b * (K @ K)


def stretch_sx(e) -> ca.SX:
    """The symmetric traceless ``(3, 3)`` matrix of five parameters ``e``:
    ``[[e0, e2, e3], [e2, e1, e4], [e3, e4, -e0 - e1]]`` (an NPCS stretch bias, :meth:`Context.data_pose`)."""
    return ca.vertcat(
        ca.horzcat(e[0], e[2], e[3]),
        ca.horzcat(e[2], e[1], e[4]),
        ca.horzcat(e[3], e[4], -e[0] - e[1]),
    )


def axis_angle_sx(u, theta) -> ca.SX:
    """Rotation by ``theta`` about the unit axis ``u``."""
    K = hat_sx(u)
    return ca.SX.eye(3) + ca.sin(theta) * K + (1.0 - ca.cos(theta)) * (K @ K)


def joint_state_expr(ctx: Context, k: int) -> ca.SX:
    """State of joint ``k`` relative to rest, from the two part poses.

    Revolute: the signed angle of ``R_p^T R_c`` about ``u_k`` (radians), in the window
    ``(ref_k - pi, ref_k + pi]`` around the parameter ``state_ref{k}`` (the middle of the joint's
    limits), so a limit range wider than ``pi`` on one side of rest is represented without a
    wrap; prismatic: ``(R_p u_k) . delta_k`` (metres).
    """
    p, c = ctx.joint_parts(k)
    u = ctx.axis(k)
    Rp, Rc = ctx.poses[p].R, ctx.poses[c].R
    if ctx.structure.is_revolute(k):
        Rrel = Rp.T @ Rc
        sin = ca.dot(u, vee_sx(Rrel))
        cos = 0.5 * (ca.trace(Rrel) - 1.0)
        ref = ctx.params.get(f"state_ref{k}")
        return ref + ca.atan2(sin * ca.cos(ref) - cos * ca.sin(ref), cos * ca.cos(ref) + sin * ca.sin(ref))
    return ca.dot(Rp @ u, ctx.origin_offset(k))


# --------------------------------------------------------------------------------------------
# Terms
# --------------------------------------------------------------------------------------------
class EnergyTerm:
    """Base class. ``kind`` is ``"cost"`` (residual), ``"equality"`` or ``"inequality"``.

    Subclasses implement :meth:`expression` (declaring the parameters they use with
    ``ctx.params.get``) and :meth:`fill` (their values from typed inputs); inequalities also
    :meth:`bounds`. ``name`` is for configuration, reports and the command line only; programs
    are keyed by term classes.
    """

    name: str = ""
    kind: str = "cost"
    #: Observed-data costs (the noise sources of a fit's covariance): residual rows per part, in
    #: part order, each part's squared norm its weighted mean squared point residual over ``L^2``;
    #: 0 for priors and penalties.
    rows_per_part: int = 0
    #: Residual components per observed point of a data term (3 point-to-point, 1 point-to-plane).
    residual_dims: int = 3

    def expression(self, ctx: Context) -> ca.SX:  # pragma: no cover - abstract
        raise NotImplementedError

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        """Values of the parameters this term declared beyond the :class:`Context`'s (none by default)."""
        return {}

    def bounds(self, joint_limits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Numeric ``(lower, upper)`` of an inequality, given the joint limits ``(K, 2)``."""
        raise NotImplementedError(f"{type(self).__name__} is not an inequality")

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


TERMS: dict[str, type] = {}


def register_term(cls: type) -> type:
    """Class decorator adding a term to :data:`TERMS` under ``cls.name``."""
    if not cls.name or cls.name in TERMS:
        raise ValueError(f"term name {cls.name!r} is empty or already registered")
    TERMS[cls.name] = cls
    return cls


@register_term
class DataTerm(EnergyTerm):
    """Point-to-point data term of every part, on per-part moments (paper's ``e_j``).

    ``e_j = sum_i w_i |p_i - (s_j R_j c_i + t_j)|^2 / (sum_i w_i L^2)``. With centred
    coordinates ``x_i = [c_i - cbar; 1]``, ``p'_i = p_i - pbar`` and ``A = [s R | s R cbar + t - pbar]``,
    ``e_j = |A Lm - B|_F^2 / L^2 + c0`` exactly, where ``Lm Lm^T = mean(w x x^T)``,
    ``Lm B^T = mean(w x p'^T)`` and ``c0 = (mean(w |p'|^2) - |B|^2) / L^2`` (see :func:`part_moments`).
    The residual is ``[vec(A Lm - B) / L; sqrt(c0)]`` (13 per part), so ``|r|^2 == sum_j e_j``.
    """

    name = "data"
    rows_per_part = 13

    def expression(self, ctx: Context) -> ca.SX:
        out = []
        for j in range(len(ctx.poses)):
            P = ctx.data_pose(j)
            Lm = ctx.params.get(f"Lm{j}", 4, 4)
            B = ctx.params.get(f"B{j}", 3, 4)
            sqrt_c0 = ctx.params.get(f"sqrt_c0_{j}")
            cbar = ctx.params.get(f"cbar{j}", 3)
            pbar = ctx.params.get(f"pbar{j}", 3)
            sR = P.s * P.R
            A = ca.horzcat(sR, sR @ cbar + P.t - pbar)
            k = ctx.data_weight(j)
            out.append(k * ca.vec(A @ Lm - B) / ctx.L)
            out.append(k * sqrt_c0)
        return ca.vertcat(*out)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        v = {}
        for j, m in enumerate(inputs.require("moments", self.name)):
            v[f"Lm{j}"], v[f"B{j}"], v[f"sqrt_c0_{j}"], v[f"cbar{j}"], v[f"pbar{j}"] = m.Lm, m.B, m.sqrt_c0, m.cbar, m.pbar
        return v


def part_moments(points_cam, npcs, weights, L: float) -> PartMoments:
    """Numeric moments of one part for :class:`DataTerm` (``Lp`` left ``None``).

    Parameters
    ----------
    points_cam : (n, 3) float64
        Camera-frame points (metres).
    npcs : (n, 3) float64
        Their NPCS coordinates.
    weights : (n,) float64
        Non-negative weights with a positive sum.
    L : float
        Object scale (metres) used to normalise the residual.
    """
    w = weights / weights.sum()
    cbar = w @ npcs
    pbar = w @ points_cam
    x = np.empty((len(w), 4))
    x[:, :3] = npcs - cbar
    x[:, 3] = 1.0
    pc = points_cam - pbar
    xw = x * w[:, None]
    M = xw.T @ x
    C = xw.T @ pc  # (4, 3)
    P = float(np.sum(w * np.einsum("ij,ij->i", pc, pc)))
    lam, V = np.linalg.eigh(M)
    keep = lam > 1e-12 * max(lam.max(), 1e-300)
    root = np.where(keep, np.sqrt(np.where(keep, lam, 1.0)), 0.0)
    inv_root = np.where(keep, 1.0 / np.where(keep, root, 1.0), 0.0)
    Lm = V * root
    B = (C.T @ V) * inv_root
    c0 = max(P - float(np.sum(B * B)), 0.0) / L**2
    return PartMoments(Lm, B, np.sqrt(c0), cbar, pbar)


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


@register_term
class CommonScaleTerm(EnergyTerm):
    """Soft common object scale: ``sqrt(w) (s_j / Gs_j - s_root / Gs_root) / L`` for ``j != root``."""

    name = "common_scale"

    def expression(self, ctx: Context) -> ca.SX:
        return ca.sqrt(ctx.params.get("common_scale_weight")) * _object_scale_differences(ctx)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        return {"common_scale_weight": inputs.require("weights", self.name).common_scale_weight}


@register_term
class ExactCommonScaleTerm(EnergyTerm):
    """One object scale, exactly: ``(s_j / Gs_j - s_root / Gs_root) / L == 0`` for ``j != root``."""

    name = "exact_common_scale"
    kind = "equality"

    def expression(self, ctx: Context) -> ca.SX:
        return _object_scale_differences(ctx)


@register_term
class CanonicalPriorTerm(EnergyTerm):
    """Prior on the canonical-parameter offsets: ``sqrt(w) [dGt_j; dq_k]`` (NAOCS units).

    Only meaningful in a program whose canonical parameters are free (see :class:`Canonical`);
    parameter ``naocs_prior_weight`` (``w``).
    """

    name = "naocs_prior"

    def expression(self, ctx: Context) -> ca.SX:
        if not ctx.canonical.free:
            raise ValueError("naocs_prior: the program's canonical parameters are fixed (free_canonical=False)")
        return ca.sqrt(ctx.params.get("naocs_prior_weight")) * ctx.canonical.offsets()

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        return {"naocs_prior_weight": inputs.require("weights", self.name).naocs_prior_weight}


@register_term
class NpcsBiasPriorTerm(EnergyTerm):
    """Prior on per-part NPCS orientation biases: ``sqrt(w) b_j`` (radians), parameter ``npcs_bias_weight`` (``w``).

    A provider's NPCS of one part can be off by a rotation about the NPCS origin common to all its points
    (a per-part orientation error: it does not average out over the points, and a per-part similarity fit
    absorbs it into the part's rotation and keeps the NPCS origin in place). With NPCS biases the data terms
    compare the points with ``s_j R_j exp(b_j) c + t_j`` (:meth:`Context.data_pose`): ``b_j`` takes up
    what the part's data want beyond the joints, at the cost ``w |b_j|^2``, while ``R_j`` (reported)
    keeps the joints exact. With scale biases (``ProgramKey.npcs_scale_bias``) each part's log-scale ``beta_j``
    about its NPCS origin joins ``b_j`` under the same prior (an isotropic NPCS error, which a per-part similarity
    also absorbs; the point-to-point data term then weighs the part by ``exp(-beta_j)``, :meth:`Context.data_weight`),
    with stretch biases (``ProgramKey.npcs_stretch_bias``) also a symmetric traceless stretch ``S_j`` (five parameters),
    so the part's NPCS may be off by any linear map near the identity about its origin, as a per-part affine fit allows.
    Only meaningful in a program with NPCS-bias variables (``ProgramKey.npcs_bias``).
    """

    name = "npcs_bias_prior"

    def expression(self, ctx: Context) -> ca.SX:
        if ctx.npcs_bias is None:
            raise ValueError("npcs_bias_prior: the program has no NPCS-bias variables (npcs_bias=False)")
        return ca.sqrt(ctx.params.get("npcs_bias_weight")) * ca.vertcat(*ctx.npcs_bias)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        return {"npcs_bias_weight": inputs.require("weights", self.name).npcs_bias_weight}


@register_term
class TemporalPriorTerm(EnergyTerm):
    """Prior toward a prediction from previous frames (tracking): ``[sqrt(w) vec(R - R'); sqrt(w) (o - o') / L;
    sqrt(w) (sigma - sigma') / L; sqrt(w_q) dtheta_k]``.

    ``R``, ``o``, ``sigma``: the object pose seen through the root part (rotation, NAOCS origin in
    the camera, metres per NAOCS unit); primes: the :class:`PreviousSolution` (the last solution:
    a zero-velocity prior; or its constant-velocity extrapolation, :meth:`PreviousSolution.constant_velocity`:
    a prior on the change of pose and joint-state velocity). ``dtheta_k`` is the deviation of
    joint state ``k`` (:func:`joint_state_expr`): radians, or divided by ``L`` (prismatic).
    Weights ``w`` (pose) and ``w_q`` (joint states) of the :class:`PreviousSolution`, entering as the
    parameters ``sqrt_temporal_weight`` and ``sqrt_temporal_state_weight`` (either may be 0).
    Defined on the part poses, so it serves both parameterisations.
    """

    name = "temporal_prior"

    def expression(self, ctx: Context) -> ca.SX:
        st, r = ctx.structure, ctx.structure.root
        pose = [ca.vec(ctx.poses[r].R - ctx.params.get("prev_R", 3, 3)),
                (ctx.naocs_to_cam(r, ca.DM.zeros(3)) - ctx.params.get("prev_origin", 3)) / ctx.L,
                (ctx.object_scale(r) - ctx.params.get("prev_scale")) / ctx.L]
        # the parameters are the weights' square roots: sqrt(w) of a parameter has no derivative at w = 0,
        # and a zero joint-state weight with a pose weight (or the reverse) made the multipliers NaN
        out = [ctx.params.get("sqrt_temporal_weight") * ca.vertcat(*pose)]
        w_q = ctx.params.get("sqrt_temporal_state_weight")
        for k in range(st.num_joints):
            d = joint_state_expr(ctx, k) - ctx.params.get(f"prev_state{k}")
            out.append(w_q * (d if st.is_revolute(k) else d / ctx.L))
        return ca.vertcat(*out)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        prev = inputs.require("previous", self.name)
        if len(prev.joint_states) != structure.num_joints:
            raise ValueError(f"inputs.previous.joint_states: expected {structure.num_joints} states, got {len(prev.joint_states)}")
        T = prev.T_cam_naocs
        return {"sqrt_temporal_weight": np.sqrt(prev.weight), "sqrt_temporal_state_weight": np.sqrt(prev.state_weight),
                "prev_R": T.rotation, "prev_origin": T.translation, "prev_scale": T.scale,
                **{f"prev_state{k}": q for k, q in enumerate(prev.joint_states)}}


@register_term
class PointToPlaneTerm(EnergyTerm):
    """Point-to-plane data term on per-part moments (parameters ``Lp{j}`` (13, 13), ``pbar{j}``).

    The point-to-plane ICP error of every part, ``sum_i w_i (n_i . (p_i - (s_j R_j c_i + t_j)))^2 / L^2`` with ``n_i = R_j m_i`` the model
    normal ``m_i`` (NPCS) rotated into the camera. Like the point-to-point
    :class:`~ancsh.solvers.terms.DataTerm` it depends on the points only through moments, so
    its cost does not grow with the number of points: with
    ``phi_i = [vec((p_i - pbar) m_i^T); m_i; m_i . c_i]`` (13) and
    ``beta = [vec(R); -R^T (t - pbar); -s]`` the residual of point ``i`` is ``beta . phi_i``, hence
    ``sum_i w_i r_i^2 = |Lp^T beta|^2`` with ``Lp Lp^T = sum_i w_i phi_i phi_i^T``.
    """

    name = "point_to_plane"
    rows_per_part = 13
    residual_dims = 1

    def expression(self, ctx: Context) -> ca.SX:
        if ctx.npcs_stretch:
            raise ValueError(f"terms: the {self.name!r} term needs rotations (its normals turn with R_j); "
                             "NPCS stretch biases are for the point-to-point data term")
        out = []
        for j in range(len(ctx.poses)):
            P = ctx.data_pose(j)
            Lp = ctx.params.get(f"Lp{j}", 13, 13)
            pbar = ctx.params.get(f"pbar{j}", 3)
            beta = ca.vertcat(ca.vec(P.R), -(P.R.T @ (P.t - pbar)), -P.s)
            out.append((Lp.T @ beta) / ctx.L)
        return ca.vertcat(*out)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        v = {}
        for j, m in enumerate(inputs.require("moments", self.name)):
            if m.Lp is None:
                raise ValueError(f"inputs.moments[{j}].Lp: required by the {self.name!r} term, got None")
            v[f"Lp{j}"], v[f"pbar{j}"] = m.Lp, m.pbar
        return v


def plane_moments(points_cam, npcs, normals_npcs, weights, pbar) -> np.ndarray:
    """``Lp`` ``(13, 13)`` of one part for :class:`PointToPlaneTerm`.

    Parameters
    ----------
    points_cam : (n, 3) float64
        Observed points (metres, camera frame).
    npcs : (n, 3) float64
        Their matches in the part's NPCS.
    normals_npcs : (n, 3) float64
        Unit model normals at the matches, in NPCS.
    weights : (n,) float64
        Non-negative weights; the moments use ``weights / sum(weights)`` like the
        point-to-point term (a per-part weighted mean).
    pbar : (3,) float64
        The centring point (the same ``pbar`` as the point-to-point term of this part).
    """
    w = np.asarray(weights, dtype=np.float64)
    total = w.sum()
    if total <= 0:
        return np.zeros((13, 13))
    w = w / total
    pc = np.asarray(points_cam) - pbar
    m = np.asarray(normals_npcs)
    # vec() is column-major in CasADi: vec(A)[3 * col + row] = A[row, col]; (p m^T)[r, c] = p_r m_c.
    phi = np.empty((len(w), 13))
    phi[:, :9] = (m[:, :, None] * pc[:, None, :]).reshape(-1, 9)
    phi[:, 9:12] = m
    phi[:, 12] = np.einsum("ij,ij->i", m, np.asarray(npcs))
    M = (phi * w[:, None]).T @ phi
    lam, V = np.linalg.eigh(M)
    return V * np.sqrt(np.clip(lam, 0.0, None))


def _object_scale_differences(ctx: Context) -> ca.SX:
    """``(s_j / Gs_j - s_root / Gs_root) / L`` for every part ``j != root``."""
    r = ctx.structure.root
    out = [(ctx.object_scale(j) - ctx.object_scale(r)) / ctx.L for j in range(ctx.structure.num_parts) if j != r]
    return ca.vertcat(*out) if out else ca.SX(0, 1)
