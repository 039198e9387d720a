"""Category-template refinement: template choice, reshaping, scoring and acceptance (ancsh.solvers.icp.category)."""

import dataclasses

import numpy as np
import pytest

from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.data.templates import TemplateEntry, TemplateLibrary, load_template_library
from ancsh.evaluation import evaluate_fit
from ancsh.solvers import Observation, fit
from ancsh.solvers.icp.articulated import FitScorer
from ancsh.solvers.icp.category import RefineConfig, fitted_layout, fitted_template, refine_fit, released
from ancsh.solvers.icp.template import ModelSurface
from ancsh.solvers.providers.oracle import OracleProvider
from ancsh.solvers.types import FitResult, FitStatus

CATEGORY = "oven"


@pytest.fixture(scope="module")
def scene():
    """A seeded held-out oven frame, its true instance, and an exact fit of realistic oracle correspondences."""
    gen = FrameGenerator(GenerationConfig(category=CATEGORY, split="test", seed=0))
    fr = gen.frame(0)
    index = next(k for k in range(gen.num_instances) if gen.instance(k)[0].name == fr.instance)
    obs = Observation(fr.points)
    corr = OracleProvider(fr, "realistic", rng=0).correspond(obs)
    result = fit(obs, corr, "exact_reduced", rng=0)
    assert result.ok
    return dict(gen=gen, frame=fr, model=gen.instance(index)[0], index=index, obs=obs, corr=corr, fit=result)


def _rot(result, gt):
    return np.array([p.rot_deg for p in evaluate_fit(result, gt).parts])


def test_true_instance_template_recovers_the_pose_at_least_as_well(scene):
    """With the true instance as the template, the refined fit is at least as good as the input, per part."""
    ref = refine_fit(scene["obs"], scene["fit"], scene["corr"], scene["model"], rng=0)
    before, after = _rot(scene["fit"], scene["frame"].gt), _rot(ref.result, scene["frame"].gt)
    assert ref.accepted and ref.result.ok
    assert ref.score_refined < ref.score_input
    assert np.all(after <= before + 1e-6), (before, after)
    assert after.max() < 1.0  # the template is the object: ICP lands near the truth (input: ~2 degrees)


def test_refined_fit_carries_the_template_icp_covariance(scene):
    """An articulated refinement reports the ICP's covariance in the refined fit's NPCS frames: the same
    camera-frame rotation and joint-state variances as the ICP run at that estimate; the scale unknown."""
    from ancsh.solvers.icp.articulated import icp_uncertainty
    from ancsh.solvers.icp.template import TemplateProvider

    icp_config = dataclasses.replace(RefineConfig().icp, num_points=None)  # every point (no subsample to replay)
    config = RefineConfig(candidates=("articulated",), scales=(1.0,), icp=icp_config)
    ref = refine_fit(scene["obs"], scene["fit"], scene["corr"], scene["model"], config=config, rng=0)
    assert ref.accepted and ref.choice == "articulated"
    u = ref.result.uncertainty
    assert u is not None and u.status == "ok"
    assert np.all(np.isfinite(u.rotation_rms_rad)) and np.all(u.rotation_rms_rad > 0)
    assert np.all(np.isfinite(u.translation_rms_m)) and np.all(np.isfinite(u.joint_state_std))
    assert np.all(np.isnan(u.scale_std))  # chosen by the scale search, not estimated
    # the ICP's own covariance at the carried estimate, in the template's part frames
    c = ref.carried
    diagonal = TemplateProvider(c.model).T_cam_naocs_scale  # as articulated_icp sets its gate and robust loss
    prov = TemplateProvider(c.model, c.pose, max_distance=max(icp_config.gate_end * diagonal, icp_config.gate_floor),
                            loss=icp_config.loss, loss_scale=max(icp_config.loss_scale * diagonal, icp_config.gate_floor / 3))
    icp = icp_uncertainty(prov, scene["obs"].points_cam, prov.correspond(scene["obs"]),
                          point_to_plane=icp_config.point_to_plane, point_weight=icp_config.point_weight)
    for j in range(2):  # composing on the right keeps the camera-frame rotation tangent
        np.testing.assert_allclose(u.part_covariances[j, :3, :3], icp.part_covariances[j, :3, :3], rtol=1e-6, atol=1e-14)
    np.testing.assert_allclose(u.joint_state_covariance, icp.joint_state_covariance, rtol=1e-6, atol=1e-14)
    # translations move to the NPCS origins, t' = t + s R c (c: the NPCS origin in the template part frame, at
    # scale 1 here): a rotation error phi moves them by phi x (s R c)
    layout = fitted_layout(scene["fit"], scene["corr"])
    moved = []
    for j, T_part in enumerate(c.pose.part_poses(c.model)):
        w = T_part.scale * T_part.rotation @ layout.T_B_npcs[j].translation
        B = np.hstack([-np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]]), np.eye(3)])
        expected = B @ icp.part_covariances[j, :6, :6] @ B.T
        np.testing.assert_allclose(u.part_covariances[j, 3:6, 3:6], expected, rtol=1e-6, atol=1e-14)
        moved.append(np.abs(expected - icp.part_covariances[j, 3:6, 3:6]).max() / np.abs(expected).max())
    assert max(moved) > 0.05  # the lever arm matters (so the check above can tell the frames apart)
    # a tracked frame of the carried template maps its ICP covariance the same way (CarriedTemplateFit.fit_of)
    tracked = c.fit_of(c.pose, icp).uncertainty
    np.testing.assert_allclose(tracked.part_covariances, u.part_covariances, rtol=1e-6, atol=1e-14)
    np.testing.assert_allclose(tracked.object_covariance, u.object_covariance, rtol=1e-6, atol=1e-14)
    assert c.fit_of(c.pose).uncertainty is None
    base = refine_fit(scene["obs"], scene["fit"], scene["corr"], scene["model"], rng=0,
                      config=RefineConfig(candidates=("base",), scales=(1.0,)))
    assert not base.accepted or base.result.uncertainty is None  # the base candidate: no single program's covariance


def test_input_score_is_the_template_at_the_fit_part_poses(scene):
    """The input fit is scored on the observed points with the template posed part by part at its own poses."""
    layout = fitted_layout(scene["fit"], scene["corr"])
    cfg = RefineConfig(scales=(1.0,))
    ft = fitted_template(scene["model"], layout, box_scaling=cfg.box_scaling)
    poses = [T @ layout.T_B_npcs[j].inverse() for j, T in enumerate(scene["fit"].T_cam_npcs)]
    gate = max(cfg.icp.gate_end * layout.diagonal, cfg.icp.gate_floor)
    expected = FitScorer(scene["obs"].points_cam, 0).score(ModelSurface(ft.model), poses, gate)
    ref = refine_fit(scene["obs"], scene["fit"], scene["corr"], scene["model"], config=cfg, rng=0)
    assert ref.score_input == pytest.approx(expected.score, abs=1e-9)


def test_refinement_whose_score_is_not_better_is_refused(scene):
    """A margin no candidate can meet: the input fit comes back unchanged, with the reason."""
    cfg = RefineConfig(scales=(1.0,), margin=2.0)  # scores lie in [0, 2]
    ref = refine_fit(scene["obs"], scene["fit"], scene["corr"], scene["model"], config=cfg, rng=0)
    assert not ref.accepted and ref.choice == "input"
    assert ref.result is scene["fit"]
    assert "scores below the input" in ref.reason


def test_refinement_worse_on_a_part_is_refused(scene):
    """A zero part tolerance with a template of another instance: refused unless no part got worse."""
    other = scene["gen"].instance((scene["index"] + 1) % scene["gen"].num_instances)[0]
    ref = refine_fit(scene["obs"], scene["fit"], scene["corr"], other, config=RefineConfig(scales=(1.0,), part_tolerance=0.0),
                     rng=0)
    if ref.accepted:
        assert ref.score_refined < ref.score_input
    else:
        assert ref.result is scene["fit"]


def test_template_selection_picks_the_true_instance(scene):
    """Among several instances, the one whose part boxes match the (exact) fitted boxes is chosen."""
    fr = scene["frame"]
    obs = scene["obs"]
    corr = OracleProvider(fr, "none", rng=0).correspond(obs)
    exact = fit(obs, corr, "exact_reduced", rng=0)
    layout = fitted_layout(exact, corr)
    models = [scene["gen"].instance(k)[0] for k in range(6)]
    if scene["index"] >= 6:
        models.append(scene["model"])
    lib = TemplateLibrary(CATEGORY, [TemplateEntry.of_model(m, "procedural", 0) for m in models])
    picked = lib.nearest(layout.centres, layout.sizes)[0]
    assert models[picked].name == scene["model"].name


def test_templates_without_their_urdf_are_skipped(scene, tmp_path, monkeypatch):
    """Without the shared data folder, real templates are not chosen (procedural ones still are), and a
    library of none available leaves the fit as it is, with the reason."""
    shipped = load_template_library("laptop").to_dict()  # read before the shared data folder is emptied
    monkeypatch.setenv("ANCSH_SHARED_DATA", str(tmp_path))  # an empty shared data folder
    laptop = TemplateLibrary.from_dict(shipped)  # a fresh copy: no cached checks
    real = [i for i, e in enumerate(laptop.entries) if e.source == "real"]
    assert real and not any(laptop.available(i) for i in real)
    assert all(laptop.available(i) for i, e in enumerate(laptop.entries) if e.source == "procedural")
    nearest_real = laptop.entries[real[0]]  # its own boxes: it would be the nearest entry if it were available
    picked = laptop.nearest(nearest_real.centres, nearest_real.sizes, count=5)
    assert len(picked) == 5 and not set(picked) & set(real)
    none_here = TemplateLibrary(CATEGORY, [TemplateEntry.of_model(scene["model"], "real")], real="builtin")
    assert none_here.nearest(np.zeros((2, 3)), np.ones((2, 3))) == []
    out = refine_fit(scene["obs"], scene["fit"], scene["corr"], none_here, rng=0)
    assert not out.accepted and out.result is scene["fit"] and "no oven template is available" in out.reason


def test_shipped_library_is_current_and_round_trips():
    lib = load_template_library(CATEGORY)
    assert len(lib) >= 200 and lib.num_parts == 2
    again = TemplateLibrary.from_dict(lib.to_dict())
    assert [e.name for e in again.entries] == [e.name for e in lib.entries]
    assert lib.model(0).num_parts == 2


def test_released_template_refines_a_state_past_its_own_limit(scene):
    """The true oven instance with its door's upper limit moved below the frame's state (a template of a
    door that opens less than the observed one): refined with its own limits the door stops at that limit;
    released (half a turn about rest, ``release_revolute``) it reaches the observed state, and the carried
    template keeps the released limits."""
    from ancsh.model.edit import with_limits

    model, fr = scene["model"], scene["frame"]
    state = float(fr.gt.joint_states[0])
    cut = with_limits(model, model.lower_limits, model.rest_states + 0.6 * state)
    free = released(cut)
    np.testing.assert_allclose(free.upper_limits, cut.rest_states + np.pi)
    np.testing.assert_allclose(free.lower_limits, np.minimum(cut.lower_limits, cut.rest_states - np.pi))
    own = refine_fit(scene["obs"], scene["fit"], scene["corr"], cut, rng=0)
    rel = refine_fit(scene["obs"], scene["fit"], scene["corr"], cut, config=RefineConfig(release_revolute=True), rng=0)
    assert rel.accepted
    err = lambda r: abs(float(r.result.joint_states[0]) - state)  # noqa: E731
    assert err(rel) < np.radians(2.0) < err(own)
    assert rel.carried.model.upper_limits[0] == pytest.approx(cut.rest_states[0] + np.pi)


def test_bad_inputs_give_clear_errors(scene):
    obs, corr, res = scene["obs"], scene["corr"], scene["fit"]
    failed = FitResult.failure(FitStatus.TOO_FEW_POINTS, "x", formulation="exact_reduced", solver="ipopt", num_joints=1)
    out = refine_fit(obs, failed, corr, scene["model"])
    assert not out.accepted and out.result is failed and "failed" in out.reason
    with pytest.raises(ValueError, match="templates"):
        refine_fit(obs, res, corr, "oven")
    with pytest.raises(ValueError, match="observation"):
        refine_fit(obs.points_cam, res, corr, scene["model"])
    with pytest.raises(ValueError, match="fit"):
        refine_fit(obs, dataclasses.replace(res, joint_states=np.zeros(2)), corr, scene["model"])
    drawer = load_template_library("drawer")
    with pytest.raises(ValueError, match="templates"):
        refine_fit(obs, res, corr, drawer)
    with pytest.raises(ValueError, match="template"):
        fitted_template(drawer.model(0), fitted_layout(res, corr))
    with pytest.raises(ValueError, match="scales"):
        RefineConfig(scales=())
    with pytest.raises(ValueError, match="box_scaling"):
        RefineConfig(box_scaling="per_axis")
    with pytest.raises(ValueError, match="candidates"):
        RefineConfig(candidates=("joints",))
    with pytest.raises(ValueError, match="release_revolute"):
        RefineConfig(release_revolute="yes")
    with pytest.raises(ValueError, match="entries"):
        TemplateLibrary(CATEGORY, [])
    lib = load_template_library(CATEGORY)
    with pytest.raises(ValueError, match="centres"):
        lib.nearest(np.zeros((3, 3)), np.ones((2, 3)))
    with pytest.raises(ValueError, match="index"):
        lib.model(len(lib))


def test_unit_diagonal_layout_is_the_fit_made_with_unit_diagonal_boxes(scene):
    """``fitted_layout(..., box_extents="unit_diagonal")``: every part's NPCS sides of unit length together; the same
    layout as that of the fit made with ``FitConfig(box_extents="unit_diagonal")``, whose own boxes it leaves as they
    are; the poses as the fitted boxes' layout has them."""
    from ancsh.solvers import FitConfig

    corr = dataclasses.replace(scene["corr"], npcs_extents=None)  # boxes from the inliers' NPCS, as a network's
    as_made = fit(scene["obs"], corr, "exact_reduced", rng=0)
    made = fit(scene["obs"], corr, "exact_reduced", config=FitConfig(box_extents="unit_diagonal"), rng=0)
    assert made.ok and as_made.ok
    as_fit = fitted_layout(as_made, corr)
    unit = fitted_layout(as_made, corr, box_extents="unit_diagonal")
    np.testing.assert_allclose(np.linalg.norm(unit.npcs_extents, axis=1), 1.0, atol=1e-12)
    assert np.abs(np.linalg.norm(as_fit.npcs_extents, axis=1) - 1.0).max() > 1e-3  # the "max" boxes are not
    for other in (fitted_layout(made, corr), fitted_layout(made, corr, box_extents="unit_diagonal")):
        np.testing.assert_allclose(other.npcs_extents, unit.npcs_extents, atol=1e-9)
        np.testing.assert_allclose(other.sizes, unit.sizes, atol=1e-9)
        assert other.diagonal == pytest.approx(unit.diagonal, rel=1e-9)
    for a, b in zip(unit.T_B_npcs, as_fit.T_B_npcs):
        np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-12)
    with pytest.raises(ValueError, match="box_extents"):
        fitted_layout(as_made, corr, box_extents="max")
