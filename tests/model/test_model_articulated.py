"""ArticulatedModel: validation on construction and forward kinematics on hand-built cases."""

import numpy as np
import pytest
import trimesh

from ancsh.geometry.rotations import axis_angle_matrix, random_rotation
from ancsh.geometry.transforms import Sim3
from ancsh.model import ArticulatedModel, Joint, JointType, Part, random_articulated_model, sample_surface

TOL = 1e-12


def _parts(*names):
    return tuple(Part(n, trimesh.creation.box(extents=(0.1, 0.2, 0.3))) for n in names)


def _rev(name, parent, child, **kw):
    kw.setdefault("lower", -1.0)
    kw.setdefault("upper", 1.0)
    return Joint(name, "revolute", parent, child, kw.pop("axis", [0.0, 0.0, 1.0]), **kw)


# --- validation ------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(axis=[0.0, 0.0, 2.0]), "axis: expected a unit vector"),
        (dict(axis=[0.0, 1.0]), "axis: expected shape"),
        (dict(lower=1.0, upper=-1.0), "lower limit 1.0 exceeds upper limit -1.0"),
        (dict(rest=2.0), "rest state 2.0 outside limits"),
        (dict(lower=np.nan), "limits and rest must be numbers"),
        (dict(type="ball"), "type must be 'revolute' or 'prismatic'"),
        (dict(type="prismatic", lower=-np.inf), "prismatic joint needs finite limits"),
        (dict(type="prismatic", upper=np.inf, lower=0.0), "prismatic joint needs finite limits"),
        (dict(child="a"), "parent and child are the same part"),
        (dict(origin=Sim3(scale=2.0)), "origin: expected a rigid Sim3"),
        (dict(name=""), "joint name"),
    ],
)
def test_joint_validation(kwargs, match):
    args = dict(name="j", type="revolute", parent="a", child="b", axis=[0.0, 0.0, 1.0], lower=-1.0, upper=1.0)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        Joint(**args)


def test_joint_accepts_unlimited_revolute_and_normalises_type():
    j = Joint("j", "revolute", "a", "b", [0.0, 1.0, 0.0])
    assert j.type is JointType.REVOLUTE and j.lower == -np.inf and j.upper == np.inf


def test_model_duplicate_part_names():
    with pytest.raises(ValueError, match=r"parts: duplicate part names \['a'\]"):
        ArticulatedModel(_parts("a", "a"), (_rev("j", "a", "a2"),))


def test_model_duplicate_joint_names():
    with pytest.raises(ValueError, match=r"joints: duplicate joint names \['j'\]"):
        ArticulatedModel(_parts("a", "b", "c"), (_rev("j", "a", "b"), _rev("j", "b", "c")))


def test_model_unknown_part():
    with pytest.raises(ValueError, match="child 'zz' is not a part"):
        ArticulatedModel(_parts("a", "b"), (_rev("j", "a", "zz"),))


def test_model_two_roots():
    with pytest.raises(ValueError, match="do not form one tree"):
        ArticulatedModel(_parts("a", "b", "c"), (_rev("j", "a", "b"),))


def test_model_two_parents():
    with pytest.raises(ValueError, match="more than one parent joint"):
        ArticulatedModel(_parts("a", "b", "c"), (_rev("j1", "a", "c"), _rev("j2", "b", "c")))


def test_model_cycle():
    # Root a is fine, but b -> c -> b is a cycle cut off from the root.
    with pytest.raises(ValueError, match="cycle or a disconnected part"):
        ArticulatedModel(_parts("a", "b", "c", "d"), (_rev("j1", "a", "d"), _rev("j2", "b", "c"), _rev("j3", "c", "b")))


def test_model_all_parts_children_is_cycle():
    with pytest.raises(ValueError, match="do not form one tree"):
        ArticulatedModel(_parts("a", "b"), (_rev("j1", "a", "b"), _rev("j2", "b", "a")))


def test_model_bad_elements():
    with pytest.raises(ValueError, match="parts: an articulated model needs at least one part"):
        ArticulatedModel((), ())
    with pytest.raises(ValueError, match="parts: expected Part objects"):
        ArticulatedModel(("a",), ())
    with pytest.raises(ValueError, match="R_canon_base: not a rotation"):
        ArticulatedModel(_parts("a"), (), R_canon_base=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="name: expected a non-empty string"):
        Part("")


def test_states_outside_limits_raise():
    model = ArticulatedModel(_parts("a", "b"), (_rev("hinge", "a", "b", lower=-0.5, upper=0.5),))
    with pytest.raises(ValueError, match=r"q: state 0.6 of joint 'hinge' outside its limits \[-0.5, 0.5\]"):
        model.forward_kinematics([0.6])
    with pytest.raises(ValueError, match=r"q: expected shape \(1,\)"):
        model.forward_kinematics([0.1, 0.2])
    with pytest.raises(ValueError, match="q: contains NaN"):
        model.forward_kinematics([np.nan])
    model.forward_kinematics([0.5])  # on the limit is fine


# --- forward kinematics ----------------------------------------------------------------
def test_revolute_quarter_turn_moves_known_point():
    """Hinge along +z through (1, 0, 0) in the parent: child point (2, 0, 0) goes to (1, 1, 0) at +90 deg."""
    joint = _rev("hinge", "base", "lid", pivot=[1.0, 0.0, 0.0], lower=-2.0, upper=2.0)
    model = ArticulatedModel(_parts("base", "lid"), (joint,))
    T = model.forward_kinematics([np.pi / 2])[1]
    np.testing.assert_allclose(T.apply(np.array([2.0, 0.0, 0.0])), [1.0, 1.0, 0.0], atol=TOL)
    np.testing.assert_allclose(T.apply(np.array([1.0, 0.0, 5.0])), [1.0, 0.0, 5.0], atol=TOL)  # on the axis
    assert model.forward_kinematics([0.0])[1].allclose(Sim3(), atol=TOL)


def test_revolute_with_origin_offset():
    """Origin moves the child by (0, 0, 1) first; the hinge along x through the parent origin then rotates it."""
    joint = Joint("j", "revolute", "a", "b", [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], -2.0, 2.0, 0.0, Sim3(np.eye(3), [0, 0, 1.0]))
    model = ArticulatedModel(_parts("a", "b"), (joint,))
    T = model.forward_kinematics([np.pi / 2])[1]
    np.testing.assert_allclose(T.apply(np.zeros(3)), [0.0, -1.0, 0.0], atol=TOL)
    np.testing.assert_allclose(T.rotation, axis_angle_matrix([1, 0, 0], np.pi / 2), atol=TOL)


def test_prismatic_translates_along_axis():
    joint = Joint("slide", "prismatic", "cabinet", "drawer", [0.0, 0.6, 0.8], [5.0, 5.0, 5.0], 0.0, 0.4, 0.0,
                  Sim3(np.eye(3), [1.0, 0.0, 0.0]))
    model = ArticulatedModel(_parts("cabinet", "drawer"), (joint,))
    T = model.forward_kinematics([0.25])[1]
    np.testing.assert_allclose(T.apply(np.zeros(3)), [1.0, 0.15, 0.2], atol=TOL)
    np.testing.assert_allclose(T.rotation, np.eye(3), atol=TOL)


def test_three_level_tree_composes():
    """base -> arm (revolute z at origin) -> hand (prismatic x in the arm frame, origin (1, 0, 0)); base -> side."""
    joints = (
        Joint("shoulder", "revolute", "base", "arm", [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], -2.0, 2.0),
        Joint("slide", "prismatic", "arm", "hand", [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0.0, 1.0, 0.0,
              Sim3(np.eye(3), [1.0, 0.0, 0.0])),
        Joint("side", "revolute", "base", "side", [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], -2.0, 2.0),
    )
    # Parts listed out of topological order on purpose.
    model = ArticulatedModel(_parts("hand", "side", "base", "arm"), joints)
    assert model.base_index == 2
    order = model.topological_order
    assert order[0] == 2 and order.index(3) < order.index(0)
    poses = model.forward_kinematics([np.pi / 2, 0.5, 0.0])
    # Hand origin: (1 + 0.5) along the arm's x, which the shoulder turned to +y.
    np.testing.assert_allclose(poses[0].apply(np.zeros(3)), [0.0, 1.5, 0.0], atol=TOL)
    np.testing.assert_allclose(poses[0].rotation, axis_angle_matrix([0, 0, 1], np.pi / 2), atol=TOL)
    # Composition: T_base_hand = T_base_arm @ T_arm_hand.
    assert poses[0].allclose(poses[3] @ joints[1].T_parent_child(0.5), atol=TOL)
    assert poses[2].allclose(Sim3(), atol=TOL) and poses[1].allclose(Sim3(), atol=TOL)
    # The slide's line in the base frame follows the arm.
    a, p = model.joint_line_in_base(1, [np.pi / 2, 0.5, 0.0])
    np.testing.assert_allclose(a, [0.0, 1.0, 0.0], atol=TOL)
    assert model.parent_joint(2) is None and model.parent_joint(0) == 1
    assert model.joint_parts(1) == (3, 0)


@pytest.mark.parametrize("seed", range(5))
def test_fk_matches_chain_product_on_random_models(seed):
    """For random trees, T_base_child = T_base_parent @ M(q) @ origin, and rotations stay rigid."""
    rng = np.random.default_rng(seed)
    model = random_articulated_model(rng, num_parts=5, tree=True)
    q = model.random_states(rng)
    poses = model.forward_kinematics(q)
    for k, j in enumerate(model.joints):
        p, c = model.joint_parts(k)
        assert poses[c].allclose(poses[p] @ j.motion(q[k]) @ j.origin, atol=1e-12)
        assert poses[c].is_rigid
        if j.is_revolute:
            # Points on the joint axis do not move relative to the parent.
            on_axis = j.pivot + 0.3 * j.axis
            T_pc = j.T_parent_child(q[k]) @ j.origin.inverse()
            np.testing.assert_allclose(T_pc.apply(on_axis), on_axis, atol=1e-12)


def test_random_states_within_limits_and_surface_points():
    model = random_articulated_model(3, num_parts=4)
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = model.random_states(rng)
        assert np.all(q >= model.lower_limits) and np.all(q <= model.upper_limits)
    pts, labels = model.surface_points(model.rest_states, 7, rng)
    assert pts.shape == (28, 3)
    np.testing.assert_array_equal(np.bincount(labels), [7, 7, 7, 7])


def test_sample_surface_on_box_faces():
    mesh = trimesh.creation.box(extents=(0.2, 0.4, 0.6))
    pts = sample_surface(mesh, 500, 1)
    half = np.array([0.1, 0.2, 0.3])
    assert np.all(np.abs(pts) <= half + 1e-12)
    # Every point lies on a face: one coordinate at +-half.
    assert np.all(np.min(np.abs(np.abs(pts) - half), axis=1) < 1e-12)
    np.testing.assert_allclose(sample_surface(mesh, 20, 4), sample_surface(mesh, 20, 4))
    with pytest.raises(ValueError, match="mesh: expected a trimesh"):
        sample_surface(None, 5, 0)
    mesh_less = ArticulatedModel((Part("a"),), ())
    with pytest.raises(ValueError, match="mesh: expected a trimesh"):
        mesh_less.surface_points([], 3, 0)


def test_lookup_errors():
    model = ArticulatedModel(_parts("a", "b"), (_rev("j", "a", "b"),))
    with pytest.raises(KeyError, match="part 'x' not in model"):
        model.part_index("x")
    with pytest.raises(KeyError, match="joint 'x' not in model"):
        model.joint_index("x")
    assert model.joint_index("j") == 0 and model.part_index("b") == 1
    with pytest.raises(ValueError, match="R_canon_base"):
        ArticulatedModel(_parts("a"), (), R_canon_base=random_rotation(0) * 2)


def test_with_limits_replaces_limits_only():
    """A seeded random model with wider limits: forward kinematics at every old state unchanged, the new
    limits accept states the old ones refused; limits that exclude the rest state, are unordered or of the
    wrong shape are refused by name."""
    from ancsh.model.edit import with_limits

    model = random_articulated_model(4, num_parts=3)
    lo, hi = model.lower_limits - 0.5, model.upper_limits + 0.5
    wide = with_limits(model, lo, hi)
    np.testing.assert_array_equal(wide.lower_limits, lo)
    np.testing.assert_array_equal(wide.upper_limits, hi)
    np.testing.assert_array_equal(wide.rest_states, model.rest_states)
    q = model.random_states(np.random.default_rng(0))
    for A, B in zip(wide.forward_kinematics(q), model.forward_kinematics(q)):
        np.testing.assert_allclose(A.matrix(), B.matrix(), atol=TOL)
    beyond = model.upper_limits + 0.25
    wide.check_states(beyond)
    with pytest.raises(ValueError, match="outside its limits"):
        model.check_states(beyond)
    with pytest.raises(ValueError, match="lower, upper"):
        with_limits(model, model.rest_states + 0.1, hi)
    with pytest.raises(ValueError, match="lower"):
        with_limits(model, lo[:-1], hi)
    with pytest.raises(ValueError, match="upper"):
        with_limits(model, lo, np.full_like(hi, np.nan))
