"""ANCSH ground truth (paper Sec. 4.1, 4.2, 4.4): every quantity recomputed from the others agrees."""

import numpy as np
import pytest
import trimesh

from ancsh.geometry.rotations import axis_angle_matrix, random_rotation
from ancsh.geometry.transforms import Sim3
from ancsh.model import (
    ArticulatedModel,
    Joint,
    JointType,
    Part,
    ancsh_ground_truth,
    canonical_space,
    joint_association,
    random_articulated_model,
    random_camera_pose,
    sample_frame,
)

TOL = 1e-9
SEEDS = range(12)


def _box(extents, center=(0.0, 0.0, 0.0)):
    return trimesh.creation.box(extents=extents, transform=trimesh.transformations.translation_matrix(center))


def _random_case(seed):
    """A seeded model (chains for even seeds, branching trees for odd) and one random frame."""
    rng = np.random.default_rng(seed)
    tree = seed % 2 == 1
    model = random_articulated_model(
        rng, num_parts=int(rng.integers(3, 6)), tree=tree, random_canonical=seed % 3 == 0, unlimited_revolute=seed % 4 == 2
    )
    frame = sample_frame(model, rng, points_per_part=150)
    gt = ancsh_ground_truth(model, frame.q, frame.T_cam_base, frame.points_cam, frame.part_labels)
    return model, frame, gt


def _line_distance(points, pivot, axis):
    """Distance of ``points`` (N, 3) to the line (pivot, unit axis), via the cross product."""
    return np.linalg.norm(np.cross(np.atleast_2d(points) - pivot, axis), axis=1)


# --- canonical space -------------------------------------------------------------------
def test_single_box_naocs_closed_form():
    """One box with sides (0.3, 0.4, 1.2) (diagonal 1.3) at (1, 2, 3), canonical frame rotated 90 deg about z."""
    R = axis_angle_matrix([0, 0, 1], np.pi / 2)
    model = ArticulatedModel((Part("base", _box((0.3, 0.4, 1.2), (1.0, 2.0, 3.0))),), (), R_canon_base=R)
    cs = canonical_space(model)
    assert cs.T_naocs_base.scale == pytest.approx(1 / 1.3, abs=1e-12)
    np.testing.assert_allclose(cs.T_naocs_base.apply(np.array([1.0, 2.0, 3.0])), 0.0, atol=TOL)
    np.testing.assert_allclose(cs.T_naocs_base.rotation, R, atol=1e-12)
    np.testing.assert_allclose(cs.naocs_extents, np.array([0.4, 0.3, 1.2]) / 1.3, atol=TOL)
    np.testing.assert_allclose(cs.npcs_scale, [1.0], atol=TOL)
    np.testing.assert_allclose(cs.npcs_translation, np.zeros((1, 3)), atol=TOL)
    np.testing.assert_allclose(cs.npcs_extents[0], cs.naocs_extents, atol=TOL)


def test_two_boxes_npcs_closed_form():
    """Base box [0,2]x[0,1]x[0,1] and a child cube of side 1 attached at x in [2,3]: known NAOCS and NPCS."""
    base = Part("base", _box((2.0, 1.0, 1.0), (1.0, 0.5, 0.5)))
    child = Part("lid", _box((1.0, 1.0, 1.0)))
    joint = Joint("hinge", "revolute", "base", "lid", [0, 0, 1], [2.0, 0.0, 0.0], -1.0, 1.0, 0.0,
                  Sim3(np.eye(3), [2.5, 0.5, 0.5]))
    cs = canonical_space(ArticulatedModel((base, child), (joint,)))
    diag = np.sqrt(9 + 1 + 1)
    assert cs.T_naocs_base.scale == pytest.approx(1 / diag, abs=1e-12)
    centre = np.array([1.5, 0.5, 0.5])
    np.testing.assert_allclose(cs.npcs_scale, [np.sqrt(6) / diag, np.sqrt(3) / diag], atol=TOL)
    np.testing.assert_allclose(cs.npcs_translation[0], (np.array([1.0, 0.5, 0.5]) - centre) / diag, atol=TOL)
    np.testing.assert_allclose(cs.npcs_translation[1], (np.array([2.5, 0.5, 0.5]) - centre) / diag, atol=TOL)
    np.testing.assert_allclose(cs.npcs_extents[1], np.full(3, 1 / np.sqrt(3)), atol=TOL)
    # Pivot: point of the line x=2, y=0 (along z) closest to the NAOCS origin.
    np.testing.assert_allclose(cs.joint_axes_naocs[0], [0, 0, 1], atol=TOL)
    np.testing.assert_allclose(cs.joint_pivots_naocs[0], [0.5 / diag, -0.5 / diag, 0.0], atol=TOL)
    assert cs.joint_types == (JointType.REVOLUTE,)


@pytest.mark.parametrize("seed", SEEDS)
def test_naocs_and_npcs_boxes_tight_and_unit(seed):
    """All rest-state vertices in NAOCS: tight box centred at 0 with diagonal 1; each part's NPCS box likewise."""
    rng = np.random.default_rng(seed)
    model = random_articulated_model(rng, num_parts=4, tree=seed % 2 == 1, random_canonical=True)
    cs = canonical_space(model)
    poses = model.forward_kinematics(model.rest_states)
    per_part = [cs.T_naocs_base.apply(poses[j].apply(p.vertices)) for j, p in enumerate(model.parts)]
    allv = np.concatenate(per_part)
    lo, hi = allv.min(0), allv.max(0)
    np.testing.assert_allclose(0.5 * (lo + hi), 0.0, atol=TOL)
    assert np.linalg.norm(hi - lo) == pytest.approx(1.0, abs=TOL)
    np.testing.assert_allclose(hi - lo, cs.naocs_extents, atol=TOL)
    for j, v in enumerate(per_part):
        npcs = cs.T_naocs_npcs(j).inverse().apply(v)
        lo, hi = npcs.min(0), npcs.max(0)
        np.testing.assert_allclose(0.5 * (lo + hi), 0.0, atol=TOL)
        np.testing.assert_allclose(hi - lo, cs.npcs_extents[j], atol=TOL)
        assert np.linalg.norm(hi - lo) == pytest.approx(1.0, abs=TOL)
    np.testing.assert_allclose(np.linalg.norm(cs.joint_axes_naocs, axis=1), 1.0, atol=TOL)
    # Pivots are the points of the joint lines closest to the origin: perpendicular to the axis.
    np.testing.assert_allclose(np.sum(cs.joint_axes_naocs * cs.joint_pivots_naocs, axis=1), 0.0, atol=TOL)


# --- per-frame ground truth ------------------------------------------------------------
@pytest.mark.parametrize("seed", SEEDS)
def test_points_npcs_naocs_poses_boxes_consistent(seed):
    model, frame, gt = _random_case(seed)
    assert gt.part_labels.dtype == np.int64 and gt.joint_association.dtype == np.int64
    for j in range(model.num_parts):
        sel = gt.part_labels == j
        # NPCS mapped by the part pose gives back the observed points.
        np.testing.assert_allclose(gt.T_cam_npcs[j].apply(gt.npcs[sel]), frame.points_cam[sel], atol=TOL)
        # NAOCS = s * NPCS + t.
        np.testing.assert_allclose(
            gt.npcs_scale[j] * gt.npcs[sel] + gt.npcs_translation[j], gt.naocs[sel], atol=TOL
        )
        # Surface points lie in the unit-diagonal NPCS box, and in the amodal camera box.
        half = 0.5 * canonical_space(model).npcs_extents[j]
        assert np.all(np.abs(gt.npcs[sel]) <= half + TOL)
        assert np.all(gt.boxes_cam[j].contains(frame.points_cam[sel], tol=TOL))
        assert gt.boxes_cam[j].diagonal == pytest.approx(gt.T_cam_npcs[j].scale, rel=1e-12)
        np.testing.assert_allclose(gt.boxes_cam[j].center, gt.T_cam_npcs[j].translation, atol=TOL)
    # The object pose is the base part's NAOCS -> camera map.
    assert gt.T_cam_naocs.allclose(gt.T_cam_naocs_part(model.base_index), atol=TOL)
    np.testing.assert_allclose(gt.joint_states, frame.q - model.rest_states, atol=0)


@pytest.mark.parametrize("seed", SEEDS)
def test_camera_joint_from_parent_and_child_agree(seed):
    """Camera-space joint axis/pivot mapped through the parent's and the child's NAOCS->camera map: same line."""
    model, _, gt = _random_case(seed)
    for k in range(model.num_joints):
        for part in (gt.joint_parents[k], gt.joint_children[k]):
            T = gt.T_cam_naocs_part(part)
            a = T.apply_direction(gt.joint_axes_naocs[k])
            np.testing.assert_allclose(a, gt.joint_axes_cam[k], atol=TOL)
            p = T.apply(gt.joint_pivots_naocs[k])
            assert _line_distance(p, gt.joint_pivots_cam[k], gt.joint_axes_cam[k])[0] < TOL
            if gt.joint_types[k] == JointType.REVOLUTE:
                np.testing.assert_allclose(p, gt.joint_pivots_cam[k], atol=TOL)
        # The camera-space line is the model's joint line at q, seen from the camera.
        a_base, p_base = model.joint_line_in_base(k, _q_of(gt, model))
        T_cam_base = _T_cam_base(gt, model)
        np.testing.assert_allclose(T_cam_base.apply_direction(a_base), gt.joint_axes_cam[k], atol=TOL)
        assert _line_distance(T_cam_base.apply(p_base), gt.joint_pivots_cam[k], gt.joint_axes_cam[k])[0] < TOL


def _q_of(gt, model):
    return gt.joint_states + model.rest_states


def _T_cam_base(gt, model):
    cs = canonical_space(model)
    return gt.T_cam_naocs @ cs.T_naocs_base


@pytest.mark.parametrize("seed", SEEDS)
def test_joint_states_recovered_from_part_poses(seed):
    """Relative NAOCS->camera maps of connected parts are the joint motion by the state, in NAOCS."""
    model, _, gt = _random_case(seed)
    s_naocs = canonical_space(model).T_naocs_base.scale
    for k in range(model.num_joints):
        T_rel = gt.T_cam_naocs_part(gt.joint_parents[k]).inverse() @ gt.T_cam_naocs_part(gt.joint_children[k])
        a, p, theta = gt.joint_axes_naocs[k], gt.joint_pivots_naocs[k], gt.joint_states[k]
        if gt.joint_types[k] == JointType.REVOLUTE:
            R = axis_angle_matrix(a, theta)
            expected = Sim3(R, p - R @ p)
        else:
            expected = Sim3(np.eye(3), s_naocs * theta * a)
        assert T_rel.allclose(expected, atol=TOL), (k, T_rel, expected)


@pytest.mark.parametrize("seed", SEEDS)
def test_naocs_invariant_to_joint_state_and_camera(seed):
    """The same material points give the same NAOCS at rest and at any state, from any camera."""
    rng = np.random.default_rng(seed)
    model = random_articulated_model(rng, num_parts=4, tree=seed % 2 == 1, random_canonical=seed % 2 == 0)
    local = [trimesh.sample.sample_surface(p.mesh, 50, seed=seed)[0] for p in model.parts]
    labels = np.repeat(np.arange(model.num_parts), 50)
    results = []
    for q in (model.rest_states, model.random_states(rng), model.random_states(rng)):
        T_cam_base = random_camera_pose(rng)
        poses = model.forward_kinematics(q)
        pts = np.concatenate([T_cam_base.apply(poses[j].apply(v)) for j, v in enumerate(local)])
        results.append(ancsh_ground_truth(model, q, T_cam_base, pts, labels))
    for gt in results[1:]:
        np.testing.assert_allclose(gt.naocs, results[0].naocs, atol=TOL)
        np.testing.assert_allclose(gt.npcs, results[0].npcs, atol=TOL)
        np.testing.assert_array_equal(gt.joint_association, results[0].joint_association)
        np.testing.assert_allclose(gt.joint_targets, results[0].joint_targets, atol=TOL)
    np.testing.assert_allclose(results[0].joint_states, 0.0, atol=0)


@pytest.mark.parametrize("seed", SEEDS)
def test_association_and_targets(seed):
    model, _, gt = _random_case(seed)
    sigma = 0.2
    dist = np.full((len(gt.naocs), model.num_joints), np.inf)
    for k in range(model.num_joints):
        if gt.joint_types[k] == JointType.REVOLUTE:
            on = np.isin(gt.part_labels, [gt.joint_parents[k], gt.joint_children[k]])
            d = _line_distance(gt.naocs, gt.joint_pivots_naocs[k], gt.joint_axes_naocs[k])
            dist[on & (d <= sigma), k] = d[on & (d <= sigma)]
    has_revolute = np.isfinite(dist).any(axis=1)
    for i in range(len(gt.naocs)):
        a = gt.joint_association[i]
        t = gt.joint_targets[i]
        prismatic = [k for k in range(model.num_joints)
                     if gt.joint_types[k] == JointType.PRISMATIC and gt.joint_children[k] == gt.part_labels[i]]
        if has_revolute[i]:
            k = int(np.argmin(dist[i]))
            assert a == k + 1
            np.testing.assert_allclose(t[:3], gt.joint_axes_naocs[k], atol=TOL)
            assert t[6] == pytest.approx(dist[i, k], abs=TOL)
            if t[6] > 1e-9:
                assert np.linalg.norm(t[3:6]) == pytest.approx(1.0, abs=TOL)
                assert abs(t[3:6] @ t[:3]) < TOL
                # Moving by the distance along the direction lands on the axis.
                foot = gt.naocs[i] + t[6] * t[3:6]
                assert _line_distance(foot, gt.joint_pivots_naocs[k], t[:3])[0] < TOL
        elif prismatic:
            assert a == prismatic[0] + 1
            np.testing.assert_allclose(t[:3], gt.joint_axes_naocs[prismatic[0]], atol=TOL)
            np.testing.assert_array_equal(t[3:], 0.0)
        else:
            assert a == 0
            np.testing.assert_array_equal(t, 0.0)


def _hinge_model(joint_type="revolute"):
    """Base cube [-1,0]x[-0.5,0.5]^2 and a lid cube [0,1]x[-0.5,0.5]^2, joint along z through the origin.

    The object box is 2 x 1 x 1 (diagonal sqrt(6)), centred at the origin, so NAOCS = base / sqrt(6).
    """
    base = Part("base", _box((1.0, 1.0, 1.0), (-0.5, 0.0, 0.0)))
    lid = Part("lid", _box((1.0, 1.0, 1.0), (0.5, 0.0, 0.0)))
    lower, upper = (-1.0, 1.0) if joint_type == "revolute" else (0.0, 0.5)
    joint = Joint("j", joint_type, "base", "lid", [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], lower, upper, 0.0)
    return ArticulatedModel((base, lid), (joint,))


def test_association_hand_built_hinge():
    """Points at known distances from a hinge along z: only those within sigma (NAOCS units) are associated."""
    model = _hinge_model()
    diag = np.sqrt(6.0)
    # x positions in metres on base (x < 0) and lid (x > 0); NAOCS distance = |x| / diag.
    xs = np.array([-0.9, -0.45, -0.3, 0.1, 0.48, 0.5, 0.8])
    pts = np.stack([xs, np.full_like(xs, 0.5), np.zeros_like(xs)], axis=1)  # on the y = 0.5 face
    labels = (xs > 0).astype(int)
    gt = ancsh_ground_truth(model, [0.0], Sim3(), pts, labels, sigma=0.2)
    d = np.hypot(xs, 0.5) / diag
    np.testing.assert_array_equal(gt.joint_association, (d <= 0.2).astype(int))
    assoc = gt.joint_association == 1
    np.testing.assert_allclose(gt.joint_targets[assoc, 6], d[assoc], atol=TOL)
    expected_dir = -np.stack([xs, np.full_like(xs, 0.5), np.zeros_like(xs)], axis=1) / np.hypot(xs, 0.5)[:, None]
    np.testing.assert_allclose(gt.joint_targets[assoc, 3:6], expected_dir[assoc], atol=TOL)
    np.testing.assert_array_equal(gt.joint_targets[~assoc], 0.0)
    # A point exactly on the axis: distance 0, zero direction, axis filled.
    on_axis = ancsh_ground_truth(model, [0.0], Sim3(), [[0.0, 0.0, 0.3]], [1])
    np.testing.assert_allclose(on_axis.joint_targets[0], [0, 0, 1, 0, 0, 0, 0], atol=TOL)


def test_prismatic_hand_built_state_and_association():
    """Lid sliding +0.2 m along the joint axis z: NAOCS of lid points undo the slide; all lid points associated, axis only."""
    model = _hinge_model("prismatic")
    R = random_rotation(3)
    T_cam_base = Sim3(R, [0.1, -0.2, 1.5])
    lid_pts = np.array([[0.5, 0.5, 0.0], [1.0, 0.1, -0.5], [0.2, -0.5, 0.3]])
    base_pts = np.array([[-0.5, 0.5, 0.0]])
    moved = np.concatenate([base_pts, lid_pts + [0.0, 0.0, 0.2]])
    gt = ancsh_ground_truth(model, [0.2], T_cam_base, T_cam_base.apply(moved), [0, 1, 1, 1])
    np.testing.assert_allclose(gt.naocs, np.concatenate([base_pts, lid_pts]) / np.sqrt(6.0), atol=TOL)
    np.testing.assert_allclose(gt.joint_states, [0.2], atol=TOL)
    np.testing.assert_array_equal(gt.joint_association, [0, 1, 1, 1])
    np.testing.assert_allclose(gt.joint_targets[1:], np.tile([0, 0, 1, 0, 0, 0, 0], (3, 1)), atol=TOL)
    np.testing.assert_allclose(gt.joint_axes_cam[0], R[:, 2], atol=TOL)


def test_revolute_wins_over_prismatic_and_nearest_revolute_wins():
    """Chain base -(prismatic)- slider -(revolute)- flap: slider points near the hinge go to the hinge."""
    base = Part("base", _box((1.0, 1.0, 1.0), (-0.5, 0.0, 0.0)))
    slider = Part("slider", _box((1.0, 1.0, 1.0), (0.5, 0.0, 0.0)))
    flap = Part("flap", _box((1.0, 1.0, 1.0), (0.5, 0.0, 0.0)))
    joints = (
        Joint("slide", "prismatic", "base", "slider", [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0.0, 0.5, 0.0),
        Joint("hinge", "revolute", "slider", "flap", [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], -1.0, 1.0, 0.0,
              Sim3(np.eye(3), [1.0, 0.0, 0.0])),
    )
    model = ArticulatedModel((base, slider, flap), joints)
    # Slider points: near the hinge (x = 0.95) and far from it (x = 0.1).
    pts = np.array([[0.95, 0.0, 0.0], [0.1, 0.0, 0.0], [1.05, 0.0, 0.2]])
    gt = ancsh_ground_truth(model, [0.0, 0.0], Sim3(), pts, [1, 1, 2])
    np.testing.assert_array_equal(gt.joint_association, [2, 1, 2])


def test_part_order_does_not_matter():
    """Listing the parts in reverse order (base last) permutes the ground truth and changes nothing else."""
    model = random_articulated_model(11, num_parts=4, tree=True, random_canonical=True)
    reordered = ArticulatedModel(model.parts[::-1], model.joints, R_canon_base=model.R_canon_base)
    assert reordered.base_index == 3
    f = sample_frame(model, 12, points_per_part=40)
    gt = ancsh_ground_truth(model, f.q, f.T_cam_base, f.points_cam, f.part_labels)
    gt_r = ancsh_ground_truth(reordered, f.q, f.T_cam_base, f.points_cam, 3 - f.part_labels)
    np.testing.assert_allclose(gt_r.naocs, gt.naocs, atol=TOL)
    np.testing.assert_allclose(gt_r.npcs, gt.npcs, atol=TOL)
    np.testing.assert_allclose(gt_r.npcs_scale, gt.npcs_scale[::-1], atol=TOL)
    np.testing.assert_array_equal(gt_r.joint_association, gt.joint_association)
    np.testing.assert_array_equal(gt_r.joint_parents, 3 - gt.joint_parents)
    np.testing.assert_allclose(gt_r.joint_pivots_cam, gt.joint_pivots_cam, atol=TOL)
    assert gt_r.T_cam_naocs.allclose(gt.T_cam_naocs, atol=TOL)
    for j in range(4):
        assert gt_r.T_cam_npcs[3 - j].allclose(gt.T_cam_npcs[j], atol=TOL)


# --- input errors ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def case():
    model = random_articulated_model(5, num_parts=3)
    frame = sample_frame(model, 6, points_per_part=10)
    return model, frame


def test_bad_inputs_raise(case):
    model, f = case
    with pytest.raises(ValueError, match="points_cam"):
        ancsh_ground_truth(model, f.q, f.T_cam_base, f.points_cam[:, :2], f.part_labels)
    with pytest.raises(ValueError, match="points_cam"):
        bad = f.points_cam.copy()
        bad[0, 0] = np.nan
        ancsh_ground_truth(model, f.q, f.T_cam_base, bad, f.part_labels)
    with pytest.raises(ValueError, match="part_labels: expected shape"):
        ancsh_ground_truth(model, f.q, f.T_cam_base, f.points_cam, f.part_labels[:-1])
    with pytest.raises(ValueError, match="part_labels: label 3 out of range"):
        ancsh_ground_truth(model, f.q, f.T_cam_base, f.points_cam, np.full(len(f.points_cam), 3))
    with pytest.raises(ValueError, match="part_labels: label -1 out of range"):
        ancsh_ground_truth(model, f.q, f.T_cam_base, f.points_cam, np.full(len(f.points_cam), -1))
    with pytest.raises(ValueError, match="part_labels: expected integer"):
        ancsh_ground_truth(model, f.q, f.T_cam_base, f.points_cam, f.part_labels + 0.5)
    with pytest.raises(ValueError, match="q: expected shape"):
        ancsh_ground_truth(model, f.q[:1], f.T_cam_base, f.points_cam, f.part_labels)
    with pytest.raises(ValueError, match="q: state .* outside its limits"):
        ancsh_ground_truth(model, model.upper_limits + 0.1, f.T_cam_base, f.points_cam, f.part_labels)
    with pytest.raises(ValueError, match="T_cam_base: expected a Sim3"):
        ancsh_ground_truth(model, f.q, np.eye(4), f.points_cam, f.part_labels)
    with pytest.raises(ValueError, match="sigma"):
        ancsh_ground_truth(model, f.q, f.T_cam_base, f.points_cam, f.part_labels, sigma=0.0)
    with pytest.raises(ValueError, match="model: expected an ArticulatedModel"):
        canonical_space("laptop")
    with pytest.raises(ValueError, match="has no mesh"):
        canonical_space(ArticulatedModel((Part("base"),), ()))


def test_joint_association_bad_inputs():
    axes, pivots = np.array([[0.0, 0.0, 1.0]]), np.zeros((1, 3))
    pts = np.zeros((4, 3))
    with pytest.raises(ValueError, match="part_labels: expected shape"):
        joint_association(pts, [0, 1], ["revolute"], [0], [1], axes, pivots)
    with pytest.raises(ValueError, match="joint_parents, joint_children"):
        joint_association(pts, [0, 1, 0, 1], ["revolute"], [0, 1], [1], axes, pivots)
    with pytest.raises(ValueError, match="axes_naocs: expected shape"):
        joint_association(pts, [0, 1, 0, 1], ["revolute"], [0], [1], axes[0], pivots)
    with pytest.raises(ValueError, match="sigma"):
        joint_association(pts, [0, 1, 0, 1], ["revolute"], [0], [1], axes, pivots, sigma=np.inf)
    with pytest.raises(ValueError, match="axes_naocs: expected unit vectors"):
        joint_association(pts, [0, 1, 0, 1], ["revolute"], [0], [1], 2 * axes, pivots)


def test_integer_valued_float_labels_and_empty_points_accepted(case):
    model, f = case
    gt = ancsh_ground_truth(model, f.q, f.T_cam_base, f.points_cam, f.part_labels.astype(float))
    np.testing.assert_array_equal(gt.part_labels, f.part_labels)
    empty = ancsh_ground_truth(model, f.q, f.T_cam_base, np.zeros((0, 3)), np.zeros(0, dtype=int))
    assert empty.npcs.shape == (0, 3) and empty.joint_targets.shape == (0, 7)
    assert len(empty.T_cam_npcs) == model.num_parts


def test_results_are_read_only(case):
    model, f = case
    gt = ancsh_ground_truth(model, f.q, f.T_cam_base, f.points_cam, f.part_labels)
    with pytest.raises(ValueError):
        gt.npcs[0, 0] = 1.0
    with pytest.raises(ValueError, match="j: expected a part index"):
        gt.T_naocs_npcs(model.num_parts)
