"""Numerical backends solving a :class:`~ancsh.solvers.program.Program` for one frame.

All evaluate the program's CasADi definitions: IPOPT (``casadi.nlpsol``) minimises
``|r(x, p)|^2`` subject to the program's equalities/inequalities and bounds on ``x``;
scipy ``least_squares`` minimises the same residuals with the program's exact Jacobian
(no finite differences), for programs without constraints (bounds on ``x`` allowed);
``lm`` is a compact projected Levenberg-Marquardt on the same residual and Jacobian for
those programs too -- a few CasADi calls and 3x3..30x30 solves per frame, without the fixed
cost of a general NLP solver.
A failed solve is reported in :class:`SolveOutcome`, never raised.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .program import Program
from .types import FitStatus

__all__ = ["BACKENDS", "Bounds", "SolveOutcome", "SolverOptions", "solve"]


@dataclass(frozen=True)
class Bounds:
    """Bounds of one solve: ``lbx <= x <= ubx`` and ``lbg <= g(x) <= ubg``.

    Attributes
    ----------
    lbx, ubx : (n,) float64
        Variable bounds (``-inf`` / ``inf`` where free).
    lbg, ubg : (m,) float64
        Constraint bounds of the program's equalities then inequalities (empty without constraints).
    """

    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ubg: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def of(cls, program: Program, joint_limits=None) -> "Bounds":
        """The bounds of ``program`` given the joint limits ``(K, 2)`` (relative to rest; default none)."""
        lbx, ubx = program.variable_bounds(joint_limits)
        lbg, ubg = program.constraint_bounds(joint_limits)
        return cls(lbx, ubx, lbg, ubg)


@dataclass(frozen=True)
class SolverOptions:
    """Stopping rules shared by the backends."""

    max_iterations: int = 100
    tol: float = 1e-10


@dataclass(frozen=True)
class SolveOutcome:
    """Result of one backend solve.

    Attributes
    ----------
    x : (n,) float64
        Final decision vector (the last iterate on failure).
    status : FitStatus
    message : str
        The backend's own status text.
    iterations : int
        Iterations of the backend (IPOPT's ``iter_count``; ``least_squares``' Jacobian
        evaluations, one per iteration; the projected LM's outer iterations).
    timings : dict of str to float
        The backend's own breakdown of its call, seconds (keys of
        :data:`ancsh.solvers.stages.SOLVER_STAGES`) and ``"<backend>.iterations"``; empty where it keeps none.
    """

    x: np.ndarray
    status: FitStatus
    message: str
    iterations: int
    timings: dict = field(default_factory=dict)


_IPOPT_STATUS = {
    "Solve_Succeeded": FitStatus.SUCCESS,
    "Solved_To_Acceptable_Level": FitStatus.SUCCESS,
    "Maximum_Iterations_Exceeded": FitStatus.MAX_ITER,
    "Maximum_CpuTime_Exceeded": FitStatus.MAX_ITER,
    "Infeasible_Problem_Detected": FitStatus.INFEASIBLE,
    "Restoration_Failed": FitStatus.NUMERICAL_FAILURE,
    "Invalid_Number_Detected": FitStatus.NUMERICAL_FAILURE,
}


def _ipopt_options(opts: SolverOptions) -> dict:
    return {
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "print_time": False,
        "ipopt.max_iter": int(opts.max_iterations),
        "ipopt.tol": float(opts.tol),
        "ipopt.acceptable_tol": max(float(opts.tol) * 1e3, 1e-8),
        # Fits start at the per-part (RANSAC/Umeyama) solution, close to the optimum: a small
        # initial barrier parameter halves the iterations (4.1 instead of 9 on the benchmark's
        # frames; 1e-5 took 4.8 and left one of 240 benchmark problems at the iteration limit).
        "ipopt.mu_init": 1e-7,
        "error_on_fail": False,
    }


def solve_ipopt(prog: Program, p: np.ndarray, x0, bounds: Bounds, opts: SolverOptions) -> SolveOutcome:
    """IPOPT on the program's NLP (the solver object is cached on the program)."""
    solver = prog.nlpsol(_ipopt_options(opts))
    t0 = time.perf_counter()
    try:
        sol = solver(x0=x0, p=p, lbx=bounds.lbx, ubx=bounds.ubx, lbg=bounds.lbg, ubg=bounds.ubg)
    except RuntimeError as exc:  # evaluation errors (NaN/inf) surface as RuntimeError in CasADi
        return SolveOutcome(np.asarray(x0, dtype=float), FitStatus.NUMERICAL_FAILURE, f"ipopt: {exc}", 0)
    wall = time.perf_counter() - t0
    stats = solver.stats()
    text = str(stats.get("return_status", "unknown"))
    x = np.asarray(sol["x"]).ravel()
    status = _IPOPT_STATUS.get(text, FitStatus.SUCCESS if stats.get("success") else FitStatus.NUMERICAL_FAILURE)
    if not np.all(np.isfinite(x)):
        status = FitStatus.NUMERICAL_FAILURE
    iterations = int(stats.get("iter_count", 0))
    timings = {f"ipopt.{k}": float(stats.get(f"t_wall_{k}", 0.0)) for k in _IPOPT_CALLBACKS}
    timings["ipopt.internal"] = wall - sum(timings.values())
    timings["ipopt.iterations"] = float(iterations)
    return SolveOutcome(x, status, f"ipopt: {text}", iterations, timings)


_IPOPT_CALLBACKS = ("nlp_f", "nlp_grad_f", "nlp_g", "nlp_jac_g", "nlp_hess_l")


def solve_lsq(prog: Program, p: np.ndarray, x0, bounds: Bounds, opts: SolverOptions) -> SolveOutcome:
    """scipy ``least_squares`` on the program's residuals and exact Jacobian."""
    from scipy.optimize import least_squares

    if prog.num_constraints:
        raise ValueError(
            f"solver: 'lsq' cannot handle the {prog.num_constraints} constraints of terms {prog.key.terms}; use 'ipopt'"
        )
    lbx = np.asarray(bounds.lbx, dtype=float)
    ubx = np.asarray(bounds.ubx, dtype=float)
    x0 = np.asarray(x0, dtype=float)
    bounded = bool(np.any(np.isfinite(lbx)) or np.any(np.isfinite(ubx)))

    def fun(x):
        return np.asarray(prog.residual(x, p)).ravel()

    def jac(x):
        return np.asarray(prog.jacobian(x, p))

    tol = max(float(opts.tol), np.finfo(float).eps)
    # scipy bounds function evaluations, not iterations: with an exact Jacobian an iteration takes
    # at least one, so max_nfev = max_iterations also caps the iterations (reported: njev).
    kwargs = dict(jac=jac, xtol=tol, ftol=tol, gtol=tol, max_nfev=int(opts.max_iterations))
    if bounded:
        # trf needs a strictly feasible start.
        span = np.where(np.isfinite(ubx - lbx), ubx - lbx, 1.0)
        x0 = np.clip(x0, lbx + 1e-9 * span, ubx - 1e-9 * span)
        kwargs.update(method="trf", bounds=(lbx, ubx))
    elif prog.num_residuals >= prog.num_x:
        kwargs.update(method="lm")
    else:
        kwargs.update(method="trf")
    try:
        res = least_squares(fun, x0, **kwargs)
    except (ValueError, np.linalg.LinAlgError) as exc:
        return SolveOutcome(x0, FitStatus.NUMERICAL_FAILURE, f"least_squares: {exc}", 0)
    if res.status > 0 and np.all(np.isfinite(res.x)):
        status = FitStatus.SUCCESS
    elif res.status == 0:
        status = FitStatus.MAX_ITER
    else:
        status = FitStatus.NUMERICAL_FAILURE
    return SolveOutcome(np.asarray(res.x), status, f"least_squares: {res.message}", int(res.njev))


def solve_lm(prog: Program, p: np.ndarray, x0, bounds: Bounds, opts: SolverOptions) -> SolveOutcome:
    """Projected Levenberg-Marquardt on the program's residuals and exact Jacobian.

    For programs without constraints; bounds on ``x`` are kept by projection, with the
    variables held at a bound (the gradient pushing outwards) removed from the step.
    Converges (``SUCCESS``) when the projected gradient, the step or the relative cost decrease
    falls below ``opts.tol`` (relative to the problem's scale). A stall -- no decrease even with
    the damping grown past ``1e12`` while none of these tests holds -- is ``NUMERICAL_FAILURE``,
    with the last iterate.
    """
    if prog.num_constraints:
        raise ValueError(
            f"solver: 'lm' cannot handle the {prog.num_constraints} constraints of terms {prog.key.terms}; use 'ipopt'"
        )
    lbx = np.asarray(bounds.lbx, dtype=float)
    ubx = np.asarray(bounds.ubx, dtype=float)
    x = np.clip(np.asarray(x0, dtype=float), lbx, ubx)
    tol = max(float(opts.tol), np.finfo(float).eps)
    t_start = time.perf_counter()
    spent = {"lm.evaluate": 0.0, "lm.linear": 0.0}

    def evaluate(x):
        t = time.perf_counter()
        r, J = prog.residual_jacobian(x, p)
        out = np.asarray(r).ravel(), np.asarray(J)
        spent["lm.evaluate"] += time.perf_counter() - t
        return out

    def outcome(x, status, message, iterations):
        timings = dict(spent)
        timings["lm.python"] = time.perf_counter() - t_start - spent["lm.evaluate"] - spent["lm.linear"]
        timings["lm.iterations"] = float(iterations)
        return SolveOutcome(x, status, message, iterations, timings)

    r, J = evaluate(x)
    cost = float(r @ r)
    if not np.isfinite(cost):
        return outcome(x, FitStatus.NUMERICAL_FAILURE, "lm: non-finite residual at the start", 0)
    lam, nu = 1e-3, 2.0  # damping (relative to diag(J^T J)) and its growth factor (Nielsen's rule)
    for it in range(1, int(opts.max_iterations) + 1):
        g = J.T @ r
        at_bound = ((x <= lbx) & (g > 0)) | ((x >= ubx) & (g < 0))
        free = ~at_bound
        every = not at_bound.any()  # the usual case: no index copies
        g_free = g if every else g[free]
        if np.max(np.abs(g_free), initial=0.0) <= tol * max(1.0, cost):
            return outcome(x, FitStatus.SUCCESS, f"lm: gradient below tolerance after {it - 1} iterations", it - 1)
        t = time.perf_counter()
        J_free = J if every else J[:, free]
        A = J_free.T @ J_free
        diag = np.diag_indices_from(A)
        D = np.maximum(A[diag], 1e-12)  # the damping's scale, diag(J^T J)
        spent["lm.linear"] += time.perf_counter() - t
        while True:
            t = time.perf_counter()
            damped = A.copy()
            damped[diag] += lam * D
            try:
                solved = np.linalg.solve(damped, -g_free)
            except np.linalg.LinAlgError:
                return outcome(x, FitStatus.NUMERICAL_FAILURE, "lm: singular normal equations", it)
            if every:
                step = solved
            else:
                step = np.zeros_like(x)
                step[free] = solved
            spent["lm.linear"] += time.perf_counter() - t
            x_new = np.minimum(np.maximum(x + step, lbx), ubx)
            r_new, J_new = evaluate(x_new)
            cost_new = float(r_new @ r_new)
            h = x_new - x
            predicted = -(2.0 * (g @ h) + h @ (J.T @ (J @ h)))
            if np.isfinite(cost_new) and cost_new <= cost and predicted > 0:
                rho = (cost - cost_new) / predicted
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                break
            lam *= nu
            nu *= 2.0
            if lam > 1e12:
                gmax = float(np.max(np.abs(g_free), initial=0.0))
                return outcome(
                    x, FitStatus.NUMERICAL_FAILURE,
                    f"lm: stalled after {it} iterations (no decrease; projected gradient {gmax:.3g} above the tolerance)", it,
                )
        small_step = np.linalg.norm(h) <= tol * (tol + np.linalg.norm(x))
        small_decrease = cost - cost_new <= tol * cost
        x, r, J, cost = x_new, r_new, J_new, cost_new
        if small_step or small_decrease:
            return outcome(x, FitStatus.SUCCESS, f"lm: converged after {it} iterations", it)
    return outcome(x, FitStatus.MAX_ITER, f"lm: iteration limit {opts.max_iterations} reached", int(opts.max_iterations))


BACKENDS = {"ipopt": solve_ipopt, "lsq": solve_lsq, "lm": solve_lm}


def solve(backend: str, prog: Program, p, x0, bounds: Bounds, opts: SolverOptions) -> SolveOutcome:
    """Solve ``prog`` with parameters ``p`` from ``x0`` within ``bounds`` by :data:`BACKENDS` ``[backend]``."""
    try:
        fn = BACKENDS[backend]
    except KeyError:
        raise ValueError(f"solver: expected one of {sorted(BACKENDS)}, got {backend!r}") from None
    return fn(prog, p, x0, bounds, opts)
