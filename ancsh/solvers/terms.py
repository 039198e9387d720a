"""Energy terms and constraints of articulated fitting, each defined ONCE in CasADi.

Every term is a small class that turns the symbolic part poses of a :class:`Context` into a
CasADi expression: a least-squares residual ``r`` (energy ``|r|^2``), an equality ``g == 0``
or an inequality ``lower <= g <= upper``. The IPOPT backend puts the same expressions into
an NLP; the scipy backend evaluates CasADi Functions built from them (residuals and exact
Jacobians). Adding a term = one subclass registered with :func:`register_term`.

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

from ..model.articulated import JointType

__all__ = [
    "TERMS",
    "Canonical",
    "CanonicalPriorTerm",
    "CommonScaleTerm",
    "Context",
    "DataTerm",
    "EnergyTerm",
    "ExactCommonScaleTerm",
    "ExactJointTerm",
    "JointLimitTerm",
    "KinematicStructure",
    "ROBUST_KERNELS",
    "SoftJointTerm",
    "exp_so3_sx",
    "joint_state_expr",
    "register_term",
]

_SMALL_ANGLE2 = 1e-8  # theta^2 below which exp(w) uses its Taylor series


# --------------------------------------------------------------------------------------------
# Kinematic structure and the symbolic context
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class KinematicStructure:
    """Part count and joint tree (hashable; a program is built once per structure).

    Attributes
    ----------
    num_parts : int
    joint_types : tuple of str
        ``"revolute"`` / ``"prismatic"`` per joint.
    joint_parents, joint_children : tuple of int
    """

    num_parts: int
    joint_types: tuple
    joint_parents: tuple
    joint_children: tuple

    @classmethod
    def from_correspondences(cls, corr) -> "KinematicStructure":
        return cls(*corr.structure_key())

    @property
    def num_joints(self) -> int:
        return len(self.joint_types)

    @property
    def root(self) -> int:
        kids = set(self.joint_children)
        return next(j for j in range(self.num_parts) if j not in kids)

    def topological_joints(self) -> tuple[int, ...]:
        """Joints ordered so that each joint's parent part is reached before it."""
        placed, order = {self.root}, []
        while len(order) < self.num_joints:
            for k in range(self.num_joints):
                if k not in order and self.joint_parents[k] in placed:
                    order.append(k)
                    placed.add(self.joint_children[k])
        return tuple(order)

    def is_revolute(self, k: int) -> bool:
        return self.joint_types[k] == JointType.REVOLUTE.value


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

    def __init__(self, structure: KinematicStructure, params: Params, poses: list, canonical: Canonical | None = None):
        self.structure = structure
        self.params = params
        self.poses = poses
        self.canonical = Canonical(structure, params) if canonical is None else canonical

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

    Subclasses implement :meth:`expression`; inequalities also :meth:`bounds`.
    """

    name: str = ""
    kind: str = "cost"

    def expression(self, ctx: Context) -> ca.SX:  # pragma: no cover - abstract
        raise NotImplementedError

    def bounds(self, frame: dict) -> tuple[np.ndarray, np.ndarray]:
        """Numeric ``(lower, upper)`` of an inequality for one frame."""
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

    def expression(self, ctx: Context) -> ca.SX:
        out = []
        for j, P in enumerate(ctx.poses):
            Lm = ctx.params.get(f"Lm{j}", 4, 4)
            B = ctx.params.get(f"B{j}", 3, 4)
            sqrt_c0 = ctx.params.get(f"sqrt_c0_{j}")
            cbar = ctx.params.get(f"cbar{j}", 3)
            pbar = ctx.params.get(f"pbar{j}", 3)
            sR = P.s * P.R
            A = ca.horzcat(sR, sR @ cbar + P.t - pbar)
            out.append(ca.vec(A @ Lm - B) / ctx.L)
            out.append(sqrt_c0)
        return ca.vertcat(*out)


def part_moments(points_cam, npcs, weights, L: float) -> dict:
    """Numeric moments of one part for :class:`DataTerm` (keys without the part index).

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
    return {"Lm": Lm, "B": B, "sqrt_c0_": np.sqrt(c0), "cbar": cbar, "pbar": pbar}


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

    def bounds(self, frame: dict) -> tuple[np.ndarray, np.ndarray]:
        lim = frame["joint_limits"]
        return lim[:, 0].copy(), lim[:, 1].copy()


@register_term
class CommonScaleTerm(EnergyTerm):
    """Soft common object scale: ``sqrt(w) (s_j / Gs_j - s_root / Gs_root) / L`` for ``j != root``."""

    name = "common_scale"

    def expression(self, ctx: Context) -> ca.SX:
        return ca.sqrt(ctx.params.get("common_scale_weight")) * _object_scale_differences(ctx)


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


def _object_scale_differences(ctx: Context) -> ca.SX:
    """``(s_j / Gs_j - s_root / Gs_root) / L`` for every part ``j != root``."""
    r = ctx.structure.root
    out = [(ctx.object_scale(j) - ctx.object_scale(r)) / ctx.L for j in range(ctx.structure.num_parts) if j != r]
    return ca.vertcat(*out) if out else ca.SX(0, 1)


# --------------------------------------------------------------------------------------------
# Robust kernels for the IRLS data term (defined once, symbolically)
# --------------------------------------------------------------------------------------------
def _kernel_functions() -> dict:
    r2 = ca.SX.sym("r2")  # squared normalised residual
    c = ca.SX.sym("c")  # kernel scale
    r = ca.sqrt(r2 + 1e-300)
    huber_rho = ca.if_else(r <= c, r2, 2.0 * c * r - c * c)
    cauchy_rho = c * c * ca.log1p(r2 / (c * c))
    out = {}
    for name, rho in (("huber", huber_rho), ("cauchy", cauchy_rho)):
        # IRLS weight: rho'(r2) * 2 / 2 -> weight multiplying r^2 so that grad matches (d rho / d r2).
        weight = ca.jacobian(rho, r2)
        out[name] = ca.Function(f"{name}_kernel", [r2, c], [rho, weight], ["r2", "c"], ["rho", "weight"])
    return out


ROBUST_KERNELS: dict = _kernel_functions()
"""``name -> casadi.Function(r2, c) -> (rho, weight)``: ``rho(r^2)`` and the IRLS weight
``d rho / d(r^2)`` (1 for an inlier under Huber). Evaluate on rows of many points at once."""
