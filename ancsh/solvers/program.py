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
``naocs_prior`` term must then be among the terms. With ``npcs_bias`` every part gets an NPCS-bias rotation
vector after them (the data terms compare the points through ``R_j exp(b_j)``; the ``npcs_bias_prior`` term must
be among the terms), with ``npcs_scale_bias`` also a log-scale ``beta_j`` (through ``s_j exp(beta_j) R_j exp(b_j)``,
see :meth:`~ancsh.solvers.terms.Context.data_pose`), with ``npcs_stretch_bias`` also a symmetric traceless stretch
``S_j`` (through ``s_j exp(beta_j) R_j exp(b_j) (I + S_j)``).

Seams
-----
A program is keyed by term classes (:class:`ProgramKey`; names are accepted and looked up in
:data:`~ancsh.solvers.terms.TERMS`, for configuration and the command line). Callers fill its
parameters from typed :class:`~ancsh.solvers.terms.ProgramInputs` with :meth:`Program.pack`
(each term fills its own parameters), start from :meth:`Program.initial_x` within
:meth:`Program.variable_bounds`, and read a solution with :meth:`Program.unpack` (part poses,
object pose, joint states, canonical offsets): the layout of ``x`` never leaves this module.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..geometry.rotations import exp_so3
from ..geometry.transforms import Sim3
from .terms import (
    TERMS, Canonical, CanonicalOffsets, CanonicalParameters, CanonicalPriorTerm, Context, EnergyTerm, KinematicStructure,
    NpcsBiasPriorTerm, Params, PoseExpr, ProgramInputs, ProgramStart, axis_angle_sx, canonical_parameter_values, exp_so3_sx, joint_state_expr,
)

__all__ = [
    "PARAMETERISATIONS", "DataBlock", "NumpyFunction", "Program", "ProgramKey", "PostProcess", "Solution", "get_program",
    "postprocess_function", "program_build_count",
]

PARAMETERISATIONS = ("maximal", "reduced")


class NumpyFunction:
    """A CasADi Function evaluated through numpy buffers: dense float64 arrays in and out.

    Calling a ``casadi.Function`` with numpy arrays converts every argument and result to a ``DM``
    (about 75 us per call for the programs here); evaluating through its ``buffer()`` costs about
    3 us, so a fit's dozens of calls stop dominating it. Buffers are per thread (cached programs are
    shared across threads).

    Call with the Function's inputs in order (anything ``numpy.ravel`` turns into the input's number of
    elements, column-major for matrices); returns one array per output: ``(m,)`` for a column vector,
    ``(m, n)`` for a matrix (a tuple when there are several outputs, the array itself when one).
    ``function`` is the wrapped Function (its outputs made dense).
    """

    def __init__(self, function: ca.Function):
        if not _all_dense(function):
            ins = function.mx_in()
            outs = [ca.densify(o) for o in function.call(ins)]
            function = ca.Function(function.name(), ins, outs, function.name_in(), function.name_out())
        self.function = function
        self._sizes_in = [int(function.nnz_in(i)) for i in range(function.n_in())]
        self._shapes_out = [tuple(function.size_out(i)) for i in range(function.n_out())]
        self._local = threading.local()

    def _buffers(self):
        b = getattr(self._local, "buffers", None)
        if b is None:
            buf, trigger = self.function.buffer()
            args = [np.zeros(n) for n in self._sizes_in]
            res = [np.zeros((m, n)) if n == 1 else np.zeros((n, m)) for m, n in self._shapes_out]  # column-major
            for i, a in enumerate(args):
                buf.set_arg(i, memoryview(a))
            for i, a in enumerate(res):
                buf.set_res(i, memoryview(a))
            b = self._local.buffers = (buf, trigger, args, res)
        return b

    def __call__(self, *inputs):
        if len(inputs) != len(self._sizes_in):
            raise ValueError(f"{self.function.name()}: expected {len(self._sizes_in)} inputs, got {len(inputs)}")
        _, trigger, args, res = self._buffers()
        for a, v in zip(args, inputs):
            a[:] = np.ravel(v)
        trigger()
        out = [r.ravel().copy() if r.shape[1] == 1 else r.T.copy() for r in res]
        return out[0] if len(out) == 1 else tuple(out)


def _all_dense(function: ca.Function) -> bool:
    return all(function.sparsity_out(i).is_dense() for i in range(function.n_out()))


@dataclass(frozen=True)
class ProgramKey:
    """What a program depends on (never the frame's numbers).

    Attributes
    ----------
    structure : KinematicStructure
    parameterisation : str
        One of :data:`PARAMETERISATIONS`.
    optimize_scale : bool
    terms : tuple of EnergyTerm subclasses
        In residual order. Registered names (:data:`~ancsh.solvers.terms.TERMS`) are accepted
        and replaced by their classes.
    free_canonical : bool
    npcs_bias : bool
        Per-part NPCS-bias rotation variables (3 per part, appended to ``x`` after the canonical
        offsets) in the data terms; the ``npcs_bias_prior`` term must then be among the terms.
    npcs_scale_bias : bool
        With ``npcs_bias``: a fourth bias variable per part, a log-scale about the NPCS origin.
    npcs_stretch_bias : bool
        With ``npcs_scale_bias``: five more bias variables per part, a symmetric traceless stretch about the NPCS
        origin (with the rotation and the log-scale, any linear map near the identity; 9 per part).
    """

    structure: KinematicStructure
    parameterisation: str
    optimize_scale: bool
    terms: tuple
    free_canonical: bool = False
    npcs_bias: bool = False
    npcs_scale_bias: bool = False
    npcs_stretch_bias: bool = False

    def __post_init__(self):
        if self.npcs_scale_bias and not self.npcs_bias:
            raise ValueError("npcs_scale_bias: needs the NPCS-bias variables (npcs_bias=True)")
        if self.npcs_stretch_bias and not self.npcs_scale_bias:
            raise ValueError("npcs_stretch_bias: needs the NPCS scale biases (npcs_scale_bias=True)")
        classes = []
        for t in self.terms:
            if isinstance(t, type) and issubclass(t, EnergyTerm):
                classes.append(t)
            elif isinstance(t, str) and t in TERMS:
                classes.append(TERMS[t])
            else:
                raise ValueError(f"terms: unknown term {t!r}; registered: {sorted(TERMS)}")
        object.__setattr__(self, "terms", tuple(classes))


@dataclass(frozen=True)
class DataBlock:
    """Residual rows of one data term on one part (see :attr:`Program.data_blocks`).

    Attributes
    ----------
    rows : slice
        Rows of the program's residual vector (their squared norm is the part's weighted mean
        squared point residual over ``L^2``).
    part : int
    residual_dims : int
        Residual components per observed point (3 point-to-point, 1 point-to-plane).
    """

    rows: slice
    part: int
    residual_dims: int


@dataclass(frozen=True)
class Solution:
    """A program's decision vector, unpacked (see :meth:`Program.unpack`).

    Attributes
    ----------
    T_cam_npcs : tuple of Sim3
        Per-part poses (NPCS -> camera, metres); not validated (check finiteness).
    T_cam_naocs : Sim3 or None
        ``reduced``: the object pose, NAOCS -> camera of the root part, scale the object's size
        in metres; ``None`` for ``maximal``.
    joint_states : (K,) float64 or None
        ``reduced``: joint states relative to rest (radians / metres); ``None`` for ``maximal``.
    canonical_offsets : CanonicalOffsets or None
        With free canonical parameters, their solved offsets; else ``None``.
    npcs_bias : (M, 3), (M, 4) or (M, 9) float64 or None
        With NPCS-bias variables, each part's bias rotation vector (radians, NPCS frame), with a scale bias
        also its log-scale (fourth column), with a stretch bias also its five stretch parameters
        (:func:`~ancsh.solvers.terms.stretch_sx`); else ``None``.
    """

    T_cam_npcs: tuple
    T_cam_naocs: Sim3 | None
    joint_states: np.ndarray | None
    canonical_offsets: CanonicalOffsets | None
    npcs_bias: np.ndarray | None = None


def _maximal_variables(st: KinematicStructure, params: Params, optimize_scale: bool):
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


def _maximal_values(st: KinematicStructure, start: ProgramStart) -> dict:
    if start.T_cam_npcs is None:
        raise ValueError("inputs.start.T_cam_npcs: required by the 'maximal' parameterisation, got None")
    v = {}
    for j, T in enumerate(start.T_cam_npcs):
        v[f"R0_{j}"], v[f"t0_{j}"], v[f"s0_{j}"] = T.rotation, T.translation, T.scale
    return v


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
    layout = {"w": slice(0, 3), "dt": slice(3, 6), "theta": slice(start, start + st.num_joints)}
    if optimize_scale:
        layout["rho"] = 6
    return ca.vertcat(*xs), poses, layout


def _reduced_values(st: KinematicStructure, start: ProgramStart) -> dict:
    T = start.T_cam_naocs
    if T is None:
        raise ValueError("inputs.start.T_cam_naocs: required by the 'reduced' parameterisation, got None")
    return {"R0_obj": T.rotation, "tau0_obj": T.translation, "sigma0": T.scale}


_VARIABLES = {
    # (variables(structure, params, optimize_scale, canonical) -> (x, poses, layout), start values)
    "maximal": (lambda st, params, optimize_scale, canonical: _maximal_variables(st, params, optimize_scale), _maximal_values),
    "reduced": (_reduced_variables, _reduced_values),
}


class Program:
    """Symbolic program of one :class:`ProgramKey` with its CasADi Functions."""

    def __init__(self, key: ProgramKey):
        if key.parameterisation not in _VARIABLES:
            raise ValueError(f"parameterisation: expected one of {PARAMETERISATIONS}, got {key.parameterisation!r}")
        self.key = key
        st = key.structure
        self.params = Params()
        self.params.get("L")
        canonical = Canonical(st, self.params, free=key.free_canonical)
        variables, self._start_values = _VARIABLES[key.parameterisation]
        x, poses, layout = variables(st, self.params, key.optimize_scale, canonical)
        offsets = canonical.offsets()
        if key.free_canonical:
            if CanonicalPriorTerm not in key.terms:
                raise ValueError(f"terms: free canonical parameters need the {CanonicalPriorTerm.name!r} term")
            layout["canonical"] = slice(int(x.numel()), int(x.numel() + offsets.numel()))
            x = ca.vertcat(x, offsets)
        bias = None
        if key.npcs_bias:
            if NpcsBiasPriorTerm not in key.terms:
                raise ValueError(f"terms: NPCS-bias variables need the {NpcsBiasPriorTerm.name!r} term")
            dims = 9 if key.npcs_stretch_bias else 4 if key.npcs_scale_bias else 3
            bias = [ca.SX.sym(f"b{j}", dims) for j in range(st.num_parts)]
            layout["npcs_bias"] = slice(int(x.numel()), int(x.numel()) + dims * st.num_parts)
            x = ca.vertcat(x, *bias)
        self.x = x
        self._layout = layout
        self.canonical = canonical
        ctx = Context(st, self.params, poses, canonical, bias)
        self.terms = [cls() for cls in key.terms]
        costs, eqs, ineqs = [], [], []
        self.cost_names, self.inequality_terms = [], []
        self._data_blocks = []
        row = 0
        for term in self.terms:
            e = term.expression(ctx)
            if term.kind == "cost":
                costs.append(e)
                self.cost_names.append(term.name)
                if term.rows_per_part:
                    for j in range(st.num_parts):
                        a = row + j * term.rows_per_part
                        self._data_blocks.append(DataBlock(slice(a, a + term.rows_per_part), j, term.residual_dims))
                row += int(e.numel())
            elif term.kind == "equality":
                eqs.append(e)
            elif term.kind == "inequality":
                ineqs.append(e)
                self.inequality_terms.append(term)
            else:
                raise ValueError(f"term {term.name!r}: unknown kind {term.kind!r}")
        # The reported object pose and joints as expressions of x (declares their parameters before p is fixed).
        r0 = st.root
        outputs = ca.vertcat(ca.vec(poses[r0].R), ctx.naocs_to_cam(r0, ca.DM.zeros(3)), ctx.object_scale(r0),
                             *_joint_expressions(ctx))
        p = self.params.vector()
        r = ca.vertcat(*costs) if costs else ca.SX(0, 1)
        self.num_equalities = int(sum(e.numel() for e in eqs))
        g = ca.vertcat(*(eqs + ineqs)) if (eqs or ineqs) else ca.SX(0, 1)
        self.num_x = int(x.numel())
        self.num_residuals = int(r.numel())
        self.num_constraints = int(g.numel())
        self._r, self._g, self._p = r, g, p
        # Functions of (x, p), evaluated through numpy buffers (NumpyFunction; .function is the CasADi Function).
        fn = lambda name, outs, names: NumpyFunction(  # noqa: E731
            ca.Function(name, [x, p], [ca.densify(o) for o in outs], ["x", "p"], names))
        self.residual = fn("residual", [r], ["r"])
        J = ca.densify(ca.jacobian(r, x))
        self.jacobian = fn("jacobian", [J], ["J"])
        self.residual_jacobian = fn("residual_jacobian", [r, J], ["r", "J"])
        self.term_costs = fn("term_costs", [ca.vertcat(*[ca.sumsqr(c) for c in costs]) if costs else ca.SX(0, 1)], ["costs"])
        self.constraints = fn("constraints", [g], ["g"])
        self.constraint_jacobian = fn("constraint_jacobian", [ca.densify(ca.jacobian(g, x))], ["Jg"])
        pose_out = []
        for P in poses:
            pose_out += [ca.vec(P.R), P.t, P.s]
        self.poses = fn("poses", [ca.vertcat(*pose_out)], ["poses"])
        self._outputs = ca.vertcat(*pose_out, outputs)
        self._linearisation = None
        self._nlpsols: dict = {}
        self._nlp_lock = threading.Lock()

    def pack(self, inputs: ProgramInputs) -> np.ndarray:
        """The parameter vector ``p`` for ``inputs``: the context's, the parameterisation's and
        each term's parameters, each filled by its owner.

        Raises
        ------
        ValueError
            When ``inputs`` lacks something a term or the parameterisation needs (naming it).
        """
        if not isinstance(inputs, ProgramInputs):
            raise ValueError(f"inputs: expected ProgramInputs, got {type(inputs).__name__}")
        st = self.key.structure
        values = Context.fill(inputs)
        values.update(self._start_values(st, inputs.start))
        for term in self.terms:
            values.update(term.fill(st, inputs))
        return self.params.pack(values)

    @property
    def has_joint_states(self) -> bool:
        """Whether joint states are decision variables (``reduced``)."""
        return "theta" in self._layout

    def initial_x(self, joint_states=None, canonical_offsets: CanonicalOffsets | None = None,
                  npcs_bias=None) -> np.ndarray:
        """The start ``x``: zero (the :class:`~ancsh.solvers.terms.ProgramStart` itself) with the
        joint states ``(K,)`` (relative to rest; ``reduced`` only), the canonical offsets (free
        canonical parameters only) and the NPCS biases ``(M, 3)`` (``(M, 4)`` with scale biases, ``(M, 9)`` with stretch biases; NPCS-bias programs
        only) when given.

        With the start poses of a :class:`Solution` and its states, offsets and biases this ``x``
        reproduces the solution (how a solution is linearised in another program of its structure).
        """
        x0 = np.zeros(self.num_x)
        if npcs_bias is not None:
            if "npcs_bias" not in self._layout:
                raise ValueError("npcs_bias: this program has no NPCS-bias variables")
            b = np.asarray(npcs_bias, dtype=np.float64).ravel()
            sl = self._layout["npcs_bias"]
            if b.size != sl.stop - sl.start:
                raise ValueError(f"npcs_bias: expected {(sl.stop - sl.start) // self.key.structure.num_parts} values per "
                                 f"part, got shape {np.shape(npcs_bias)}")
            x0[sl] = b
        if joint_states is not None:
            if not self.has_joint_states:
                raise ValueError("joint_states: this program has no joint-state variables (maximal parameterisation)")
            x0[self._layout["theta"]] = joint_states
        if canonical_offsets is not None:
            if "canonical" not in self._layout:
                raise ValueError("canonical_offsets: this program's canonical parameters are fixed")
            M = self.key.structure.num_parts
            parts = [np.asarray(canonical_offsets.npcs_translation, dtype=np.float64).reshape(M, 3).ravel()]
            parts += [np.asarray(canonical_offsets.joint_pivots_naocs[k], dtype=np.float64) for k in sorted(self.canonical.dq)]
            x0[self._layout["canonical"]] = np.concatenate(parts)
        return x0

    @property
    def data_blocks(self) -> tuple["DataBlock", ...]:
        """The residual rows of observed data, per term and part (the noise sources of a covariance)."""
        return tuple(self._data_blocks)

    @property
    def num_parts(self) -> int:
        return self.key.structure.num_parts

    def linearisation(self, x, p) -> tuple[np.ndarray, ...]:
        """Everything a covariance needs at ``x``, in one call: ``(r, J, Jg, outputs, G)`` -- the
        residuals ``(m,)`` and their Jacobian ``(m, n)``, the Jacobian of the equality constraints
        ``(num_equalities, n)``, and :meth:`output_jacobian`'s outputs and Jacobian ``G``."""
        with self._nlp_lock:
            if self._linearisation is None:
                eq = self._g[: self.num_equalities]
                out = [self._r, ca.densify(ca.jacobian(self._r, self.x)), ca.densify(ca.jacobian(eq, self.x)),
                       self._outputs, ca.densify(ca.jacobian(self._outputs, self.x))]
                self._linearisation = NumpyFunction(ca.Function("linearisation", [self.x, self._p],
                                                                [ca.densify(o) for o in out]))
                _count_build("output_jacobian")
        r, J, Jg, out, G = self._linearisation(x, p)
        return r, J.reshape(self.num_residuals, self.num_x), Jg.reshape(self.num_equalities, self.num_x), out, \
            G.reshape(-1, self.num_x)

    def output_jacobian(self, x, p) -> tuple[np.ndarray, np.ndarray]:
        """The reported quantities at ``x`` and their Jacobian with respect to ``x``.

        Returns
        -------
        outputs : (13 M + 13 + 7 K,) float64
            Per part ``vec(R)`` (column-major), ``t`` (metres), ``s``; the object pose (root part's
            ``vec(R)``, NAOCS origin in the camera (metres), metres per NAOCS unit); joint axes
            ``(3 K)`` (unit, camera), pivots ``(3 K)`` (metres, camera), states ``(K)`` (relative to
            rest), defined as in :func:`postprocess_function` but with the program's own (free)
            canonical parameters.
        jacobian : (len(outputs), n) float64
        """
        _, _, _, out, G = self.linearisation(x, p)
        return out, G

    def variable_bounds(self, joint_limits=None) -> tuple[np.ndarray, np.ndarray]:
        """``(lbx, ubx)``: the joint limits ``(K, 2)`` (relative to rest) on the joint states of a
        ``reduced`` program; unbounded otherwise."""
        lbx = np.full(self.num_x, -np.inf)
        ubx = np.full(self.num_x, np.inf)
        if joint_limits is not None and self.has_joint_states:
            sl = self._layout["theta"]
            lbx[sl], ubx[sl] = joint_limits[:, 0], joint_limits[:, 1]
        return lbx, ubx

    def unpack(self, x, p) -> Solution:
        """The solution at ``x`` for the parameter vector ``p`` (from :meth:`pack`)."""
        x = np.asarray(x, dtype=np.float64).ravel()
        st = self.key.structure
        parts = tuple(Sim3.unchecked(R, t, s) for R, t, s in self.unpack_poses(x, p))
        T_cam_naocs = states = offsets = None
        lay = self._layout
        if self.has_joint_states:
            pv = np.asarray(p, dtype=np.float64).ravel()
            R = self.params.value(pv, "R0_obj") @ exp_so3(x[lay["w"]])
            tau = self.params.value(pv, "tau0_obj") + float(self.params.value(pv, "L")) * x[lay["dt"]]
            sigma = float(self.params.value(pv, "sigma0"))
            if "rho" in lay:
                sigma = sigma * float(np.exp(x[lay["rho"]]))
            T_cam_naocs = Sim3.unchecked(R, tau, sigma)
            states = x[lay["theta"]].copy()
        if "canonical" in lay:
            off = x[lay["canonical"]]
            M = st.num_parts
            dq = np.zeros((st.num_joints, 3))
            for i, k in enumerate(sorted(self.canonical.dq)):
                dq[k] = off[3 * (M + i) : 3 * (M + i) + 3]
            offsets = CanonicalOffsets(off[: 3 * M].reshape(M, 3).copy(), dq)
        bias = x[lay["npcs_bias"]].reshape(st.num_parts, -1).copy() if "npcs_bias" in lay else None
        return Solution(parts, T_cam_naocs, states, offsets, bias)

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

    def constraint_bounds(self, joint_limits) -> tuple[np.ndarray, np.ndarray]:
        """``(lbg, ubg)`` of the constraints: zero for equalities, the inequality terms' bounds
        given the joint limits ``(K, 2)`` (relative to rest)."""
        lo = [np.zeros(self.num_equalities)]
        hi = [np.zeros(self.num_equalities)]
        for term in self.inequality_terms:
            a, b = term.bounds(joint_limits)
            lo.append(a)
            hi.append(b)
        return np.concatenate(lo), np.concatenate(hi)

    def unpack_poses(self, x, p) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """``[(R (3, 3), t (3,), s), ...]`` per part at ``x``."""
        v = self.poses(x, p)
        out = []
        for j in range(self.key.structure.num_parts):
            b = v[13 * j : 13 * (j + 1)]
            out.append((b[:9].reshape(3, 3, order="F"), b[9:12].copy(), float(b[12])))
        return out


_CACHE: dict = {}
_CACHE_LOCK = threading.Lock()
_BUILDS = {"program": 0, "nlpsol": 0, "postprocess": 0, "output_jacobian": 0}


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

    def __call__(self, T_cam_npcs, canonical: CanonicalParameters) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(axes (K, 3), pivots (K, 3) metres, states (K,))`` in the camera frame.

        Parameters
        ----------
        T_cam_npcs : sequence of Sim3
            Part poses.
        canonical : CanonicalParameters
            Its ``state_reference`` centres the revolute state windows.
        """
        pose_vector = np.concatenate(
            [np.concatenate([T.rotation.ravel(order="F"), T.translation, [T.scale]]) for T in T_cam_npcs]
        )
        axes, pivots, states = self.function(pose_vector, self.params.pack(canonical_parameter_values(canonical)))
        k = int(states.size)
        return axes.reshape(k, 3), pivots.reshape(k, 3), states.reshape(k)


def _joint_expressions(ctx: Context) -> tuple[ca.SX, ca.SX, ca.SX]:
    """Camera-space joint axes ``(3 K)``, pivots ``(3 K)`` and states ``(K)`` from the context's part poses.

    Revolute: axis ``normalise((R_p + R_c) u)``, pivot the mean of ``X_p(q)`` and ``X_c(q)``;
    prismatic: axis likewise, pivot ``X_p(q)``; states from :func:`~ancsh.solvers.terms.joint_state_expr`.
    """
    st, poses = ctx.structure, ctx.poses
    axes, pivots, states = [], [], []
    for k in range(st.num_joints):
        p, c = ctx.joint_parts(k)
        u, q = ctx.axis(k), ctx.pivot(k)
        a = (poses[p].R + poses[c].R) @ u
        axes.append(a / ca.norm_2(a))
        if st.is_revolute(k):
            pivots.append(0.5 * (ctx.naocs_to_cam(p, q) + ctx.naocs_to_cam(c, q)))
        else:
            pivots.append(ctx.naocs_to_cam(p, q))
        states.append(joint_state_expr(ctx, k))
    cat = lambda xs: ca.vertcat(*xs) if xs else ca.SX(0, 1)  # noqa: E731
    return cat(axes), cat(pivots), cat(states)


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
        axes, pivots, states = _joint_expressions(ctx)
        f = NumpyFunction(ca.Function(
            "postprocess", [ca.vertcat(*pose_syms), params.vector()], [ca.densify(o) for o in (axes, pivots, states)],
            ["poses", "p"], ["axes", "pivots", "states"],
        ))
        f = PostProcess(f, params)
        _POST_CACHE[structure] = f
        _count_build("postprocess")
        return f
