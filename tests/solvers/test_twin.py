"""A fit as a URDF: the written file reloads (yourdfpy) with the model's part poses, joint axes, limits and states."""

import json

import numpy as np
import pytest
import yourdfpy

from ancsh.data.procedural import make_object
from ancsh.geometry.rotations import exp_so3
from ancsh.geometry.transforms import Sim3
from ancsh.model.urdf_export import rpy_matrix, urdf_rpy, write_urdf
from ancsh.solvers.types import FitResult, FitStatus


def _reload(path):
    robot = yourdfpy.URDF.load(str(path))
    states = json.loads((path.parent / "joint_states.json").read_text())
    robot.update_cfg(states)
    return robot, states


def test_rpy_round_trip_including_gimbal_lock():
    from scipy.spatial.transform import Rotation

    for R in [*Rotation.random(50, random_state=0).as_matrix(), Rotation.from_euler("y", 90, degrees=True).as_matrix()]:
        roll, pitch, yaw = urdf_rpy(R)
        back = Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()  # URDF: Rz(yaw) Ry(pitch) Rx(roll)
        assert np.abs(back - R).max() < 1e-12
        assert np.abs(rpy_matrix(roll, pitch, yaw) - R).max() < 1e-12  # what load_urdf reads back


@pytest.mark.parametrize("category, seed", [("laptop", 3), ("drawer", 5), ("eyeglasses", 7)])
def test_a_written_model_reloads_with_its_part_poses_axes_limits_and_states(tmp_path, category, seed):
    model = make_object(category, seed)
    rng = np.random.default_rng(seed)
    q = model.random_states(rng)
    T = Sim3(exp_so3(rng.normal(size=3)), rng.normal(size=3))
    path = write_urdf(model, tmp_path / "twin", states=q, T_root_base=T)
    robot, states = _reload(path)
    assert [states[j.name] for j in model.joints] == pytest.approx(q, abs=1e-12)
    fk = model.forward_kinematics(q)
    for i, part in enumerate(model.parts):
        part_pose = robot.get_transform(part.name, "camera") @ robot.link_map[part.name].visuals[0].origin
        assert np.abs(part_pose - (T @ fk[i]).matrix()).max() < 1e-9
    for k, j in enumerate(model.joints):
        uj = robot.joint_map[j.name]
        assert (uj.limit.lower, uj.limit.upper) == (j.lower, j.upper)
        axis_base, pivot_base = model.joint_line_in_base(k, q)
        parent = robot.get_transform(uj.parent, "camera") @ uj.origin  # the joint frame, in the root
        axis_root = parent[:3, :3] @ uj.axis
        assert np.abs(axis_root - T.apply_direction(axis_base)).max() < 1e-9
        if j.is_revolute:  # the joint frame's origin lies on the axis through the pivot
            d = parent[:3, 3] - T.apply(pivot_base)
            assert np.linalg.norm(d - (d @ axis_root) * axis_root) < 1e-9


def test_a_state_outside_the_limits_widens_them_and_folders_are_not_overwritten(tmp_path):
    model = make_object("laptop", 3)
    q = model.upper_limits + 0.2
    path = write_urdf(model, tmp_path / "t", states=q)
    robot, _ = _reload(path)
    assert robot.joint_map[model.joints[0].name].limit.upper == pytest.approx(q[0], abs=1e-12)
    assert "limits widened" in path.read_text()
    with pytest.raises(ValueError, match="exists and is not empty"):
        write_urdf(model, tmp_path / "t")
    write_urdf(model, tmp_path / "t", overwrite=True)
    with pytest.raises(ValueError, match="states"):
        write_urdf(model, tmp_path / "u", states=[0.1, 0.2])
    with pytest.raises(ValueError, match="root"):
        write_urdf(model, tmp_path / "v", root=model.part_names[0])
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(ValueError, match="symbolic link"):
        write_urdf(model, tmp_path / "link")
    assert not any((tmp_path / "elsewhere").iterdir())


def test_a_fit_exports_with_its_fitted_joint_axis_pivot_and_state(tmp_path):
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.data.templates import load_template_library
    from ancsh.solvers import Observation, fit
    from ancsh.solvers.providers.oracle import OracleProvider
    from ancsh.solvers.twin import export_fit_urdf

    fr = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0)).frame(2)
    obs = Observation(fr.points)
    corr = OracleProvider(fr, "none", rng=0).correspond(obs)
    res = fit(obs, corr, "exact_reduced", rng=0)
    assert res.ok
    path, twin = export_fit_urdf(res, corr, load_template_library("laptop"), tmp_path / "twin")
    robot, states = _reload(path)
    name = twin.model.joints[0].name
    assert states[name] == pytest.approx(twin.model.rest_states[0] + res.joint_states[0], abs=1e-12)
    uj = robot.joint_map[name]
    frame = robot.get_transform(uj.parent, "camera") @ uj.origin
    axis = frame[:3, :3] @ uj.axis
    assert abs(abs(axis @ res.joint_axes_cam[0]) - 1.0) < 1e-9
    d = frame[:3, 3] - res.joint_pivots_cam[0]
    assert np.linalg.norm(d - (d @ axis) * axis) < 1e-9  # on the fitted axis line
    assert uj.limit.lower <= states[name] <= uj.limit.upper
    failed = FitResult.failure(FitStatus.TOO_FEW_POINTS, "few points", formulation="exact_reduced", solver="none",
                               num_joints=1, num_points=10)
    with pytest.raises(ValueError, match="a failed fit .* is not exported"):
        export_fit_urdf(failed, corr, load_template_library("laptop"), tmp_path / "none")
    assert not (tmp_path / "none").exists()


def test_predict_writes_the_urdf_and_refuses_to_overwrite(tmp_path, capsys):
    from ancsh.cli import main
    from ancsh.data.generate import FrameGenerator, GenerationConfig

    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
    fr = gen.frame(2)  # an open laptop (83 deg); frame 1 (10 deg) is fitted 52 deg off and rejected (p_object)
    _, renderer = gen.instance(fr.instance_index)
    np.save(tmp_path / "d.npy", renderer.render(fr.joint_states_abs, fr.T_cam_base, fr.intrinsics).depth)
    (tmp_path / "K.json").write_text(json.dumps(fr.intrinsics.to_json()))
    args = ["predict", "--depth", str(tmp_path / "d.npy"), "--intrinsics", str(tmp_path / "K.json"), "--category",
            "laptop", "--out", str(tmp_path / "r.json")]
    assert main([*args, "--urdf", str(tmp_path / "twin"), "--urdf-align", "0"]) == 0  # the fit's own pose and state
    robot, states = _reload(tmp_path / "twin" / "laptop.urdf")
    result = json.loads((tmp_path / "r.json").read_text())
    assert states["display_hinge"] == pytest.approx(result["joints"][0]["state_abs"], abs=1e-9)
    assert "at the fitted pose and states, median |depth residual|" in capsys.readouterr().out
    assert main([*args, "--urdf", str(tmp_path / "twin")]) == 2
    assert "--urdf: " in capsys.readouterr().err
    assert main([*args, "--urdf", str(tmp_path / "twin"), "--overwrite"]) == 0  # aligned to the depth (the default)
    _, aligned = _reload(tmp_path / "twin" / "laptop.urdf")
    assert np.isfinite(aligned["display_hinge"])
    line = next(x for x in capsys.readouterr().out.splitlines() if "model: template" in x)
    assert "median |depth residual|" in line and " mm on the object's pixels" in line  # what was written, and how well
    assert main([*args, "--overwrite"]) == 2
    assert "--overwrite: only with --urdf" in capsys.readouterr().err
    assert main([*args, "--urdf-align", "2"]) == 2
    assert "--urdf-align: only with --urdf" in capsys.readouterr().err
    (tmp_path / "link").symlink_to(tmp_path / "elsewhere", target_is_directory=True)
    (tmp_path / "elsewhere").mkdir()
    assert main([*args, "--urdf", str(tmp_path / "link"), "--overwrite"]) == 2  # refused before any work
    assert "--urdf: " in capsys.readouterr().err and not any((tmp_path / "elsewhere").iterdir())


def test_the_observed_depth_chooses_the_template_that_explains_it_best(tmp_path):
    """``fitted_model(..., observed, candidates=K)``: of the K templates nearest to the fitted boxes, the one with the
    lowest depth residual (each measured alone by ``depth_residual``), at the same pose and states; without the
    depth, the nearest one; the URDF export takes the same choice."""
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.data.templates import TemplateLibrary, load_template_library
    from ancsh.solvers import Observation, fit
    from ancsh.solvers.icp.category import fitted_layout
    from ancsh.solvers.providers.oracle import OracleProvider
    from ancsh.solvers.twin import ObservedDepth, depth_residual, export_fit_urdf, fitted_model

    fr = FrameGenerator(GenerationConfig(category="oven", split="test", seed=0)).frame(0, keep_depth=True)
    obs = Observation(fr.points)
    corr = OracleProvider(fr, "none", rng=0).correspond(obs)
    res = fit(obs, corr, "exact_reduced", rng=0)
    lib = load_template_library("oven")
    observed = ObservedDepth(fr.depth, fr.intrinsics, fr.depth > 0)
    layout = fitted_layout(res, corr)
    singles = {}
    for i in lib.nearest(layout.centres, layout.sizes, count=4):  # each candidate alone: a library holding only it
        one = fitted_model(res, corr, TemplateLibrary("oven", [lib.entries[i]], lib.real, lib.stamp))
        singles[i] = (one.template, depth_residual(one, observed))
    assert len({t for t, _ in singles.values()}) == 4
    nearest = fitted_model(res, corr, lib)
    best = fitted_model(res, corr, lib, observed=observed, candidates=4)
    first = next(iter(singles.values()))
    assert nearest.median_residual_m is None and nearest.template == first[0]
    winner = min(singles.values(), key=lambda v: v[1])
    assert best.template == winner[0] and best.median_residual_m == pytest.approx(winner[1], abs=1e-12)
    assert best.median_residual_m <= depth_residual(nearest, observed)
    np.testing.assert_array_equal(best.states, nearest.states)
    assert np.allclose(best.T_cam_B.matrix(), nearest.T_cam_B.matrix())
    _, exported = export_fit_urdf(res, corr, lib, tmp_path / "twin", observed=observed, candidates=4)
    assert exported.template == best.template
    for bad, message in ((dict(object_mask=np.zeros_like(fr.depth, dtype=bool)), "object_mask: no object pixel"),
                         (dict(object_mask=np.ones((3, 3), dtype=bool)), "object_mask: expected the depth's shape"),
                         (dict(depth=fr.depth[:-1], object_mask=fr.depth[:-1] > 0), "intrinsics: ")):
        with pytest.raises(ValueError, match=message):
            ObservedDepth(**{"depth": fr.depth, "intrinsics": fr.intrinsics, "object_mask": fr.depth > 0, **bad})
    with pytest.raises(ValueError, match="candidates: expected a positive integer"):
        fitted_model(res, corr, lib, observed=observed, candidates=0)


def _oven_frame():
    from ancsh.data.generate import FrameGenerator, GenerationConfig

    gen = FrameGenerator(GenerationConfig(category="oven", split="test", seed=0))
    return gen, gen.frame(0, keep_depth=True)


def test_alignment_moves_a_misplaced_model_back_onto_its_depth():
    """``align_model``: the frame's own instance, posed 2 degrees, 1 cm and 3 degrees of door off its true pose and
    state, is moved back onto the depth by articulated ICP: pose and state recovered near the truth, the residual
    down to the sensor noise's."""
    from ancsh.geometry.rotations import exp_so3
    from ancsh.solvers.twin import FittedModel, ObservedDepth, align_model, depth_residual

    gen, fr = _oven_frame()
    model, _ = gen.instance(fr.instance_index)
    observed = ObservedDepth(fr.depth, fr.intrinsics, fr.depth > 0)
    truth = FittedModel(model, fr.T_cam_base, np.asarray(fr.joint_states_abs, dtype=float), "instance")
    rng = np.random.default_rng(4)
    axis = rng.normal(size=3)
    turn = Sim3(exp_so3(np.radians(2.0) * axis / np.linalg.norm(axis)), 0.01 * np.array([0.6, -0.8, 0.0]))
    q = np.clip(truth.states + np.radians(3.0), model.lower_limits, model.upper_limits)
    off = FittedModel(model, turn @ fr.T_cam_base, q, "instance")
    floor, before = depth_residual(truth, observed), depth_residual(off, observed)
    back = align_model(off, observed, rng=0)
    assert back.aligned and back.template == "instance" and back.model is model
    assert back.median_residual_m == pytest.approx(depth_residual(back, observed), abs=1e-12)
    assert back.median_residual_m < before and back.median_residual_m < floor + 0.25 * (before - floor)
    R_err = back.T_cam_B.rotation @ fr.T_cam_base.rotation.T
    assert np.degrees(np.arccos(np.clip((np.trace(R_err) - 1) / 2, -1, 1))) < 0.5
    assert np.linalg.norm(back.T_cam_B.translation - fr.T_cam_base.translation) < 0.003
    assert np.degrees(np.abs(back.states - truth.states)).max() < 1.0
    with pytest.raises(ValueError, match="twin: expected a FittedModel"):
        align_model(model, observed)
    with pytest.raises(ValueError, match="observed: expected an ObservedDepth"):
        align_model(off, fr.depth)


def test_alignment_finds_the_size_of_a_model_made_too_small():
    """``align_model(..., scales=...)``: the frame's own instance shrunk by 4 % (a learned box's size error) at its true
    pose is aligned best by its factor-1.04 copy, back at the instance's size; with ``scales=(1.0,)`` the size stays."""
    from ancsh.model.edit import scaled
    from ancsh.solvers.twin import FittedModel, ObservedDepth, align_model, depth_residual

    gen, fr = _oven_frame()
    model, _ = gen.instance(fr.instance_index)
    observed = ObservedDepth(fr.depth, fr.intrinsics, fr.depth > 0)
    small = FittedModel(scaled(model, 1 / 1.04), fr.T_cam_base, np.asarray(fr.joint_states_abs, dtype=float), "small")
    fixed = align_model(small, observed, scales=(1.0,), rng=0)
    grown = align_model(small, observed, scales=(1.0, 0.96, 1.04), rng=0)

    def size(m):
        return np.linalg.norm(np.ptp(np.concatenate([p.mesh.vertices for p in m.parts]), axis=0))

    assert size(fixed.model) == pytest.approx(size(small.model), rel=1e-12)
    assert grown.aligned and size(grown.model) == pytest.approx(size(model), rel=1e-9)
    assert grown.median_residual_m < fixed.median_residual_m
    assert grown.median_residual_m == pytest.approx(depth_residual(grown, observed), abs=1e-12)
    for bad in ((), (1.0, -1.0), (np.nan,)):
        with pytest.raises(ValueError, match="scales: expected positive finite factors"):
            align_model(small, observed, scales=bad)


def test_a_prismatic_opening_scales_with_the_model():
    """``_scaled_model``: a drawer scaled by 1.1 keeps its parts where the scaled original puts them (the prismatic
    openings scaled too)."""
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.solvers.twin import FittedModel, _scaled_model

    gen = FrameGenerator(GenerationConfig(category="drawer", split="test", seed=0))
    fr = gen.frame(0)
    model, _ = gen.instance(fr.instance_index)
    q = np.asarray(fr.joint_states_abs, dtype=float)
    big, q_big = _scaled_model(FittedModel(model, fr.T_cam_base, q, "drawer"), 1.1)
    for T, T_big in zip(model.forward_kinematics(q), big.forward_kinematics(q_big)):
        np.testing.assert_allclose(T_big.translation, 1.1 * T.translation, atol=1e-12)
        np.testing.assert_allclose(T_big.rotation, T.rotation, atol=1e-12)
    assert _scaled_model(FittedModel(model, fr.T_cam_base, q, "drawer"), 1.0)[0] is model


def test_the_aligned_choice_never_explains_the_depth_worse_and_is_what_the_urdf_holds(tmp_path):
    """``fitted_model(..., align=A)``: the best A of the K templates are aligned; the kept model's residual is at most
    the unaligned best's and is its own render's; the exported URDF holds the kept model's pose and states."""
    from ancsh.data.templates import load_template_library
    from ancsh.solvers import Observation, fit
    from ancsh.solvers.providers.oracle import OracleProvider
    from ancsh.solvers.twin import ObservedDepth, depth_residual, export_fit_urdf, fitted_model

    _, fr = _oven_frame()
    obs = Observation(fr.points)
    corr = OracleProvider(fr, "none", rng=0).correspond(obs)
    res = fit(obs, corr, "exact_reduced", rng=0)
    lib = load_template_library("oven")
    observed = ObservedDepth(fr.depth, fr.intrinsics, fr.depth > 0)
    best = fitted_model(res, corr, lib, observed=observed, candidates=4)
    kept = fitted_model(res, corr, lib, observed=observed, candidates=4, align=2, rng=0)
    assert not best.aligned and kept.median_residual_m <= best.median_residual_m
    assert kept.median_residual_m == pytest.approx(depth_residual(kept, observed), abs=1e-12)
    path, exported = export_fit_urdf(res, corr, lib, tmp_path / "twin", observed=observed, candidates=4, align=2, rng=0)
    assert exported.template == kept.template and exported.aligned == kept.aligned
    robot, states = _reload(path)
    assert [states[j.name] for j in exported.model.joints] == pytest.approx(exported.states, abs=1e-12)
    base = exported.model.part_names[0]
    pose = robot.get_transform(base, "camera") @ robot.link_map[base].visuals[0].origin
    fk = exported.model.forward_kinematics(exported.states)[0]
    assert np.abs(pose - (exported.T_cam_B @ fk).matrix()).max() < 1e-9
    for bad, message in ((dict(align=-1), "align: expected a non-negative integer"),
                         (dict(align=True), "align: expected a non-negative integer"),
                         (dict(align=1, observed=None), "align: aligning the model needs the observed depth")):
        with pytest.raises(ValueError, match=message):
            fitted_model(res, corr, lib, **{"observed": observed, "candidates": 4, **bad})


def test_a_model_written_tilted_so_no_axis_is_horizontal_loads_back(tmp_path):
    """``load_urdf`` of an exported model whose base is turned so that every base axis is 54.7 degrees from the
    root's up (the camera-frame root of ``predict --urdf`` puts a base anywhere): it loads with the written parts and
    joints instead of finding no horizontal axis to face."""
    from scipy.spatial.transform import Rotation

    from ancsh.data.urdf import load_urdf

    model = make_object("oven", 2)
    R = Rotation.align_vectors([[0.0, 0.0, 1.0]], [np.ones(3) / np.sqrt(3.0)])[0].as_matrix()  # (1,1,1) -> up
    assert np.allclose(np.abs(R.T @ [0.0, 0.0, 1.0]), 1 / np.sqrt(3.0))
    path = write_urdf(model, tmp_path / "tilted", states=model.rest_states, T_root_base=Sim3(R, np.array([0.0, 0.0, 1.0])))
    back = load_urdf(path)
    assert back.num_parts == model.num_parts and [j.name for j in back.joints] == [j.name for j in model.joints]


def test_a_written_model_loads_back_at_its_base_link_with_its_orientation_and_category(tmp_path):
    """``load_urdf`` of a model written in a camera frame (``predict --urdf``): the ``<ancsh>`` element makes the
    object start at its base link -- parts and joints as written, no ``camera`` part, the base's meshes in the base
    frame, the joints' axes, pivots, limits and rest states there, the model's ``R_canon_base`` and category -- where
    the camera's +z would otherwise be taken for up."""
    from ancsh.data.urdf import load_urdf

    model = make_object("laptop", 3)
    rng = np.random.default_rng(3)
    T = Sim3(exp_so3(rng.normal(size=3)), rng.normal(size=3))
    q = model.random_states(rng)
    back = load_urdf(write_urdf(model, tmp_path / "twin", states=q, T_root_base=T))
    assert back.part_names == model.part_names and back.category == model.category
    np.testing.assert_array_equal(back.rest_states, model.rest_states)  # the laptop's display upright, not URDF's 0
    np.testing.assert_allclose(back.R_canon_base, model.R_canon_base, atol=1e-12)
    for a, b in zip(back.forward_kinematics(q), model.forward_kinematics(q)):  # the same parts in the same base frame
        np.testing.assert_allclose(a.matrix(), b.matrix(), atol=1e-9)
    for pa, pb in zip(back.parts, model.parts):  # the OBJ files hold 8 decimals of a metre
        np.testing.assert_allclose(pa.mesh.bounds, pb.mesh.bounds, atol=1e-8)
    for ja, jb in zip(back.joints, model.joints):
        assert (ja.lower, ja.upper) == (jb.lower, jb.upper)
        np.testing.assert_allclose(ja.axis, jb.axis, atol=1e-12)


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace('base_link="base"', 'base_link="keyboard"'), "names no <link>"),
    (lambda t: t.replace('canonical_rpy="', 'canonical_rpy="x '), "canonical_rpy must be 3 finite numbers"),
    (lambda t: t.replace('base_link="base"', 'base_link="display"'), "hangs from the revolute joint"),
    (lambda t: t.replace('rest="', 'rest="0.5 '), "rest=...> must hold 1 number"),
    (lambda t: t.replace('rest="', 'rest="x'), "rest must be finite numbers"),
    (lambda t: t.replace('rest="', 'rest="-1'), "rest -11.5.* lies outside its limits"),
    (lambda t: t.replace('<link name="camera"/>', '<link name="camera"><visual><geometry><box size="1 1 1"/>'
                         '</geometry></visual></link>'), "link 'camera' above the base carries geometry"),
])
def test_a_written_object_record_that_does_not_fit_the_file_is_refused(tmp_path, edit, message):
    from ancsh.data.urdf import load_urdf

    path = write_urdf(make_object("laptop", 3), tmp_path / "twin")
    path.write_text(edit(path.read_text()))
    with pytest.raises(ValueError, match=message):
        load_urdf(path)


#: A held-out frame (test split, seed 0) of each category whose object ``ancsh predict`` finds at 320 x 240 pixels and
#: whose twin explains 80 % of the depth (``ArticulatedIcpConfig.accept_inliers``), so that ``fit-cad`` keeps its
#: start: frame 0 of the drawer, the washing machine and the box is refused by ``p_object``; on safe frames 1-3 and 6
#: the template's shelves differ from the instance's, ``fit-cad`` searches further and leaves the twin by more than
#: its gate (its multi-start search, not the round trip).
ROUND_TRIP_FRAMES = {"box": 2, "drawer": 2, "eyeglasses": 0, "laptop": 0, "microwave": 2, "oven": 2, "safe": 5,
                     "washing_machine": 2}


@pytest.mark.slow
@pytest.mark.parametrize("category", sorted(ROUND_TRIP_FRAMES))
def test_the_twin_round_trips_through_data_import_and_fit_cad(tmp_path, category, capsys):
    """What ``ancsh predict --urdf`` writes, ``ancsh data import`` accepts and ``ancsh fit-cad`` fits on the same depth
    (a 320 x 240 noise-free render of a held-out instance):

    - the file loads as the model written: the category's parts and joints, its base frame with NAOCS axes
      (``R_canon_base`` the identity), the category's rest states;
    - ``data import`` (the category read from the file) accepts it as it is: state 0 at the file's 0 (within one step
      of the importer's search grid), growing the same way, the front not turned;
    - ``fit-cad`` started at the twin's pose (the fixed joint placing its base in the camera) and states ends at the
      object -- not a failure (``max_iter``: the ICP still creeping by 1e-4 diagonals an iteration on the template's
      shape difference, is not one) -- with every vertex of the model within the ICP's final correspondence gate of
      where the twin put it."""
    from ancsh.cli import main
    from ancsh.data.catalog import load_catalog
    from ancsh.data.conventions import convention
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.data.import_rules import _GRID
    from ancsh.data.render import Intrinsics, object_extent
    from ancsh.data.urdf import load_urdf
    from ancsh.solvers.icp import ArticulatedIcpConfig

    config = GenerationConfig(category=category, split="test", seed=0, intrinsics=Intrinsics.kinect(320, 240))
    gen = FrameGenerator(config)
    fr = gen.frame(ROUND_TRIP_FRAMES[category])
    _, renderer = gen.instance(fr.instance_index)
    depth, K = tmp_path / "d.npy", tmp_path / "K.json"
    np.save(depth, renderer.render(fr.joint_states_abs, fr.T_cam_base, fr.intrinsics).depth)
    K.write_text(json.dumps(fr.intrinsics.to_json()))
    assert main(["predict", "--depth", str(depth), "--intrinsics", str(K), "--category", category,
                 "--urdf", str(tmp_path / "twin")]) == 0, capsys.readouterr()
    urdf = tmp_path / "twin" / f"{category}.urdf"

    conv = convention(category)
    model = load_urdf(urdf)
    assert tuple(model.part_names) == conv.part_names and model.category == category
    assert tuple(j.name for j in model.joints) == conv.joint_names
    np.testing.assert_allclose(model.R_canon_base, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(model.rest_states, conv.rest_states, atol=1e-12)

    assert main(["data", "import", str(urdf), "--out", str(tmp_path / "catalog")]) == 0, capsys.readouterr()
    (obj,) = load_catalog(tmp_path / "catalog").objects
    assert obj.category == category and not obj.flip_front and obj.sign == (1,) * model.num_joints
    steps = [(j.upper - j.lower) / (_GRID - 1) for j in model.joints]
    assert all(abs(z) <= step for z, step in zip(obj.zero, steps)), (obj.zero, steps)

    robot, states = _reload(urdf)
    T_cam_B = robot.get_transform(model.part_names[0], "camera")  # the fixed joint placing the base
    q = np.array([states[j.name] for j in model.joints])
    init = json.loads((tmp_path / "twin" / "init.json").read_text())  # written for fit-cad --init: the same
    np.testing.assert_allclose(init["T_cam_base"], T_cam_B, atol=1e-12)
    np.testing.assert_array_equal(init["q"], q)
    code = main(["fit-cad", "--urdf", str(urdf), "--depth", str(depth), "--intrinsics", str(K), "--init",
                 str(tmp_path / "twin" / "init.json"), "--points", "800", "--out", str(tmp_path / "fit.json")])
    result = json.loads((tmp_path / "fit.json").read_text())
    # The twin is the nearest category template reshaped to the fit, not the instance: on this noise-free render the
    # sensor-noise verdict (solvers/icp/verdict.py) may call its shape difference large_residual. What must hold is
    # the fit ending at the twin (below) and the exit code following the status.
    assert result["status"] in ("success", "max_iter", "large_residual"), result
    assert code == (0 if result["status"] == "success" else 1), (code, result["status"])
    config = ArticulatedIcpConfig()
    gate = max(config.gate_end * object_extent(model, model.rest_states)[1], config.gate_floor)
    for part, T_twin, T_fit in zip(model.parts, model.forward_kinematics(q), result["T_cam_parts"]):
        v = part.mesh.vertices
        twin = v @ (T_cam_B[:3, :3] @ T_twin.rotation).T + T_cam_B[:3, :3] @ T_twin.translation + T_cam_B[:3, 3]
        fitted = v @ np.array(T_fit["rotation"]).T + np.array(T_fit["translation"])
        assert np.linalg.norm(fitted - twin, axis=1).max() <= gate, (part.name, gate)
