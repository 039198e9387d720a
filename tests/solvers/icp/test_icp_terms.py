"""The point-to-plane term: equal to the per-point sum, exact Jacobian."""

import casadi as ca
import numpy as np

from ancsh.geometry.rotations import exp_so3
from ancsh.solvers.terms import PointToPlaneTerm, plane_moments
from ancsh.solvers.terms import TERMS, Context, KinematicStructure, Params, PoseExpr, exp_so3_sx

L = 1.7


def _problem(seed=0, n=40):
    """One part with pose (rotation vector, translation, scale) = x (7,), random matches."""
    rng = np.random.default_rng(seed)
    params = Params()
    params.get("L")
    x = ca.SX.sym("x", 7)
    ctx = Context(KinematicStructure(1, (), (), ()), params, [PoseExpr(exp_so3_sx(x[:3]), x[3:6], x[6])])
    r = PointToPlaneTerm().expression(ctx)
    p, c = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    m = rng.normal(size=(n, 3))
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    w = rng.random(n)
    pbar = w @ p / w.sum()
    pv = params.pack({"L": L, "Lp0": plane_moments(p, c, m, w, pbar), "pbar0": pbar})
    residual = ca.Function("r", [x, params.vector()], [r])
    jacobian = ca.Function("J", [x, params.vector()], [ca.jacobian(r, x)])
    return residual, jacobian, pv, (p, c, m, w), rng


def test_point_to_plane_is_registered():
    assert TERMS["point_to_plane"] is PointToPlaneTerm


def test_point_to_plane_energy_equals_the_weighted_sum_over_points():
    residual, _, pv, (p, c, m, w), rng = _problem()
    for _ in range(3):
        xv = rng.normal(size=7)
        R, t, s = exp_so3(xv[:3]), xv[3:6], xv[6]
        direct = np.sum(w / w.sum() * np.einsum("ij,ij->i", m @ R.T, p - (s * c @ R.T + t)) ** 2) / L**2
        assert np.isclose(float(np.sum(np.asarray(residual(xv, pv)) ** 2)), direct, rtol=1e-10)


def test_point_to_plane_jacobian_matches_central_differences(numeric_derivative):
    residual, jacobian, pv, _, rng = _problem(1)
    xv = rng.normal(size=7)
    J = np.asarray(jacobian(xv, pv))
    num = numeric_derivative(lambda v: np.asarray(residual(v, pv)).ravel(), xv)
    np.testing.assert_allclose(J, num, atol=1e-6 * max(1.0, np.abs(J).max()))


def test_zero_weights_give_zero_moments():
    np.testing.assert_array_equal(plane_moments(np.ones((2, 3)), np.ones((2, 3)), np.ones((2, 3)), np.zeros(2), np.zeros(3)), 0.0)
