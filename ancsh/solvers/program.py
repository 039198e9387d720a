"""CasADi programs: variables of a formulation + its terms, built once per kinematic structure.

A :class:`Program` owns the symbolic decision vector ``x`` of one parameterisation, the
named parameters ``p`` (data moments, initial poses, canonical joint parameters, weights),
and CasADi Functions of ``(x, p)``: stacked residuals and their Jacobian (scipy backend),
per-term energies, constraints, part poses, and (lazily) an IPOPT ``nlpsol``. Everything
that changes per frame is a parameter, so :func:`get_program` builds a program once per
``(structure, parameterisation, scale mode, terms)`` and the cache is reused across frames
and RANSAC rounds; :func:`program_build_count` exposes how many programs were built.

Parameterisations
-----------------
``"maximal"``: every part ``j`` has a local rotation vector ``w_j`` around an initial
rotation, ``R_j = R0_j exp(w_j)``, a translation ``t_j = t0_j + L dt_j`` and (when the scale
is optimised) a log-scale ``s_j = s0_j exp(rho_j)``.

``"reduced"``: one object pose (NAOCS -> camera of the root part: ``R = R0 exp(w)``,
``tau = tau0 + L dt``, object scale ``sigma = sigma0 exp(rho)``) and one state per joint
``theta_k`` (relative to rest: radians / metres). Part poses follow by forward kinematics
over the joint tree in NAOCS: a revolute child is ``X_c(g) = X_p(Rot(u, theta)(g - q) + q)``,
a prismatic child ``X_c(g) = X_p(g) + theta R_p u``; then ``s_j = sigma Gs_j`` and
``t_j = X_j(Gt_j)``.

With ``free_canonical`` the canonical parameters ``Gt_j`` and revolute pivots ``q_k`` get
offset variables appended to ``x`` (see :class:`~ancsh.solvers.terms.Canonical`); the
``naocs_prior`` term must then be among the terms.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .terms import TERMS, Canonical, Context, KinematicStructure, Params, PoseExpr, axis_angle_sx, exp_so3_sx, joint_state_expr

__all__ = ["PARAMETERISATIONS", "Program", "ProgramKey", "PostProcess", "get_program", "postprocess_function", "program_build_count"]

PARAMETERISATIONS = ("maximal", "reduced")


@dataclass(frozen=True)
class ProgramKey:
    """What a program depends on (never the frame's numbers)."""

    structure: KinematicStructure
    parameterisation: str
    optimize_scale: bool
    terms: tuple
    free_canonical: bool = False


def _maximal_variables(st: KinematicStructure, params: Params, optimize_scale: bool, canonical: Canonical):
    xs, poses, layout = [], [], {}
    for j in range(st.num_parts):
        w = ca.SX.sym(f"w{j}", 3)
        dt = ca.SX.sym(f"dt{j}", 3)
        R = params.get(f"R0_{j}", 3, 3) @ exp_so3_sx(w)
        t = params.get(f"t0_{j}", 3) + params.get("L") * dt
        s = params.get(f"s0_{j}")
        xs += [w, dt]
        if optimize_scale:
            rho = ca.SX.sym(f"rho{j}")
            s = s * ca.exp(rho)
            xs.append(rho)
        poses.append(PoseExpr(R, t, s))
    return ca.vertcat(*xs), poses, layout


def _reduced_variables(st: KinematicStructure, params: Params, optimize_scale: bool, canonical: Canonical):
    w = ca.SX.sym("w", 3)
    dt = ca.SX.sym("dt", 3)
    xs = [w, dt]
    sigma = params.get("sigma0")
    if optimize_scale:
        rho = ca.SX.sym("rho")
        sigma = sigma * ca.exp(rho)
        xs.append(rho)
    theta = ca.SX.sym("theta", st.num_joints)
    xs.append(theta)
    L = params.get("L")
    # NAOCS -> camera of each part: X_j(g) = sigma R_j g + tau_j
    R = [None] * st.num_parts
    tau = [None] * st.num_parts
    R[st.root] = params.get("R0_obj", 3, 3) @ exp_so3_sx(w)
    tau[st.root] = params.get("tau0_obj", 3) + L * dt
    for k in st.topological_joints():
        p, c = st.joint_parents[k], st.joint_children[k]
        u = params.get(f"u{k}", 3)
        if st.is_revolute(k):
            q = canonical.pivot(k)
            Rk = axis_angle_sx(u, theta[k])
            R[c] = R[p] @ Rk
            tau[c] = tau[p] + sigma * (R[p] @ (q - Rk @ q))
        else:
            R[c] = R[p]
            tau[c] = tau[p] + theta[k] * (R[p] @ u)
    poses = []
    for j in range(st.num_parts):
        Gs, Gt = params.get(f"Gs{j}"), canonical.Gt(j)
        poses.append(PoseExpr(R[j], sigma * (R[j] @ Gt) + tau[j], sigma * Gs))
    start = 6 + (1 if optimize_scale else 0)
    layout = {"theta": slice(start, start + st.num_joints)}
    return ca.vertcat(*xs), poses, layout


_VARIABLES = {"maximal": _maximal_variables, "reduced": _reduced_variables}


class Program:
    """Symbolic program of one :class:`ProgramKey` with its CasADi Functions."""

    def __init__(self, key: ProgramKey):
        if key.parameterisation not in _VARIABLES:
            raise ValueError(f"parameterisation: expected one of {PARAMETERISATIONS}, got {key.parameterisation!r}")
        unknown = [t for t in key.terms if t not in TERMS]
        if unknown:
            raise ValueError(f"terms: unknown term(s) {unknown}; registered: {sorted(TERMS)}")
        self.key = key
        st = key.structure
        self.params = Params()
        self.params.get("L")
        canonical = Canonical(st, self.params, free=key.free_canonical)
        x, poses, layout = _VARIABLES[key.parameterisation](st, self.params, key.optimize_scale, canonical)
        offsets = canonical.offsets()
        if key.free_canonical:
            if "naocs_prior" not in key.terms:
                raise ValueError("terms: free canonical parameters need the 'naocs_prior' term")
            layout["canonical"] = slice(int(x.numel()), int(x.numel() + offsets.numel()))
            x = ca.vertcat(x, offsets)
        self.x = x
        self.layout = layout
        self.canonical = canonical
        ctx = Context(st, self.params, poses, canonical)
        self.terms = [TERMS[name]() for name in key.terms]
        costs, eqs, ineqs = [], [], []
        self.cost_names, self.inequality_terms = [], []
        for term in self.terms:
            e = term.expression(ctx)
            if term.kind == "cost":
                costs.append(e)
                self.cost_names.append(term.name)
            elif term.kind == "equality":
                eqs.append(e)
            elif term.kind == "inequality":
                ineqs.append(e)
                self.inequality_terms.append(term)
            else:
                raise ValueError(f"term {term.name!r}: unknown kind {term.kind!r}")
        p = self.params.vector()
        r = ca.vertcat(*costs) if costs else ca.SX(0, 1)
        self.num_equalities = int(sum(e.numel() for e in eqs))
        g = ca.vertcat(*(eqs + ineqs)) if (eqs or ineqs) else ca.SX(0, 1)
        self.num_x = int(x.numel())
        self.num_residuals = int(r.numel())
        self.num_constraints = int(g.numel())
        self._r, self._g, self._p = r, g, p
        self.residual = ca.Function("residual", [x, p], [r], ["x", "p"], ["r"])
        J = ca.densify(ca.jacobian(r, x))
        self.jacobian = ca.Function("jacobian", [x, p], [J], ["x", "p"], ["J"])
        self.residual_jacobian = ca.Function("residual_jacobian", [x, p], [r, J], ["x", "p"], ["r", "J"])
        self.term_costs = ca.Function("term_costs", [x, p], [ca.vertcat(*[ca.sumsqr(c) for c in costs]) if costs else ca.SX(0, 1)])
        self.constraints = ca.Function("constraints", [x, p], [g], ["x", "p"], ["g"])
        self.constraint_jacobian = ca.Function(
            "constraint_jacobian", [x, p], [ca.densify(ca.jacobian(g, x))], ["x", "p"], ["Jg"]
        )
        pose_out = []
        for P in poses:
            pose_out += [ca.vec(P.R), P.t, P.s]
        self.poses = ca.Function("poses", [x, p], [ca.vertcat(*pose_out)], ["x", "p"], ["poses"])
        self._nlpsols: dict = {}
        self._nlp_lock = threading.Lock()

    def pack(self, values: dict) -> np.ndarray:
        return self.params.pack(values)

    def nlpsol(self, options: dict):
        """The IPOPT solver of this program for these ``options`` (built once per option set)."""
        opts_key = tuple(sorted(options.items()))
        with self._nlp_lock:
            solver = self._nlpsols.get(opts_key)
            if solver is None:
                nlp = {"x": self.x, "p": self._p, "f": ca.sumsqr(self._r), "g": self._g}
                solver = ca.nlpsol("ancsh_fit", "ipopt", nlp, dict(options))
                self._nlpsols[opts_key] = solver
                _count_build("nlpsol")
            return solver

    def constraint_bounds(self, frame: dict) -> tuple[np.ndarray, np.ndarray]:
        lo = [np.zeros(self.num_equalities)]
        hi = [np.zeros(self.num_equalities)]
        for term in self.inequality_terms:
            a, b = term.bounds(frame)
            lo.append(a)
            hi.append(b)
        return np.concatenate(lo), np.concatenate(hi)

    def unpack_poses(self, x, p) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """``[(R (3, 3), t (3,), s), ...]`` per part at ``x``."""
        v = np.asarray(self.poses(x, p)).ravel()
        out = []
        for j in range(self.key.structure.num_parts):
            b = v[13 * j : 13 * (j + 1)]
            out.append((b[:9].reshape(3, 3, order="F"), b[9:12].copy(), float(b[12])))
        return out


_CACHE: dict = {}
_CACHE_LOCK = threading.Lock()
_BUILDS = {"program": 0, "nlpsol": 0, "postprocess": 0}


def _count_build(kind: str) -> None:
    _BUILDS[kind] += 1


def get_program(key: ProgramKey) -> Program:
    """The cached program of ``key`` (built on first request)."""
    with _CACHE_LOCK:
        prog = _CACHE.get(key)
        if prog is None:
            prog = Program(key)
            _CACHE[key] = prog
            _count_build("program")
        return prog


def program_build_count() -> dict:
    """How many programs, IPOPT solvers and post-processing Functions were built so far."""
    return dict(_BUILDS)


_POST_CACHE: dict = {}


@dataclass(frozen=True)
class PostProcess:
    """A post-processing Function and the layout of its parameter vector."""

    function: ca.Function
    params: Params

    def __call__(self, pose_vector: np.ndarray, values: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(axes (K, 3), pivots (K, 3), states (K,))`` for poses packed as in :meth:`Program.poses`.

        ``values`` holds ``Gs{j}``, ``Gt{j}``, ``u{k}``, ``q{k}`` and optionally ``state_ref{k}``
        (centre of the revolute state window, default 0: states in ``(-pi, pi]``).
        """
        values = {**{n: 0.0 for n in self.params.names if n.startswith("state_ref")}, **values}
        axes, pivots, states = self.function(pose_vector, self.params.pack(values))
        k = int(np.asarray(states).size)
        return (
            np.asarray(axes).reshape(k, 3),
            np.asarray(pivots).reshape(k, 3),
            np.asarray(states).reshape(k),
        )


def postprocess_function(structure: KinematicStructure) -> PostProcess:
    """Camera-space joint parameters and states from part poses (paper Sec. 4.4).

    The Function maps ``(poses (13 M,), params)`` -> ``(axes (3 K,), pivots (3 K,), states (K,))``
    where each part contributes ``vec(R)`` (column-major), ``t`` and ``s``. Revolute:
    axis ``normalise((R_p + R_c) u)``, pivot the mean of ``X_p(q)`` and ``X_c(q)``; prismatic:
    axis likewise, pivot ``X_p(q)``; states from :func:`~ancsh.solvers.terms.joint_state_expr`.
    """
    with _CACHE_LOCK:
        f = _POST_CACHE.get(structure)
        if f is not None:
            return f
        params = Params()
        pose_syms, poses = [], []
        for j in range(structure.num_parts):
            v = ca.SX.sym(f"pose{j}", 13)
            pose_syms.append(v)
            poses.append(PoseExpr(ca.reshape(v[:9], 3, 3), v[9:12], v[12]))
        ctx = Context(structure, params, poses)
        axes, pivots, states = [], [], []
        for k in range(structure.num_joints):
            p, c = ctx.joint_parts(k)
            u, q = ctx.axis(k), ctx.pivot(k)
            a = (poses[p].R + poses[c].R) @ u
            axes.append(a / ca.norm_2(a))
            if structure.is_revolute(k):
                pivots.append(0.5 * (ctx.naocs_to_cam(p, q) + ctx.naocs_to_cam(c, q)))
            else:
                pivots.append(ctx.naocs_to_cam(p, q))
            states.append(joint_state_expr(ctx, k))
        cat = lambda xs: ca.vertcat(*xs) if xs else ca.SX(0, 1)  # noqa: E731
        f = ca.Function(
            "postprocess", [cat(pose_syms), params.vector()], [cat(axes), cat(pivots), cat(states)],
            ["poses", "p"], ["axes", "pivots", "states"],
        )
        f = PostProcess(f, params)
        _POST_CACHE[structure] = f
        _count_build("postprocess")
        return f
