"""The symbolic context every energy term reads (part poses, canonical parameters, named parameters), small
CasADi helpers, the term base class :class:`EnergyTerm` and the registry :data:`TERMS`."""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..inputs import KinematicStructure, ProgramInputs, canonical_parameter_values

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
