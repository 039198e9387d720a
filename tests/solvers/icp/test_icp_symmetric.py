"""The symmetric starts and the status at the sensor noise of articulated ICP (``ArticulatedIcpConfig.instance``)."""

import numpy as np
import pytest

from ancsh.data.procedural import make_object
from ancsh.data.render import Intrinsics, ModelRenderer, backproject, object_extent
from ancsh.geometry.metrics import AD_THRESHOLD, ad_error
from ancsh.geometry.rotations import exp_so3
from ancsh.geometry.transforms import Sim3
from ancsh.model.articulated import sample_surface
from ancsh.solvers.icp.articulated import ArticulatedIcpConfig, articulated_icp, symmetric_hypotheses
from ancsh.solvers.icp.depth import fit_depth
from ancsh.solvers.icp.scoring import DepthSupport, paired_z, sensor_noise
from ancsh.solvers.icp.template import ArticulatedPose, ModelSurface
from ancsh.studies.cad.measure import _orbit_pose
from ancsh.solvers.types import FitStatus

INTR = Intrinsics.kinect(320, 240)


def _view(model, q, azimuth_deg=30.0, elevation_deg=35.0):
    center, diag = object_extent(model, q)
    T = _orbit_pose(model, q, center, diag, np.radians(azimuth_deg), np.radians(elevation_deg), 1.8)
    frame = ModelRenderer(model).render(q, T, INTR)
    return T, backproject(frame.depth, INTR, frame.depth > 0)


def _swapped(model, T, q):
    """The laptop's base where its display is and vice versa: a half turn about the line through the hinge that
    bisects the two parts."""
    axis_b, pivot_b = model.joint_line_in_base(0, q)
    a, o = T.apply_direction(axis_b), T.apply(pivot_b)
    parts = [T @ P for P in model.forward_kinematics(q)]
    dirs = []
    for j in model.joint_parts(0):
        u = parts[j].apply(model.parts[j].vertices).mean(axis=0) - o
        u -= a * (a @ u)
        dirs.append(u / np.linalg.norm(u))
    b = (dirs[0] + dirs[1]) / np.linalg.norm(dirs[0] + dirs[1])
    R = exp_so3(np.pi * b)
    return ArticulatedPose(Sim3(R @ T.rotation, R @ (T.translation - o) + o), q)


def _ad_ratios(model, est_parts, T, q, rng=0):
    rng = np.random.default_rng(rng)
    truth = [T @ P for P in model.forward_kinematics(q)]
    out = []
    for part, Te, Tg in zip(model.parts, est_parts, truth):
        p = sample_surface(part.mesh, 300, rng)
        diameter = np.max(np.linalg.norm(p[:, None] - p[None], axis=2))
        out.append(ad_error(p, Te, Tg) / diameter)
    return np.array(out)


@pytest.fixture(scope="module")
def laptop():
    """A procedural laptop opened to 70% of its range, seen from 30 degrees azimuth (noise-free)."""
    model = make_object("laptop", 1)
    q = model.lower_limits + 0.7 * (model.upper_limits - model.lower_limits)
    T, pts = _view(model, q)
    return model, q, T, pts


def test_sensor_noise_recovers_the_noise_of_a_plane():
    """Points on a tilted plane with normal noise of a known sigma: the estimate is within 10% of it; noise-free
    points give (nearly) zero."""
    rng = np.random.default_rng(4)
    uv = rng.uniform(-0.5, 0.5, size=(4000, 2))
    n = np.array([0.2, -0.3, 1.0]) / np.linalg.norm([0.2, -0.3, 1.0])
    e1 = np.cross(n, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    plane = np.array([0.0, 0.0, 2.0]) + uv[:, :1] * e1 + uv[:, 1:] * e2
    sigma = 0.003
    noisy = plane + rng.normal(0.0, sigma, size=(4000, 1)) * n
    assert abs(sensor_noise(noisy) / sigma - 1.0) < 0.1
    assert sensor_noise(plane) < 1e-3 * sigma


def test_paired_z_counts_points_on_the_model_only():
    """McNemar's statistic: 100 of 500 points off a rival that shares every other point is 10 standard errors; the
    same share on other points is no worse; errors changed below the tolerance (all still on the model) change
    nothing."""
    rng = np.random.default_rng(5)
    e = rng.uniform(0.0, 0.5, 500)

    def support(errors):
        return DepthSupport(1.0, float(np.mean(errors < 1)), 0.0, float(np.mean(errors)), errors)

    off = e.copy()
    off[:100] = 1.0
    assert paired_z(support(e), support(e)) == 0.0
    assert paired_z(support(e), support(off)) == pytest.approx(10.0)
    assert paired_z(support(off), support(e)) == pytest.approx(-10.0)
    other = e.copy()
    other[rng.permutation(500)[:100]] = 1.0
    assert abs(paired_z(support(off), support(other))) < 4.0
    assert paired_z(support(e), support(2 * e)) == 0.0
    with pytest.raises(ValueError, match="worse"):
        paired_z(support(e), support(e[:10]))


def test_the_swap_of_a_swapped_estimate_is_among_the_hypotheses(laptop):
    """The swapped pose's own swap hypothesis is the truth (to rounding), and no hypothesis repeats the estimate."""
    model, q, T, _ = laptop
    diag = object_extent(model, q)[1]
    hyps = symmetric_hypotheses(model, _swapped(model, T, q), diag)
    truth = [T @ P for P in model.forward_kinematics(q)]
    errors = [max(np.linalg.norm(H.matrix() - G.matrix()) for H, G in zip(h.part_poses(model), truth)) for h in hyps]
    assert min(errors) < 1e-9
    assert 1 <= len(hyps) <= 3 + model.num_joints
    swapped_parts = _swapped(model, T, q).part_poses(model)
    assert all(max(np.linalg.norm(H.matrix() - S.matrix()) for H, S in zip(h.part_poses(model), swapped_parts)) > 0.1
               for h in hyps)


def test_a_swapped_start_is_recovered_and_a_swapped_fit_is_not_success(laptop):
    """From the swapped pose, the plain search settles on the swap and calls it success; the symmetric starts
    recover the truth (success, AD-correct); the status at the sensor noise alone refuses the swapped fit."""
    model, q, T, pts = laptop
    start = _swapped(model, T, q)
    plain = ArticulatedIcpConfig(num_points=800, rescue_angle=0.0, joint_starts=2)
    old = articulated_icp(model, pts, start, config=plain)
    assert old.status == FitStatus.SUCCESS and _ad_ratios(model, old.T_cam_parts, T, q).max() > AD_THRESHOLD
    new = articulated_icp(model, pts, start, config=ArticulatedIcpConfig.instance(num_points=800, rescue_angle=0.0,
                                                                                  joint_starts=2))
    assert new.status == FitStatus.SUCCESS, new.message
    assert _ad_ratios(model, new.T_cam_parts, T, q).max() < 1e-3
    judged = articulated_icp(model, pts, start, config=ArticulatedIcpConfig(num_points=800, rescue_angle=0.0,
                                                                            joint_starts=2, noise_status=True))
    assert judged.status in (FitStatus.LARGE_RESIDUAL, FitStatus.AMBIGUOUS), judged.message
    assert _ad_ratios(model, judged.T_cam_parts, T, q).max() > AD_THRESHOLD


def test_a_correct_fit_stopped_by_the_iteration_limit_is_success(laptop):
    """Started near the truth with too few iterations for the gate to shrink to its end (even with the second
    budget the chosen fit gets): the plain status is max_iter; at the sensor noise the fit explains the points and
    has stopped moving, so it is success."""
    model, q, T, pts = laptop
    R = exp_so3([0.01, -0.01, 0.005])
    start = ArticulatedPose(Sim3(R @ T.rotation, T.translation + 0.002), q)
    kw = dict(num_points=800, max_iterations=4, start_iterations=3, joint_restarts=False, joint_starts=0,
              rescue_angle=0.0)
    old = articulated_icp(model, pts, start, config=ArticulatedIcpConfig(**kw))
    assert old.status == FitStatus.MAX_ITER
    new = articulated_icp(model, pts, start, config=ArticulatedIcpConfig(noise_status=True, **kw))
    assert new.status == FitStatus.SUCCESS and "sensor noise" in new.message
    assert _ad_ratios(model, new.T_cam_parts, T, q).max() < AD_THRESHOLD


@pytest.mark.slow
def test_the_automatic_start_gives_the_same_fit_at_every_seed(laptop):
    """fit-cad's path (fit_depth, automatic start) at seeds 0, 1, 2: one status and AD-equal fits."""
    model, q, T, pts = laptop
    surface = ModelSurface(model)
    fits = [fit_depth(model, pts, points=1500, rng=seed, surface=surface) for seed in (0, 1, 2)]
    assert len({f.status for f in fits}) == 1
    for f in fits[1:]:
        ratios = _ad_ratios(model, f.T_cam_parts, fits[0].T_cam_base, fits[0].q)
        assert ratios.max() < AD_THRESHOLD
    assert fits[0].status == FitStatus.SUCCESS and _ad_ratios(model, fits[0].T_cam_parts, T, q).max() < AD_THRESHOLD


def test_an_exactly_symmetric_object_is_ambiguous():
    """Two identical slabs on a hinge through their mid-planes (a book): the parts swapped is the same shape, so
    the depth cannot tell the fit from its swap -- ambiguous, not success -- while the plain status says success."""
    import trimesh

    from ancsh.model.articulated import ArticulatedModel, Joint, Part

    slab = trimesh.creation.box(extents=[0.4, 0.02, 0.3])
    slab.apply_translation([0.0, 0.0, 0.15])
    model = ArticulatedModel(parts=(Part("base", slab), Part("cover", slab.copy())),
                             joints=(Joint("hinge", "revolute", "base", "cover", axis=[1.0, 0.0, 0.0], lower=0.3,
                                           upper=2.8, rest=0.3),), name="book")
    q = np.array([1.9])
    T, pts = _view(model, q, azimuth_deg=40.0, elevation_deg=30.0)
    kw = dict(num_points=800, rescue_angle=0.0, joint_starts=2)
    plain = articulated_icp(model, pts, ArticulatedPose(T, q), config=ArticulatedIcpConfig(**kw))
    assert plain.status == FitStatus.SUCCESS
    res = articulated_icp(model, pts, ArticulatedPose(T, q), config=ArticulatedIcpConfig.instance(**kw))
    assert res.status == FitStatus.AMBIGUOUS, res.message
    assert "cannot tell" in res.message and not res.ok


def test_a_fit_still_moving_at_the_limit_gets_a_second_budget(laptop):
    """8 iterations cannot shrink the gate to its end (plain: max_iter); the chosen fit's 8 more do (converged)."""
    model, q, T, pts = laptop
    R = exp_so3([0.01, -0.01, 0.005])
    start = ArticulatedPose(Sim3(R @ T.rotation, T.translation + 0.002), q)
    kw = dict(num_points=800, max_iterations=8, start_iterations=4, joint_restarts=False, joint_starts=0,
              rescue_angle=0.0)
    assert articulated_icp(model, pts, start, config=ArticulatedIcpConfig(**kw)).status == FitStatus.MAX_ITER
    new = articulated_icp(model, pts, start, config=ArticulatedIcpConfig(noise_status=True, **kw))
    assert new.status == FitStatus.SUCCESS and new.message.startswith("converged"), new.message
    assert _ad_ratios(model, new.T_cam_parts, T, q).max() < AD_THRESHOLD
