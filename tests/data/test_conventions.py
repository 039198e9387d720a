"""Category conventions: every procedural instance obeys its category's rules, measured on the
geometry, and the measurement catches each kind of violation."""

from __future__ import annotations

import numpy as np
import pytest

from ancsh.data.conventions import CONVENTIONS, convention, convention_violations, rest_diagonal
from ancsh.data.procedural import CATEGORIES, CATEGORY_INFO, instance_seeds, make_object
from ancsh.model.edit import reparameterized, restructured, scaled, with_orientation
from ancsh.geometry.rotations import axis_angle_matrix


def _some_seeds(category, n_train=4, n_test=2):
    return instance_seeds(category, "train")[:n_train] + instance_seeds(category, "test")[:n_test]


@pytest.mark.parametrize("category", CATEGORIES)
def test_procedural_instances_obey_their_convention(category):
    conv = convention(category)
    assert CATEGORY_INFO[category] is conv  # one definition
    for seed in _some_seeds(category):
        model = make_object(category, seed)
        assert convention_violations(model, conv) == [], model.name


@pytest.mark.slow
@pytest.mark.parametrize("category", CATEGORIES)
def test_every_procedural_instance_obeys_its_convention(category):
    conv = convention(category)
    for split in ("train", "test"):
        for seed in instance_seeds(category, split):
            model = make_object(category, seed)
            assert convention_violations(model, conv) == [], model.name


def test_conventions_are_consistent():
    for name, conv in CONVENTIONS.items():
        assert conv.name == name
        assert conv.part_names[0] == "base"
        assert len(conv.joints) == conv.num_parts - 1
        assert conv.rest_states.shape == (conv.num_joints,)
    with pytest.raises(ValueError, match="no convention"):
        convention("teapot")


def test_a_shifted_zero_is_not_closed():
    model = make_object("laptop", 0)
    # state 0 moved 0.4 rad into the opening: the display no longer lies on the base at 0
    shifted = reparameterized(model, 0, zero=0.4, rest=np.pi / 2 - 0.4)
    found = " ".join(convention_violations(shifted, convention("laptop")))
    assert "not closed" in found and "rest" in found


def test_a_flipped_direction_is_caught():
    model = make_object("oven", 0)
    flipped = reparameterized(model, 0, zero=0.0, sign=-1)
    assert any("cannot increase" in v for v in convention_violations(flipped, convention("oven")))


def test_swapped_temples_break_the_part_order():
    model = make_object("eyeglasses", 0)
    swapped = restructured(model, [0, 2, 1], model.part_names, [j.name for j in model.joints])
    assert any("ordered" in v for v in convention_violations(swapped, convention("eyeglasses")))


def test_a_backwards_orientation_puts_the_door_on_the_wrong_side():
    model = make_object("oven", 0)
    turned = with_orientation(model, axis_angle_matrix(np.array([0.0, 1.0, 0.0]), np.pi))
    assert any("front" in v for v in convention_violations(turned, convention("oven")))


def test_the_size_range_is_checked_in_metres():
    model = make_object("drawer", 0)
    assert any("diagonal" in v for v in convention_violations(scaled(model, 3.0), convention("drawer")))
    assert convention_violations(scaled(model, 3.0), convention("drawer"), units_metres=False) == []


def test_reparameterized_keeps_the_motion():
    model = make_object("washing_machine", 3)
    new = reparameterized(model, 0, zero=0.3, sign=-1, rest=-0.3)
    for q_new in (-0.5, -0.3, 0.0):
        old = model.forward_kinematics([0.3 - q_new])
        moved = new.forward_kinematics([q_new])
        assert old[1].allclose(moved[1], atol=1e-12)
    drawer = make_object("drawer", 1)
    new = reparameterized(drawer, 1, zero=0.05, sign=1)
    q = drawer.rest_states.copy()
    q[1] = 0.08
    q_new = q.copy()
    q_new[1] = 0.03
    for a, b in zip(drawer.forward_kinematics(q), new.forward_kinematics(q_new)):
        assert a.allclose(b, atol=1e-12)


def test_scaled_scales_geometry_and_prismatic_states():
    model = make_object("drawer", 2)
    big = scaled(model, 2.0)
    assert rest_diagonal(big) == pytest.approx(2 * rest_diagonal(model), rel=1e-12)
    np.testing.assert_allclose(big.upper_limits, 2 * model.upper_limits)
    q = 0.5 * model.upper_limits
    for a, b in zip(model.forward_kinematics(q), big.forward_kinematics(2 * q)):
        np.testing.assert_allclose(b.translation, 2 * a.translation, atol=1e-12)
        np.testing.assert_allclose(b.rotation, a.rotation, atol=1e-12)
    with pytest.raises(ValueError, match="factor"):
        scaled(model, -1.0)


def test_restructured_checks_its_arguments():
    model = make_object("eyeglasses", 0)
    with pytest.raises(ValueError, match="part_order"):
        restructured(model, [0, 1, 1], model.part_names)
    with pytest.raises(ValueError, match="base"):
        restructured(model, [1, 0, 2], model.part_names)


@pytest.mark.parametrize("category", CATEGORIES)
def test_batched_probe_equals_forward_kinematics(category):
    """The closed-state probe moves the child of every joint like forward kinematics does."""
    from ancsh.data import conventions as c

    model = make_object(category, 3)
    for k, joint in enumerate(model.joints):
        qs = np.linspace(joint.lower, joint.upper, 5)
        batch = c._child_vertices_at(model, k, qs)
        for i, q in enumerate(qs):
            np.testing.assert_allclose(batch[i], c._joint_pair(model, k, c._with_state(model, k, q))[1], atol=1e-12)


@pytest.mark.parametrize("category", CATEGORIES)
def test_the_category_range_holds_every_procedural_instances_limits(category):
    """The fits are bounded by the category's joint range (JointConvention.state_range): no instance of the generator
    may reach a state outside it, or its true state would be out of the fit's reach; closed joints start at 0."""
    conv = convention(category)
    ranges = np.array([j.state_range for j in conv.joints])
    for seed in instance_seeds(category, "train")[:10] + instance_seeds(category, "test")[:10]:
        model = make_object(category, seed)
        assert np.all(model.lower_limits >= ranges[:, 0] - 1e-9) and np.all(model.upper_limits <= ranges[:, 1] + 1e-9), (
            model.name, model.lower_limits, model.upper_limits, ranges)
    for j in conv.joints:
        if j.zero == "closed":
            assert j.state_range[0] == 0.0, j.name
    np.testing.assert_allclose(conv.joint_limits, ranges - conv.rest_states[:, None])
    with pytest.raises(ValueError, match="state_range"):
        type(conv.joints[0])("j", conv.joints[0].type, "base", "x", "closed", "opens", 0.5, "front", (), (0.0, 0.2))
