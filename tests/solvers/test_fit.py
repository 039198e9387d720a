"""End-to-end fits: ground truth recovery, backend agreement, exact constraints, limits, errors."""

from dataclasses import replace

import numpy as np
import pytest

from ancsh.geometry.rotations import geodesic_angle
from ancsh.solvers import FORMULATIONS, Correspondences, FitConfig, FitStatus, Observation, fit
from ancsh.solvers.program import program_build_count

ALL = [(f, s) for f, form in FORMULATIONS.items() for s in form.solvers]


def _pose_errors(result, gt):
    rot = max(geodesic_angle(a.rotation, b.rotation) for a, b in zip(result.T_cam_npcs, gt.T_cam_npcs))
    trans = max(np.linalg.norm(a.translation - b.translation) for a, b in zip(result.T_cam_npcs, gt.T_cam_npcs))
    scale = max(abs(a.scale - b.scale) for a, b in zip(result.T_cam_npcs, gt.T_cam_npcs))
    return rot, trans, scale


@pytest.mark.parametrize("formulation, solver", ALL)
@pytest.mark.parametrize("seed, num_parts, tree", [(0, 3, False), (1, 4, True), (2, 2, False)])
def test_noise_free_correspondences_recover_ground_truth(fit_case, formulation, solver, seed, num_parts, tree):
    """Seeded random models (mixed joint types, chain and tree): every formulation is exact."""
    case = fit_case(seed, num_parts=num_parts, tree=tree)
    config = FitConfig(optimize_scale=formulation != "per_part" and seed == 1)
    r = fit(case.observation, case.correspondences, formulation, solver, config, rng=seed)
    assert r.status == FitStatus.SUCCESS, r.message
    assert max(_pose_errors(r, case.gt)) < 1e-6
    gt = case.gt
    np.testing.assert_allclose(r.joint_states, gt.joint_states, atol=1e-6)
    np.testing.assert_allclose(np.abs(np.sum(r.joint_axes_cam * gt.joint_axes_cam, axis=1)), 1.0, atol=1e-9)
    for k, jt in enumerate(gt.joint_types):
        if jt.value == "revolute":
            np.testing.assert_allclose(r.joint_pivots_cam[k], gt.joint_pivots_cam[k], atol=1e-6)
    for box, gt_box in zip(r.boxes_cam, gt.boxes_cam):
        np.testing.assert_allclose(box.corners(), gt_box.corners(), atol=1e-6)
    assert r.inliers.all() and r.max_constraint_violation < 1e-6 and r.time_s > 0


@pytest.mark.parametrize("formulation", ["soft", "exact_reduced"])
@pytest.mark.parametrize("other", ["lsq", "lm"])
def test_ipopt_and_least_squares_agree_from_the_same_start(fit_case, formulation, other):
    case = fit_case(5, num_parts=3, npcs_noise=0.01)
    cfg = FitConfig(ransac=False, rescore_rounds=0, tol=1e-12, max_iterations=200)
    a = fit(case.observation, case.correspondences, formulation, "ipopt", cfg)
    b = fit(case.observation, case.correspondences, formulation, other, cfg)
    assert a.ok and b.ok, (a.message, b.message)
    for Ta, Tb in zip(a.T_cam_npcs, b.T_cam_npcs):
        assert geodesic_angle(Ta.rotation, Tb.rotation) < 1e-6
        np.testing.assert_allclose(Ta.translation, Tb.translation, atol=1e-7)
    np.testing.assert_allclose(a.joint_states, b.joint_states, atol=1e-6)
    for name in a.cost_per_term:
        np.testing.assert_allclose(a.cost_per_term[name], b.cost_per_term[name], rtol=1e-6, atol=1e-14)


def test_exact_formulations_satisfy_constraints_and_beat_noise(fit_case):
    """With NPCS noise, exact fits hold the joints to solver tolerance; per-part and soft fits do not."""
    case = fit_case(7, num_parts=4, tree=True, npcs_noise=0.02)
    cfg = FitConfig(ransac=False, optimize_scale=True)
    res = {f: fit(case.observation, case.correspondences, f, config=cfg) for f in FORMULATIONS}
    assert all(r.ok for r in res.values()), {f: r.message for f, r in res.items()}
    assert res["exact_maximal"].max_constraint_violation < 1e-7
    assert res["exact_reduced"].max_constraint_violation < 1e-9
    assert res["per_part"].max_constraint_violation > 1e-4
    # Both exact parameterisations (one object scale) solve the same problem: same optimum.
    for Ta, Tb in zip(res["exact_maximal"].T_cam_npcs, res["exact_reduced"].T_cam_npcs):
        assert geodesic_angle(Ta.rotation, Tb.rotation) < 1e-5


def test_joint_limits_hold_when_the_data_violates_them(fit_case):
    case = fit_case(3, num_parts=3, joint_types="revolute")
    gt_states = case.gt.joint_states
    lim = np.stack([gt_states - 0.3, gt_states - 0.1], axis=1)  # the true states lie above the limits
    c = case.correspondences
    corr = replace(c, joint_limits=lim)
    cfg = FitConfig(ransac=False, rescore_rounds=0)
    for formulation, solver in [("exact_maximal", "ipopt"), ("exact_reduced", "ipopt"), ("exact_reduced", "lsq"),
                                ("exact_reduced", "lm")]:
        r = fit(case.observation, corr, formulation, solver, cfg)
        assert r.ok, r.message
        assert np.all(r.joint_states <= lim[:, 1] + 1e-6) and np.all(r.joint_states >= lim[:, 0] - 1e-6)
        assert r.max_constraint_violation < 1e-6
    free = fit(case.observation, corr, "exact_reduced", config=FitConfig(ransac=False, enforce_limits=False))
    np.testing.assert_allclose(free.joint_states, gt_states, atol=1e-6)


def test_ransac_rejects_outliers(fit_case):
    case = fit_case(11, num_parts=3, points_per_part=200)
    c = case.correspondences
    rng = np.random.default_rng(0)
    bad = rng.random(c.num_points) < 0.25
    npcs = c.npcs.copy()
    shift = rng.normal(size=(bad.sum(), 3))
    npcs[bad] += shift / np.linalg.norm(shift, axis=1, keepdims=True) / c.npcs_scale[c.part_labels[bad], None]
    corr = replace(c, npcs=npcs)
    for formulation in ("per_part", "exact_reduced", "exact_maximal"):
        r = fit(case.observation, corr, formulation, rng=1)
        assert r.ok, r.message
        assert max(_pose_errors(r, case.gt)) < 1e-6
        np.testing.assert_array_equal(r.inliers, ~bad)


@pytest.mark.parametrize("objective, gain", [("previous", 0.1), ("npcs_bias", 0.15)])
@pytest.mark.parametrize("kernel", ["huber", "cauchy"])
def test_robust_data_term_downweights_outliers(fit_case, kernel, objective, gain):
    """Without RANSAC, a robust kernel (IRLS on moments) resists gross outliers that pull least squares. With the
    default objective's NPCS biases (``npcs_bias``) the biases take up part of the outliers' pull in both fits (huber:
    0.0077 rad against 0.076 for least squares, 0.0022 against 0.048 without them; cauchy 0.0016 against 0.0014),
    hence its smaller gain; RANSAC, on by default, removes such outliers before the solve."""
    case = fit_case(13, num_parts=3, points_per_part=200, npcs_noise=0.002)
    c = case.correspondences
    rng = np.random.default_rng(3)
    bad = rng.random(c.num_points) < 0.1
    npcs = c.npcs.copy()
    npcs[bad] += rng.normal(0.0, 0.3, size=(bad.sum(), 3))
    corr = replace(c, npcs=npcs)
    # Scales optimised: the Umeyama initial scales are biased by the outliers.
    base = FitConfig.with_objective(objective, ransac=False, rescore_rounds=0, optimize_scale=True)
    plain = fit(case.observation, corr, "exact_reduced", config=base)
    robust = fit(case.observation, corr, "exact_reduced", config=replace(
        base, robust=kernel, robust_scale=0.01, irls_iterations=8))
    assert plain.ok and robust.ok, robust.message
    assert _pose_errors(robust, case.gt)[0] < gain * _pose_errors(plain, case.gt)[0]
    assert "robust_data" in robust.cost_per_term


def test_program_cache_is_reused_across_frames(fit_case):
    """Programs, IPOPT solvers and post-processing are built once per structure, not per frame."""
    cases = [fit_case(s, num_parts=3, joint_types=["revolute", "prismatic"]) for s in (20, 21, 22)]
    configs = [FitConfig(), FitConfig(robust="huber", irls_iterations=2, rescore_rounds=1)]
    for f, s in ALL:
        for cfg in configs:
            fit(cases[0].observation, cases[0].correspondences, f, s, cfg)
    before = program_build_count()
    for case in cases[1:]:
        for f, s in ALL:
            for cfg in configs:
                assert fit(case.observation, case.correspondences, f, s, cfg).ok
    assert program_build_count() == before


def test_too_few_points_nan_and_empty_inputs(fit_case):
    case = fit_case(4, num_parts=3)
    c = case.correspondences
    keep = (c.part_labels != 2) | (np.cumsum(c.part_labels == 2) <= 2)  # part 2 keeps 2 points
    corr = replace(c, part_labels=c.part_labels[keep], npcs=c.npcs[keep], npcs_extents=None, joint_limits=None)
    obs = Observation(case.observation.points_cam[keep])
    for f, s in ALL:
        r = fit(obs, corr, f, s)
        assert r.status == FitStatus.TOO_FEW_POINTS and "part(s) [2]" in r.message
        assert r.joint_states.shape == (2,) and np.all(np.isnan(r.joint_states))
    empty = replace(c, part_labels=np.zeros(0, int), npcs=np.zeros((0, 3)))
    assert fit(Observation(np.zeros((0, 3))), empty).status == FitStatus.TOO_FEW_POINTS
    with pytest.raises(ValueError, match="points_cam"):
        pts = case.observation.points_cam.copy()
        pts[0, 0] = np.nan
        Observation(pts)


def test_degenerate_part_is_a_status(fit_case):
    case = fit_case(4, num_parts=2)
    c = case.correspondences
    npcs = c.npcs.copy()
    npcs[c.part_labels == 1] = npcs[c.part_labels == 1][0]  # all NPCS of part 1 coincide
    corr = replace(c, npcs=npcs)
    for ransac in (True, False):
        r = fit(case.observation, corr, "exact_reduced", config=FitConfig(ransac=ransac))
        assert r.status == FitStatus.DEGENERATE and not r.ok


def test_bad_arguments_raise(fit_case):
    case = fit_case(4, num_parts=2)
    obs, corr = case.observation, case.correspondences
    with pytest.raises(ValueError, match="formulation"):
        fit(obs, corr, "magic")
    with pytest.raises(ValueError, match="solver"):
        fit(obs, corr, "exact_maximal", "lsq")
    with pytest.raises(ValueError, match="solver"):
        fit(obs, corr, "exact_maximal", "lm")
    with pytest.raises(ValueError, match="observation"):
        fit(obs.points_cam, corr)
    with pytest.raises(ValueError, match="do not match"):
        fit(Observation(obs.points_cam[:-1]), corr)
    with pytest.raises(ValueError, match="config"):
        fit(obs, corr, config={"tol": 1e-3})


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(ransac_iterations=0), "ransac_iterations"),
        (dict(inlier_threshold=-0.1), "inlier_threshold"),
        (dict(ransac_confidence=1.5), "ransac_confidence"),
        (dict(robust="tukey"), "robust"),
        (dict(soft_weight=float("nan")), "soft_weight"),
        (dict(ransac="yes"), "ransac"),
    ],
)
def test_fit_config_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        FitConfig(**kwargs)


def test_fit_config_from_dict_rejects_unknown_keys():
    assert FitConfig.from_dict({"soft_weight": 2.0}).soft_weight == 2.0
    with pytest.raises(ValueError, match="unknown key.*lamda"):
        FitConfig.from_dict({"lamda": 2.0})


def test_single_part_without_joints(fit_case):
    case = fit_case(8, num_parts=2)
    c = case.correspondences
    keep = c.part_labels == 0
    corr = Correspondences(c.part_labels[keep], c.npcs[keep], c.npcs_scale[:1], c.npcs_translation[:1])
    obs = Observation(case.observation.points_cam[keep])
    for f, s in ALL:
        r = fit(obs, corr, f, s)
        assert r.ok, r.message
        assert r.joint_states.shape == (0,) and len(r.T_cam_npcs) == 1
        assert r.T_cam_npcs[0].allclose(case.gt.T_cam_npcs[0], atol=1e-6)


@pytest.mark.parametrize("kernel", ["huber", "cauchy"])
def test_robust_fit_is_a_stationary_point_of_the_robust_energy(fit_case, kernel, numeric_derivative):
    """IRLS on moments converges to a minimum of mean_i rho(|p_i - T c_i|^2 / L^2), not of least squares."""
    from ancsh.geometry.robust import robust_loss
    from ancsh.geometry.transforms import Sim3

    case = fit_case(9, num_parts=2, points_per_part=200, npcs_noise=0.005)
    c = case.correspondences
    keep = c.part_labels == 0
    rng = np.random.default_rng(4)
    npcs = c.npcs[keep].copy()
    bad = rng.random(npcs.shape[0]) < 0.15
    npcs[bad] += rng.normal(0.0, 0.2, size=(bad.sum(), 3))
    corr = Correspondences(np.zeros(keep.sum(), int), npcs, c.npcs_scale[:1], c.npcs_translation[:1])
    pts = case.observation.points_cam[keep]
    cfg = FitConfig(ransac=False, optimize_scale=True, scale_estimator="umeyama", robust=kernel, robust_scale=0.02,
                    irls_iterations=60, npcs_bias_weight=0.0)  # the energy below has no NPCS biases
    r = fit(Observation(pts), corr, "exact_reduced", config=cfg)
    assert r.ok, r.message
    T = r.T_cam_npcs[0]
    # Residuals are normalised by the object scale of the initial (Umeyama, all points) fit.
    from ancsh.geometry.umeyama import umeyama

    L = umeyama(npcs, pts).scale / c.npcs_scale[0]

    def energy(delta):
        Td = Sim3.from_rotvec(delta[:3], delta[3:6] * L, np.exp(delta[6])) @ T
        r = np.linalg.norm(pts - Td.apply(npcs), axis=1) / L
        return float(np.mean(robust_loss(r, kernel, 0.02)))

    grad = numeric_derivative(energy, np.zeros(7))
    # Reference: the gradient of the same energy at the plain least-squares solution.
    plain = fit(Observation(pts), corr, "exact_reduced", config=FitConfig(ransac=False, optimize_scale=True, scale_estimator="umeyama"))
    T_ls = plain.T_cam_npcs[0]
    D = T_ls @ T.inverse()
    delta_ls = np.concatenate([D.rotvec(), D.translation / L, [np.log(D.scale)]])
    grad_ls = numeric_derivative(energy, delta_ls)
    assert np.linalg.norm(grad) < 1e-3 * np.linalg.norm(grad_ls)
    assert r.cost_per_term["robust_data"] == pytest.approx(energy(np.zeros(7)), rel=1e-9)



def test_canonical_prior_absorbs_noisy_naocs_parameters(fit_case):
    """Noise on G_t and pivots biases the exact fit; with free canonical offsets (small prior) the
    noise-free points pin every part again, while a very stiff prior reproduces the exact fit."""
    case = fit_case(17, num_parts=3, tree=True, joint_types="revolute")
    c = case.correspondences
    rng = np.random.default_rng(5)
    corr = replace(
        c, npcs_translation=c.npcs_translation + rng.normal(0, 0.02, (3, 3)),
        joint_pivots_naocs=c.joint_pivots_naocs + rng.normal(0, 0.02, (2, 3)), joint_limits=None,
    )
    base = dict(ransac=False, optimize_scale=True)
    for formulation in ("exact_reduced", "exact_maximal"):
        exact = fit(case.observation, corr, formulation, config=FitConfig(naocs_prior_weight=0.0, **base))
        loose = fit(case.observation, corr, formulation, config=FitConfig(naocs_prior_weight=1e-4, **base))
        stiff = fit(case.observation, corr, formulation, config=FitConfig(naocs_prior_weight=1e8, **base))
        assert exact.ok and loose.ok and stiff.ok
        assert max(_pose_errors(exact, case.gt)) > 1e-3
        assert max(_pose_errors(loose, case.gt)) < 1e-4 * max(_pose_errors(exact, case.gt)) / 1e-3
        assert loose.max_constraint_violation < 1e-7  # the joints hold for the adjusted parameters
        for Ta, Tb in zip(stiff.T_cam_npcs, exact.T_cam_npcs):
            assert geodesic_angle(Ta.rotation, Tb.rotation) < 1e-5


def test_paper_config_and_two_tolerances_share_one_program(fit_case):
    case = fit_case(6, num_parts=3)
    paper = FitConfig.paper()
    assert paper.scale_estimator == "umeyama" and paper.naocs_prior_weight == 0.0
    assert FitConfig.paper(max_iterations=7).max_iterations == 7  # overrides win
    with pytest.raises(ValueError, match="unknown key"):
        FitConfig.paper(lambda_=1.0)
    configs = [FitConfig(tol=1e-10), FitConfig(tol=1e-9)]
    for cfg in configs:
        fit(case.observation, case.correspondences, "exact_maximal", config=cfg)
    before = program_build_count()
    for cfg in configs * 2:
        assert fit(case.observation, case.correspondences, "exact_maximal", config=cfg).ok
    assert program_build_count() == before


def test_revolute_states_beyond_pi_inside_wide_limits(fit_case):
    """A revolute joint limited to [-0.2, 5.5] rad at 4 rad is reported as 4 (not 4 - 2 pi) and fitted."""
    from ancsh.model.articulated import ArticulatedModel, Joint
    from ancsh.model.canonical import ancsh_ground_truth
    from ancsh.model.synthetic import random_articulated_model, sample_frame

    rng = np.random.default_rng(23)
    m = random_articulated_model(rng, 2, joint_types="revolute")
    j = m.joints[0]
    joint = Joint(j.name, j.type, j.parent, j.child, j.axis, j.pivot, -0.2, 5.5, 0.0, j.origin)
    model = ArticulatedModel(m.parts, (joint,), name="wide")
    frame = sample_frame(model, rng, q=[4.0])
    gt = ancsh_ground_truth(model, frame.q, frame.T_cam_base, frame.points_cam, frame.part_labels)
    corr = Correspondences.from_ground_truth(gt, joint_limits=[[-0.2, 5.5]])
    for f, s in ALL:
        r = fit(Observation(frame.points_cam), corr, f, s)
        assert r.ok, (f, s, r.message)
        np.testing.assert_allclose(r.joint_states, [4.0], atol=1e-6)
        assert r.max_constraint_violation < 1e-6


@pytest.mark.parametrize("formulation, solver", [(f, s) for f, s in ALL if f != "per_part"])
def test_iteration_limit_is_a_status_with_an_estimate(fit_case, formulation, solver):
    case = fit_case(31, num_parts=3, npcs_noise=0.03)
    r = fit(case.observation, case.correspondences, formulation, solver, FitConfig(max_iterations=1, ransac=False))
    assert r.status == FitStatus.MAX_ITER and not r.ok
    assert len(r.T_cam_npcs) == 3 and np.all(np.isfinite(r.joint_states)) and r.message


def test_exact_maximal_starts_on_the_joints(fit_case):
    """The maximal program's start: per-part poses moved onto the joints (root pose kept, states
    clipped to the limits), so it starts feasible as the reduced one does."""
    import sys

    from ancsh.geometry.rotations import axis_angle_matrix
    from ancsh.geometry.transforms import Sim3
    from ancsh.solvers.fit import FORMULATIONS
    from ancsh.solvers.fit_result import max_violation

    fit_module = sys.modules["ancsh.solvers.fit"]
    case = fit_case(9, num_parts=3, tree=False)
    rng = np.random.default_rng(3)
    gt = case.gt.T_cam_npcs
    # per-part poses: root exact, the others turned by large random rotations (not about their axes)
    poses = [gt[0]] + [Sim3(axis_angle_matrix(rng.normal(size=3), 2.0) @ T.rotation, T.translation, T.scale)
                       for T in gt[1:]]
    limits = np.tile([-0.2, 0.2], (case.gt.num_joints, 1))
    run = fit_module._Fit(case.observation, replace(case.correspondences, joint_limits=limits),
                          FORMULATIONS["exact_maximal"], "ipopt", FitConfig(), rng, 0.0)
    L = float(np.median([T.scale / g for T, g in zip(gt, case.correspondences.npcs_scale)]))
    moved = run._onto_joints(poses, L, limits)
    assert moved[0].allclose(poses[0], atol=1e-12)
    assert [T.scale for T in moved] == [T.scale for T in poses]
    violation = max_violation(run.structure, moved, run.canonical, L, limits)
    assert violation < 1e-9
    assert max_violation(run.structure, poses, run.canonical, L, limits) > 1e-2  # the raw per-part poses are not


def test_reverse_scale_is_unbiased_under_npcs_noise_and_lowers_translation_error(fit_case):
    """Issue 13 item 7: NPCS noise shrinks the Umeyama scale (and half as much the symmetric one);
    the part translation (the NPCS origin) inherits the scale error times the distance from the
    observed points to that origin (far from it in a partial view). The default reverse-regression
    scale is not shrunk, and the exact fit recovers the known translations better
    (docs/results/fit_translation.md)."""
    assert FitConfig().scale_estimator == "reverse"
    errors = {}
    for estimator in ("umeyama", "symmetric", "reverse"):
        scale, trans, rot = [], [], []
        for seed in range(6):
            case = fit_case(40 + seed, num_parts=3, npcs_noise=0.05)
            seen = (case.gt.npcs[:, 0] > 0.0).astype(float)  # a partial view: half of every part
            cfg = FitConfig.previous(ransac=False, scale_estimator=estimator)  # no NPCS scale biases re-estimating it
            r = fit(case.observation, case.correspondences.with_weights(seen), "exact_reduced", "lm", cfg)
            assert r.ok, r.message
            L = case.gt.T_cam_naocs.scale
            for T, T_gt in zip(r.T_cam_npcs, case.gt.T_cam_npcs):
                scale.append(T.scale / T_gt.scale - 1.0)
                trans.append(np.linalg.norm(T.translation - T_gt.translation) / L)
                rot.append(geodesic_angle(T.rotation, T_gt.rotation))
        errors[estimator] = (np.mean(scale), np.mean(trans), np.mean(rot))
    (s_u, t_u, r_u), (s_s, t_s, r_s), (s_r, t_r, r_r) = errors["umeyama"], errors["symmetric"], errors["reverse"]
    assert s_u < s_s < 0 and abs(s_r) < abs(s_s) / 3, errors  # shrinkage: umeyama > symmetric >> reverse
    assert t_r < 0.9 * t_s and t_s < t_u, errors
    assert r_r <= r_s * 1.02, errors  # the rotation does not get worse


@pytest.mark.parametrize("formulation, solver", [("exact_reduced", "lm"), ("exact_reduced", "ipopt"), ("exact_reduced", "lsq"),
                                                 ("exact_maximal", "ipopt")])
def test_npcs_bias_takes_up_a_rotated_npcs_and_keeps_the_origins(fit_case, formulation, solver):
    """One part's NPCS turned about its origin (a per-part orientation error of the provider): the plain exact
    fit moves every part's origin; with NPCS biases the points are explained exactly, every NPCS origin is
    recovered, the joints still hold, and a stiff bias prior gives the plain fit back."""
    from ancsh.geometry.rotations import exp_so3

    case = fit_case(23, num_parts=3, tree=True, joint_types="revolute")
    c = case.correspondences
    turn = exp_so3(np.radians(4.0) * np.array([0.6, -0.48, 0.64]))
    on = c.part_labels == 2
    npcs = c.npcs.copy()
    npcs[on] = npcs[on] @ turn  # = turn^T c: the true NPCS are turn @ (provider's NPCS)
    corr = replace(c, npcs=npcs, joint_limits=None)
    base = dict(ransac=False, scale_estimator="umeyama", naocs_prior_weight=0.0)
    rotations = dict(base, npcs_scale_bias=False)  # the rotation biases only (the default adds scales and stretches)
    plain = fit(case.observation, corr, formulation, solver, config=FitConfig(npcs_bias_weight=0.0, **base))
    biased = fit(case.observation, corr, formulation, solver, config=FitConfig(npcs_bias_weight=1e-6, **rotations))
    stiff = fit(case.observation, corr, formulation, solver, config=FitConfig(npcs_bias_weight=1e8, **rotations))
    assert plain.ok and biased.ok and stiff.ok

    def origin_error(res):
        return max(np.linalg.norm(a.translation - b.translation) for a, b in zip(res.T_cam_npcs, case.gt.T_cam_npcs))

    assert origin_error(plain) > 1e-3
    assert origin_error(biased) < 1e-3 * origin_error(plain)
    assert biased.cost_per_term["data"] < 1e-6 * plain.cost_per_term["data"]
    assert biased.max_constraint_violation < 1e-7
    for Ta, Tb in zip(stiff.T_cam_npcs, plain.T_cam_npcs):
        assert geodesic_angle(Ta.rotation, Tb.rotation) < 1e-4
        assert np.linalg.norm(Ta.translation - Tb.translation) < 1e-4


_STRETCH = np.eye(3) + np.array([[0.04, 0.02, -0.03], [0.02, -0.05, 0.01], [-0.03, 0.01, 0.01]])
# bias -> (the linear error of part 2's NPCS about its origin besides a turn and a 6 % shrink, the biases without it,
#          the option with it, the refusal of the option alone)
_BIAS_CASES = {
    "scale": (np.eye(3), {"npcs_scale_bias": False}, {"npcs_scale_bias": True, "npcs_stretch_bias": False},
              ({"npcs_bias_weight": 0.0, "npcs_scale_bias": True}, "npcs_scale_bias: needs the NPCS biases")),
    "stretch": (_STRETCH, {"npcs_scale_bias": True, "npcs_stretch_bias": False}, {"npcs_scale_bias": True, "npcs_stretch_bias": True},
                ({"npcs_bias_weight": 0.01, "npcs_scale_bias": False, "npcs_stretch_bias": True},
                 "npcs_stretch_bias: needs the NPCS scale biases")),
}


@pytest.mark.parametrize("solver", ["lm", "ipopt", "lsq"])
@pytest.mark.parametrize("bias", sorted(_BIAS_CASES))
def test_npcs_scale_and_stretch_biases_take_up_a_distorted_npcs_and_keep_the_origins(fit_case, solver, bias):
    """One part's NPCS shrunk and turned (``scale``), and also stretched (``stretch``: any linear map near the identity),
    about its origin: the biases without the option leave its origin off (the scale or stretch error moves it); with it
    every NPCS origin is recovered, the data fit exactly and the joints hold; the option alone is refused.
    (Reduced coordinates, whose part scales are ``sigma G_s``: the maximal ones keep each part's estimated scale,
    which already holds a scale error.)"""
    from ancsh.geometry.rotations import exp_so3

    linear, without, option, (refused, says) = _BIAS_CASES[bias]
    case = fit_case(29, num_parts=3, tree=True, joint_types="revolute")
    c = case.correspondences
    turn = exp_so3(np.radians(3.0) * np.array([0.0, 0.6, 0.8]))
    on = c.part_labels == 2
    npcs = c.npcs.copy()
    npcs[on] = (npcs[on] @ (turn @ linear)) / 1.06  # c -> (turn linear)^T c / 1.06 about the NPCS origin
    corr = replace(c, npcs=npcs, joint_limits=None)
    base = dict(ransac=False, scale_estimator="umeyama", naocs_prior_weight=0.0, npcs_bias_weight=1e-6, **without)
    before = fit(case.observation, corr, "exact_reduced", solver, config=FitConfig(**base))
    after = fit(case.observation, corr, "exact_reduced", solver, config=FitConfig(**{**base, **option}))
    assert before.ok and after.ok

    def origin_error(res):
        return max(np.linalg.norm(a.translation - b.translation) for a, b in zip(res.T_cam_npcs, case.gt.T_cam_npcs))

    assert origin_error(before) > 1e-4, origin_error(before)
    assert origin_error(after) < 1e-2 * origin_error(before), (origin_error(after), origin_error(before))
    assert after.cost_per_term["data"] < 1e-6 * before.cost_per_term["data"]
    assert after.max_constraint_violation < 1e-7
    with pytest.raises(ValueError, match=says):
        FitConfig(**refused)


def test_unit_diagonal_boxes_undo_the_inflation_by_npcs_noise(fit_case):
    """Without NPCS extents from the provider the boxes come from the inliers' NPCS: noise and the points' reach put
    them off the unit diagonal every NPCS box has; ``box_extents="unit_diagonal"`` scales them onto it, closer to
    the true boxes; the poses are the same fit."""
    from ancsh.geometry.boxes import OrientedBox
    from ancsh.geometry.metrics import box_iou

    case = fit_case(31, num_parts=3, npcs_noise=0.02)
    true_extents = case.correspondences.npcs_extents
    assert true_extents is not None
    corr = replace(case.correspondences, npcs_extents=None)
    measured = fit(case.observation, corr, config=FitConfig(ransac=False))
    scaled = fit(case.observation, corr, config=FitConfig(ransac=False, box_extents="unit_diagonal"))
    with pytest.raises(ValueError, match="box_extents"):
        FitConfig(box_extents="min")
    for j, (a, b, T, T_gt) in enumerate(zip(measured.boxes_cam, scaled.boxes_cam, scaled.T_cam_npcs, case.gt.T_cam_npcs)):
        assert np.allclose(T.rotation, measured.T_cam_npcs[j].rotation) and np.allclose(T.translation, measured.T_cam_npcs[j].translation)
        assert np.linalg.norm(b.extents / T.scale) == pytest.approx(1.0)
        truth = OrientedBox(T_gt.translation, T_gt.rotation, T_gt.scale * np.asarray(true_extents[j]))
        assert abs(np.linalg.norm(a.extents / T.scale) - 1.0) > 0.01  # off the unit diagonal as measured
        assert box_iou(b, truth) > box_iou(a, truth)


@pytest.mark.parametrize("estimator", ["symmetric", "reverse"])
def test_rescale_of_all_parts_at_once_matches_each_part_on_its_own(fit_case, estimator):
    """The initial scales of every part in one pass (``_Fit._rescale``) are the one-part formulas: the RMS spread
    ratio, or the reverse regression ``var(p) / tr(R^T cov(p, c))`` capped at twice it; the translation re-centred."""
    import sys

    from ancsh.geometry.rotations import axis_angle_matrix
    from ancsh.geometry.transforms import Sim3

    fit_module = sys.modules["ancsh.solvers.fit"]
    case = fit_case(5, num_parts=3, npcs_noise=0.03)
    corr = case.correspondences
    rng = np.random.default_rng(4)
    corr = corr.with_weights(rng.uniform(0.2, 1.0, corr.num_points))
    inliers = rng.random(corr.num_points) < 0.8
    run = fit_module._Fit(case.observation, corr, FORMULATIONS["exact_reduced"], "lm",
                          FitConfig(scale_estimator=estimator), rng, 0.0)
    poses = [Sim3(axis_angle_matrix(rng.normal(size=3), 0.1) @ T.rotation, T.translation, T.scale)
             for T in case.gt.T_cam_npcs]
    for j, (T, got) in enumerate(zip(poses, run._rescale(poses, inliers))):
        sel = inliers & (corr.part_labels == j)
        w = corr.weights[sel] / corr.weights[sel].sum()
        p, c = case.observation.points_cam[sel], corr.npcs[sel]
        pbar, cbar = w @ p, w @ c
        var_p, var_c = w @ np.sum((p - pbar) ** 2, axis=1), w @ np.sum((c - cbar) ** 2, axis=1)
        s = np.sqrt(var_p / var_c)
        if estimator == "reverse":
            cov = np.trace(T.rotation.T @ (((p - pbar) * w[:, None]).T @ (c - cbar)))
            s = var_p / max(cov, 0.5 * np.sqrt(var_p * var_c))
        assert got.scale == pytest.approx(s, rel=1e-12)
        np.testing.assert_allclose(got.rotation, T.rotation)
        np.testing.assert_allclose(got.translation, pbar - s * T.rotation @ cbar, atol=1e-12)
