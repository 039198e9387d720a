"""Energy terms: exact Jacobians (vs central differences), moment form, rotation map, kernels."""

import zlib

import casadi as ca
import numpy as np
import pytest

from ancsh.geometry.rotations import exp_so3, random_rotation
from ancsh.geometry.transforms import Sim3
from ancsh.solvers.program import Program, ProgramKey
from ancsh.solvers.terms import (
    TERMS, CanonicalParameters, DataTerm, KinematicStructure, ProgramInputs, ProgramStart, exp_so3_sx,
    part_moments,
)

# Both joint types, a branching tree: 0 -> 1 (revolute), 0 -> 2 (prismatic), 2 -> 3 (revolute).
STRUCTURE = KinematicStructure(4, ("revolute", "prismatic", "revolute"), (0, 0, 2), (1, 2, 3))


def _random_values(prog: Program, rng) -> dict:
    values = {}
    for name, (rows, cols) in prog.params._shapes.items():
        if name.startswith("R0"):
            values[name] = random_rotation(rng)
        elif name[0] in "uab" and rows == 3:
            v = rng.normal(size=3)
            values[name] = v / np.linalg.norm(v)
        elif rows * cols == 1:
            values[name] = rng.uniform(0.5, 1.5)
        else:
            values[name] = rng.normal(size=(rows, cols)) if cols > 1 else rng.normal(size=rows)
    return values


@pytest.mark.parametrize("free_canonical", [False, True])
@pytest.mark.parametrize("parameterisation", ["maximal", "reduced"])
@pytest.mark.parametrize("name", sorted(TERMS))
def test_term_jacobian_matches_central_differences(name, parameterisation, free_canonical, numeric_derivative):
    """Also with respect to the canonical-parameter offsets (``free_canonical``)."""
    if name == "naocs_prior" and not free_canonical:
        with pytest.raises(ValueError, match="canonical parameters are fixed"):
            Program(ProgramKey(STRUCTURE, parameterisation, True, (name,)))
        return
    if name == "npcs_bias_prior":  # its variables: test_npcs_bias_jacobians_match_central_differences
        with pytest.raises(ValueError, match="no NPCS-bias variables"):
            Program(ProgramKey(STRUCTURE, parameterisation, True, (name,)))
        return
    rng = np.random.default_rng(zlib.crc32(f"{name}{parameterisation}{free_canonical}".encode()))
    terms = (name,) + (("naocs_prior",) if free_canonical and name != "naocs_prior" else ())
    prog = Program(ProgramKey(STRUCTURE, parameterisation, True, terms, free_canonical))
    p = prog.params.pack(_random_values(prog, rng))
    x = rng.normal(scale=0.3, size=prog.num_x)
    if TERMS[name].kind == "cost":
        f, J = prog.residual, prog.jacobian
    else:
        f, J = prog.constraints, prog.constraint_jacobian
    value = lambda x_: np.asarray(f(x_, p)).ravel()  # noqa: E731
    analytic = np.asarray(J(x, p))
    numeric = numeric_derivative(value, x)
    assert analytic.shape == numeric.shape and analytic.size > 0
    np.testing.assert_allclose(analytic, numeric, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("parameterisation", ["maximal", "reduced"])
@pytest.mark.parametrize("name, bias_dims", [(n, d) for n in ("data", "point_to_plane", "npcs_bias_prior")
                                             for d in (3, 4, 9) if (n, d) != ("point_to_plane", 9)])
def test_npcs_bias_jacobians_match_central_differences(name, parameterisation, bias_dims, numeric_derivative):
    """The data terms through NPCS-bias rotations (and scales, and stretches), and the bias prior, differentiated in
    every variable. (Point-to-plane needs rotations: it refuses stretch biases, tested below.)"""
    rng = np.random.default_rng(zlib.crc32(f"bias{name}{parameterisation}{bias_dims}".encode()))
    terms = tuple(dict.fromkeys((name, "naocs_prior", "npcs_bias_prior")))
    prog = Program(ProgramKey(STRUCTURE, parameterisation, True, terms, free_canonical=True, npcs_bias=True,
                              npcs_scale_bias=bias_dims > 3, npcs_stretch_bias=bias_dims == 9))
    p = prog.params.pack(_random_values(prog, rng))
    x = rng.normal(scale=0.3, size=prog.num_x)
    value = lambda x_: np.asarray(prog.residual(x_, p)).ravel()  # noqa: E731
    np.testing.assert_allclose(np.asarray(prog.jacobian(x, p)), numeric_derivative(value, x), rtol=1e-6, atol=1e-7)
    bias = prog.unpack(x, p).npcs_bias
    assert bias.shape == (STRUCTURE.num_parts, bias_dims)
    np.testing.assert_array_equal(prog.initial_x(npcs_bias=bias)[-bias.size:], bias.ravel())
    with pytest.raises(ValueError, match="npcs_bias: expected"):
        prog.initial_x(npcs_bias=np.zeros((STRUCTURE.num_parts, 3 if bias_dims > 3 else 4)))


def test_the_stretch_bias_is_a_symmetric_traceless_map_and_zero_stretch_is_the_scale_bias():
    """The stretch is symmetric and traceless (:func:`stretch_sx`); with stretch biases the point-to-point data
    residual is the scale-bias program's at zero stretch and differs from it elsewhere (that it maps the NPCS by
    ``I + S``: ``test_fit.py::test_npcs_scale_and_stretch_biases_take_up_a_distorted_npcs_and_keep_the_origins``); the point-to-plane term
    and a stretch without scale biases are refused."""
    import casadi as ca

    from ancsh.solvers.terms import stretch_sx

    e = np.array([0.3, -0.1, 0.2, 0.05, -0.4])
    S = np.asarray(ca.Function("S", [sym := ca.SX.sym("e", 5)], [stretch_sx(sym)])(e))
    np.testing.assert_allclose(S, S.T)
    assert abs(np.trace(S)) < 1e-15 and np.count_nonzero(S) == 9
    rng = np.random.default_rng(6)
    scaled = Program(ProgramKey(STRUCTURE, "maximal", True, ("data", "npcs_bias_prior"), npcs_bias=True,
                                npcs_scale_bias=True))
    stretched = Program(ProgramKey(STRUCTURE, "maximal", True, ("data", "npcs_bias_prior"), npcs_bias=True,
                                   npcs_scale_bias=True, npcs_stretch_bias=True))
    values = _random_values(stretched, rng)
    M = STRUCTURE.num_parts
    x = rng.normal(scale=0.3, size=stretched.num_x)
    bias = x[-9 * M:].reshape(M, 9)
    x4 = np.concatenate([x[:-9 * M], bias[:, :4].ravel()])
    data_rows = slice(0, 13 * M)
    x_zero = x.copy()
    x_zero[-9 * M:] = np.hstack([bias[:, :4], np.zeros((M, 5))]).ravel()
    r_zero = np.asarray(stretched.residual(x_zero, stretched.params.pack(values))).ravel()[data_rows]
    np.testing.assert_allclose(r_zero, np.asarray(scaled.residual(x4, scaled.params.pack(values))).ravel()[data_rows],
                               rtol=1e-12, atol=1e-12)
    r = np.asarray(stretched.residual(x, stretched.params.pack(values))).ravel()[data_rows]
    assert not np.allclose(r, r_zero)
    with pytest.raises(ValueError, match="'point_to_plane' term needs rotations"):
        Program(ProgramKey(STRUCTURE, "maximal", True, ("point_to_plane", "npcs_bias_prior"), npcs_bias=True,
                           npcs_scale_bias=True, npcs_stretch_bias=True))
    with pytest.raises(ValueError, match="npcs_stretch_bias: needs the NPCS scale biases"):
        ProgramKey(STRUCTURE, "maximal", True, ("data", "npcs_bias_prior"), npcs_bias=True, npcs_stretch_bias=True)


def test_the_scale_bias_weighs_the_data_term_as_the_reverse_regression():
    """With a log-scale bias beta the point-to-point residual is the plain one through ``s exp(beta)``, times
    ``exp(-beta)``; at beta = 0 it is the plain residual; the scale bias needs the NPCS biases."""
    rng = np.random.default_rng(5)
    plain = Program(ProgramKey(STRUCTURE, "maximal", True, ("data", "npcs_bias_prior"), npcs_bias=True))
    scaled = Program(ProgramKey(STRUCTURE, "maximal", True, ("data", "npcs_bias_prior"), npcs_bias=True,
                                npcs_scale_bias=True))
    values = _random_values(scaled, rng)
    p0, p1 = plain.params.pack(values), scaled.params.pack(values)
    M = STRUCTURE.num_parts
    x = rng.normal(scale=0.3, size=scaled.num_x)
    bias = x[-4 * M:].reshape(M, 4)
    x0 = np.concatenate([x[:-4 * M], bias[:, :3].ravel()])
    data_rows = slice(0, 13 * M)
    r1 = np.asarray(scaled.residual(x, p1)).ravel()[data_rows]
    x_zero = x.copy()
    x_zero[-4 * M:] = np.hstack([bias[:, :3], np.zeros((M, 1))]).ravel()
    np.testing.assert_allclose(np.asarray(scaled.residual(x_zero, p1)).ravel()[data_rows],
                               np.asarray(plain.residual(x0, p0)).ravel()[data_rows], rtol=1e-12, atol=1e-12)
    assert not np.allclose(r1, np.asarray(plain.residual(x0, p0)).ravel()[data_rows])
    with pytest.raises(ValueError, match="npcs_scale_bias: needs the NPCS-bias variables"):
        ProgramKey(STRUCTURE, "maximal", True, ("data",), npcs_scale_bias=True)


def test_npcs_bias_needs_its_prior_and_zero_bias_is_the_plain_data_term():
    with pytest.raises(ValueError, match="need the 'npcs_bias_prior' term"):
        Program(ProgramKey(STRUCTURE, "reduced", False, ("data",), npcs_bias=True))
    with pytest.raises(ValueError, match="no NPCS-bias variables"):
        Program(ProgramKey(STRUCTURE, "reduced", False, ("data",))).initial_x(npcs_bias=np.zeros((4, 3)))
    rng = np.random.default_rng(3)
    plain = Program(ProgramKey(STRUCTURE, "reduced", False, ("data",)))
    biased = Program(ProgramKey(STRUCTURE, "reduced", False, ("data", "npcs_bias_prior"), npcs_bias=True))
    values = _random_values(biased, rng)
    x = rng.normal(scale=0.3, size=plain.num_x)
    r_plain = np.asarray(plain.residual(x, plain.params.pack({k: values[k] for k in plain.params.names}))).ravel()
    r_biased = np.asarray(biased.residual(np.concatenate([x, np.zeros(12)]), biased.params.pack(values))).ravel()
    np.testing.assert_allclose(r_biased[: r_plain.size], r_plain, rtol=1e-12)
    np.testing.assert_array_equal(r_biased[r_plain.size:], 0.0)


@pytest.mark.parametrize("planar", [False, True])
def test_data_term_moments_reproduce_the_point_energy(planar):
    """|r|^2 of the moment form equals mean_i w_i |p_i - (s R c_i + t)|^2 / L^2, also for planar NPCS."""
    rng = np.random.default_rng(1)
    st = KinematicStructure(1, (), (), ())
    prog = Program(ProgramKey(st, "maximal", True, ("data",)))
    c = rng.normal(size=(50, 3))
    if planar:
        c[:, 2] = 0.3
    p_cam = rng.normal(size=(50, 3)) + 2.0
    w = rng.uniform(0.1, 2.0, size=50)
    L = 0.7
    canonical = CanonicalParameters(np.ones(1), np.zeros((1, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    start = ProgramStart(T_cam_npcs=(Sim3(random_rotation(rng), rng.normal(size=3), 0.4),))
    p = prog.pack(ProgramInputs(L, canonical, start, (part_moments(p_cam, c, w, L),)))
    x = rng.normal(scale=0.2, size=prog.num_x)
    T = prog.unpack(x, p).T_cam_npcs[0]
    R, t, s = T.rotation, T.translation, T.scale
    expected = np.sum(w * np.sum((p_cam - (s * c @ R.T + t)) ** 2, axis=1)) / w.sum() / L**2
    r = np.asarray(prog.residual(x, p)).ravel()
    assert r.size == 13
    np.testing.assert_allclose(r @ r, expected, rtol=1e-9)


@pytest.mark.parametrize("w", [np.zeros(3), [1e-6, -2e-6, 5e-7], [0.3, -1.2, 0.5], [np.pi - 1e-3, 0, 0]])
def test_symbolic_exp_matches_numpy_and_has_finite_derivatives(w, numeric_derivative):
    ws = ca.SX.sym("w", 3)
    R = exp_so3_sx(ws)
    f = ca.Function("f", [ws], [R, ca.jacobian(ca.vec(R), ws)])
    val, jac = f(np.asarray(w, dtype=float))
    np.testing.assert_allclose(np.asarray(val), exp_so3(np.asarray(w, dtype=float)), atol=1e-12)
    jac = np.asarray(jac)
    assert np.all(np.isfinite(jac))
    numeric = numeric_derivative(lambda v: np.asarray(f(v)[0]).ravel(order="F"), np.asarray(w, dtype=float))
    np.testing.assert_allclose(jac, numeric, atol=1e-7)


def test_term_registry_rejects_duplicates():
    from ancsh.solvers.terms import register_term

    with pytest.raises(ValueError, match="already registered"):
        register_term(type("Again", (DataTerm,), {"name": "data"}))
    with pytest.raises(ValueError, match="unknown term"):
        Program(ProgramKey(STRUCTURE, "maximal", False, ("no_such_term",)))


def _two_part_frame(rng, theta: float, T_cam_naocs: Sim3):
    """Noise-free points of a two-part revolute object (NPCS = NAOCS, pivot off the origin) at ``theta``."""
    from ancsh.geometry.rotations import axis_angle_matrix

    u, q = np.array([0.0, 0.0, 1.0]), np.array([0.3, 0.1, 0.0])
    c = [rng.uniform(-0.5, 0.5, size=(60, 3)) for _ in range(2)]
    g1 = c[1] @ axis_angle_matrix(u, theta).T + q - axis_angle_matrix(u, theta) @ q
    points = [T_cam_naocs.apply(c[0]), T_cam_naocs.apply(g1)]
    canonical = CanonicalParameters(np.ones(2), np.zeros((2, 3)), u[None], q[None], np.zeros(1))
    return c, points, canonical


@pytest.mark.parametrize("weight", [0.0, 1e-3, 1e4])
def test_temporal_prior_pulls_the_reduced_solution_toward_the_previous_one(weight):
    """Scenario: noise-free points of a two-part revolute object at state 0.6 and a previous solution at
    state 0.2 with another pose: weight 0 recovers the truth (~1e-8), a small weight lands between the two,
    a large one on the previous solution."""
    from ancsh.solvers.backends import Bounds, SolverOptions, solve
    from ancsh.solvers.terms import PreviousSolution, TemporalPriorTerm

    rng = np.random.default_rng(5)
    truth = Sim3(random_rotation(rng), np.array([0.1, -0.2, 1.5]), 0.4)
    c, points, canonical = _two_part_frame(rng, 0.6, truth)
    L = truth.scale
    previous = PreviousSolution(Sim3(truth.rotation @ exp_so3(np.array([0.0, 0.1, 0.0])), truth.translation + 0.02, 0.42),
                                np.array([0.2]), weight)
    st = KinematicStructure(2, ("revolute",), (0,), (1,))
    prog = Program(ProgramKey(st, "reduced", True, (DataTerm, TemporalPriorTerm)))
    moments = tuple(part_moments(pts, cj, np.ones(len(cj)), L) for pts, cj in zip(points, c))
    p = prog.pack(ProgramInputs(L, canonical, ProgramStart(T_cam_naocs=previous.T_cam_naocs), moments, previous=previous))
    out = solve("lsq", prog, p, prog.initial_x(previous.joint_states), Bounds.of(prog), SolverOptions(max_iterations=200))
    sol = prog.unpack(out.x, p)
    state, T = float(sol.joint_states[0]), sol.T_cam_naocs
    if weight == 0.0:
        assert state == pytest.approx(0.6, abs=1e-8)
        np.testing.assert_allclose(T.translation, truth.translation, atol=1e-8)
    elif weight < 1:
        assert 0.2 < state < 0.6 - 1e-4
        assert np.linalg.norm(T.translation - truth.translation) > 1e-6
    else:
        assert state == pytest.approx(0.2, abs=1e-3)
        np.testing.assert_allclose(T.translation, previous.T_cam_naocs.translation, atol=1e-3 * L)
        assert T.scale == pytest.approx(previous.T_cam_naocs.scale, abs=1e-3 * L)


def test_temporal_prior_names_what_it_lacks():
    from ancsh.solvers.terms import PreviousSolution, TemporalPriorTerm

    st = KinematicStructure(2, ("revolute",), (0,), (1,))
    prog = Program(ProgramKey(st, "reduced", True, (TemporalPriorTerm,)))
    canonical = CanonicalParameters(np.ones(2), np.zeros((2, 3)), np.array([[0.0, 0.0, 1.0]]), np.zeros((1, 3)), np.zeros(1))
    start = ProgramStart(T_cam_naocs=Sim3.identity())
    with pytest.raises(ValueError, match="inputs.previous: required by the 'temporal_prior' term"):
        prog.pack(ProgramInputs(1.0, canonical, start))
    with pytest.raises(ValueError, match="joint_states: expected 1 states"):
        prog.pack(ProgramInputs(1.0, canonical, start, previous=PreviousSolution(Sim3.identity(), np.zeros(2), 1.0)))
    with pytest.raises(ValueError, match="weight"):
        PreviousSolution(Sim3.identity(), np.zeros(1), -1.0)


def test_constant_velocity_prediction_continues_a_constant_motion():
    """Scenario: object poses and joint states at three times of a constant screw motion and a constant joint
    velocity: the prediction from the first two reproduces the third (to 1e-12); damping 0 keeps the last."""
    from ancsh.solvers.terms import PreviousSolution

    rng = np.random.default_rng(3)
    R0, w, v = random_rotation(rng), np.array([0.02, -0.05, 0.03]), np.array([0.01, 0.0, -0.02])
    poses = [Sim3(exp_so3(i * w) @ R0, np.array([0.1, 0.2, 1.5]) + i * v, 0.4) for i in range(3)]
    states = [np.array([0.3 + 0.05 * i, -0.1 * i]) for i in range(3)]
    a, b = (PreviousSolution(poses[i], states[i], 0.5, 0.2) for i in (1, 0))
    pred = PreviousSolution.constant_velocity(a, b)
    np.testing.assert_allclose(pred.T_cam_naocs.rotation, poses[2].rotation, atol=1e-12)
    np.testing.assert_allclose(pred.T_cam_naocs.translation, poses[2].translation, atol=1e-12)
    np.testing.assert_allclose(pred.joint_states, states[2], atol=1e-12)
    assert (pred.weight, pred.state_weight) == (0.5, 0.2)
    assert PreviousSolution.constant_velocity(a, b, damping=0.0) is a
    assert PreviousSolution.constant_velocity(a, None) is a
    with pytest.raises(ValueError, match="damping"):
        PreviousSolution.constant_velocity(a, b, damping=2.0)


def test_parts_moments_equal_part_moments_one_part_at_a_time():
    """The batched moments (every part in one pass, zero weights leaving points out) are each part's own."""
    from ancsh.solvers.terms import parts_moments

    rng = np.random.default_rng(11)
    n = 300
    labels = rng.integers(0, 3, n)
    c = rng.uniform(-0.5, 0.5, (n, 3))
    p = c @ rng.normal(size=(3, 3)) + rng.normal(scale=0.01, size=(n, 3))
    w = rng.random(n) * (rng.random(n) > 0.2)
    batched = parts_moments(p, c, labels, w, 3, 0.8)
    for j, m in enumerate(batched):
        sel = (labels == j) & (w > 0)
        ref = part_moments(p[sel], c[sel], w[sel], 0.8)
        for a, b in ((m.Lm @ m.Lm.T, ref.Lm @ ref.Lm.T), (m.B @ m.Lm.T, ref.B @ ref.Lm.T), (m.cbar, ref.cbar),
                     (m.pbar, ref.pbar), (m.sqrt_c0, ref.sqrt_c0)):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-14)
    # one part's moments by definition: M = mean(w x x^T), C = mean(w x p'^T), x = [c - cbar, 1]
    sel = labels == 1
    wn = w[sel] / w[sel].sum()
    x = np.c_[c[sel] - wn @ c[sel], np.ones(sel.sum())]
    pc = p[sel] - wn @ p[sel]
    m = batched[1]
    np.testing.assert_allclose(m.Lm @ m.Lm.T, (x * wn[:, None]).T @ x, atol=1e-14)
    np.testing.assert_allclose(m.B @ m.Lm.T, pc.T @ (x * wn[:, None]), atol=1e-14)
    np.testing.assert_allclose(m.sqrt_c0**2 * 0.8**2 + np.sum(m.B * m.B), wn @ np.sum(pc * pc, axis=1), rtol=1e-12)
