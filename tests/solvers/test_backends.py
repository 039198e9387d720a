"""The numerical backends on one program: status reporting and the projected LM's bounds."""

import numpy as np
import pytest

from ancsh.solvers import FitConfig, FitStatus, fit
from ancsh.solvers.backends import Bounds, SolverOptions, solve
from ancsh.solvers.program import ProgramKey, get_program
from ancsh.solvers.terms import KinematicStructure


def test_lm_iteration_limit_is_a_status_not_an_exception(fit_case):
    case = fit_case(6, num_parts=3, npcs_noise=0.02)
    r = fit(case.observation, case.correspondences, "exact_reduced", "lm",
            FitConfig(ransac=False, max_iterations=1, tol=1e-14))
    assert r.status == FitStatus.MAX_ITER and not r.ok and "iteration limit" in r.message


def test_lm_keeps_bounds_and_matches_ipopt_on_a_bounded_problem(fit_case):
    # joint limits that exclude the data's states: both backends end on the bound
    case = fit_case(8, num_parts=3, joint_types="revolute", npcs_noise=0.01)
    from dataclasses import replace

    q = case.gt.joint_states
    corr = replace(case.correspondences, joint_limits=np.stack([q + 0.05, q + 0.4], axis=1))
    cfg = FitConfig(ransac=False, tol=1e-12, max_iterations=200)
    a = fit(case.observation, corr, "exact_reduced", "ipopt", cfg)
    b = fit(case.observation, corr, "exact_reduced", "lm", cfg)
    assert a.ok and b.ok, (a.message, b.message)
    assert np.all(b.joint_states >= q + 0.05 - 1e-9)
    assert np.any(np.abs(b.joint_states - (q + 0.05)) < 1e-9)  # held at the bound
    np.testing.assert_allclose(b.joint_states, a.joint_states, atol=1e-6)


def test_lm_and_lsq_refuse_programs_with_constraints():
    structure = KinematicStructure(2, ("revolute",), (0,), (1,))
    prog = get_program(ProgramKey(structure, "maximal", False, ("data", "exact_joint")))
    x0 = np.zeros(prog.num_x)
    p = np.zeros(prog.params.vector().numel())
    for backend in ("lm", "lsq"):
        with pytest.raises(ValueError, match=f"'{backend}' cannot handle"):
            solve(backend, prog, p, x0, Bounds(x0 - np.inf, x0 + np.inf), SolverOptions())
    with pytest.raises(ValueError, match="solver: expected one of"):
        solve("newton", prog, p, x0, Bounds(x0, x0), SolverOptions())


def test_lm_stall_is_a_numerical_failure_not_a_success():
    """A Jacobian pointing uphill: no step decreases the cost, the damping runs away -> a stall."""
    from types import SimpleNamespace

    from ancsh.solvers.backends import solve_lm
    from ancsh.solvers.types import FitStatus

    prog = SimpleNamespace(num_constraints=0, residual_jacobian=lambda x, p: (x.copy(), -np.eye(1)))
    out = solve_lm(prog, None, np.array([1.0]), Bounds(np.array([-np.inf]), np.array([np.inf])), SolverOptions())
    assert out.status == FitStatus.NUMERICAL_FAILURE and "stalled" in out.message


def test_lsq_iterations_count_iterations_not_function_evaluations():
    from types import SimpleNamespace

    from scipy.optimize import least_squares

    from ancsh.solvers.backends import solve_lsq

    A = np.array([[1.0, 2.0], [0.5, -1.0], [3.0, 0.1]])
    b = np.array([1.0, 2.0, -1.0])
    fun = lambda x: np.exp(A @ x) - b - 2.0  # noqa: E731
    jac = lambda x: np.exp(A @ x)[:, None] * A  # noqa: E731
    prog = SimpleNamespace(num_constraints=0, num_residuals=3, num_x=2, residual=lambda x, p: fun(x),
                           jacobian=lambda x, p: jac(x))
    out = solve_lsq(prog, None, np.zeros(2), Bounds(np.full(2, -np.inf), np.full(2, np.inf)), SolverOptions(100, 1e-12))
    ref = least_squares(fun, np.zeros(2), jac=jac, method="lm", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=100)
    assert out.iterations == ref.njev and ref.njev <= ref.nfev


@pytest.mark.parametrize("seed, num_parts, joint_types, tree", [
    (31, 2, "revolute", False), (32, 3, None, False), (33, 4, None, True), (34, 3, "prismatic", False),
    (35, 4, "revolute", True)])
def test_default_lm_agrees_with_ipopt_on_seeded_random_objects(fit_case, seed, num_parts, joint_types, tree):
    """The default exact fit (``exact_reduced`` with ``lm``) ends where IPOPT ends, RANSAC, limits and covariance
    included: NPCS-noisy correspondences of random objects, revolute, prismatic and mixed joints, chains and trees."""
    from ancsh.solvers import FORMULATIONS

    assert FORMULATIONS["exact_reduced"].solvers[0] == "lm"
    case = fit_case(seed, num_parts=num_parts, joint_types=joint_types, tree=tree, npcs_noise=0.02)
    a = fit(case.observation, case.correspondences, "exact_reduced", "ipopt", rng=seed)
    b = fit(case.observation, case.correspondences, rng=seed)
    assert b.solver == "lm" and a.ok and b.ok, (a.message, b.message)
    for Ta, Tb in zip(a.T_cam_npcs, b.T_cam_npcs):
        np.testing.assert_allclose(Tb.rotation, Ta.rotation, atol=1e-6)
        np.testing.assert_allclose(Tb.translation, Ta.translation, atol=1e-6 * case.gt.T_cam_naocs.scale)
        assert Tb.scale == pytest.approx(Ta.scale, rel=1e-6)
    np.testing.assert_allclose(b.joint_states, a.joint_states, atol=1e-6)
    np.testing.assert_array_equal(b.inliers, a.inliers)
    np.testing.assert_allclose(b.uncertainty.rotation_rms_rad, a.uncertainty.rotation_rms_rad, rtol=1e-4)
    assert sum(b.cost_per_term.values()) <= sum(a.cost_per_term.values()) * (1 + 1e-9) + 1e-15
