"""Procedural categories: valid models, canonical orientation, rest states, determinism, split."""

from __future__ import annotations

import numpy as np
import pytest

from ancsh.data.procedural import (
    CATEGORIES,
    CATEGORY_INFO,
    instance_seeds,
    load_instance,
    make_object,
)
from ancsh.data.procedural import _mesh as m
from ancsh.model.articulated import ArticulatedModel

SEEDS_PER_CATEGORY = 20


def _seeds(category):
    train, test = instance_seeds(category, "train"), instance_seeds(category, "test")
    return train[: SEEDS_PER_CATEGORY - 4] + test[:4]


@pytest.fixture(scope="module")
def objects():
    return {c: [make_object(c, s) for s in _seeds(c)] for c in CATEGORIES}


def _world_vertices(model, q):
    poses = model.forward_kinematics(q)
    return [poses[i].apply(p.vertices) for i, p in enumerate(model.parts)]


def _bounds(v):
    return v.min(axis=0), v.max(axis=0)


# --- structure ---------------------------------------------------------------------------
@pytest.mark.parametrize("category", CATEGORIES)
def test_models_are_valid_and_follow_the_part_table(objects, category):
    info = CATEGORY_INFO[category]
    for model in objects[category]:
        assert isinstance(model, ArticulatedModel)
        assert model.category == category
        assert tuple(model.part_names) == info.part_names
        assert tuple(j.name for j in model.joints) == info.joint_names
        assert tuple(j.type for j in model.joints) == info.joint_types
        assert model.base_index == 0
        np.testing.assert_array_equal(model.R_canon_base, np.eye(3))
        for k, joint in enumerate(model.joints):
            assert model.joint_parts(k)[1] == k + 1
            assert np.isfinite(joint.lower) and np.isfinite(joint.upper) and joint.upper > joint.lower
        for part in model.parts:
            v = part.vertices
            assert len(part.mesh.faces) > 0 and v.shape[0] > 0
            assert np.all(np.isfinite(v))
            assert part.mesh.is_watertight, f"{model.name}: part {part.name} mesh not closed"
            assert part.mesh.volume > 0, f"{model.name}: part {part.name} mesh inside out"


@pytest.mark.parametrize("category", CATEGORIES)
def test_rest_size_within_the_stated_range(objects, category):
    lo, hi = CATEGORY_INFO[category].diagonal_range
    for model in objects[category]:
        v = np.concatenate(_world_vertices(model, model.rest_states))
        a, b = _bounds(v)
        diag = np.linalg.norm(b - a)
        assert lo <= diag <= hi, f"{model.name}: rest diagonal {diag:.3f} m outside [{lo}, {hi}]"


@pytest.mark.parametrize("category", CATEGORIES)
def test_forward_kinematics_moves_each_child_rigidly_about_its_joint(objects, category):
    rng = np.random.default_rng(7)
    for model in objects[category][:8]:
        for _ in range(3):
            q = model.random_states(rng)
            rest_v = _world_vertices(model, model.rest_states)
            moved_v = _world_vertices(model, q)
            np.testing.assert_allclose(moved_v[0], rest_v[0])  # the base never moves
            for k, joint in enumerate(model.joints):
                child = k + 1
                d_rest = np.linalg.norm(np.diff(rest_v[child][:50], axis=0), axis=1)
                d_moved = np.linalg.norm(np.diff(moved_v[child][:50], axis=0), axis=1)
                np.testing.assert_allclose(d_moved, d_rest, atol=1e-12)
                # all procedural joints hang off the base: compare with the joint's own motion
                T = joint.T_parent_child(q[k])
                np.testing.assert_allclose(moved_v[child], T.apply(model.parts[child].vertices), atol=1e-12)
                if joint.is_revolute:  # distances to the hinge line are preserved
                    def dist(p):
                        r = p - joint.pivot
                        return np.linalg.norm(r - np.outer(r @ joint.axis, joint.axis), axis=1)

                    np.testing.assert_allclose(dist(moved_v[child]), dist(rest_v[child]), atol=1e-9)


@pytest.mark.parametrize("category", CATEGORIES)
def test_states_outside_limits_are_rejected(objects, category):
    model = objects[category][0]
    q = model.upper_limits + 0.1
    with pytest.raises(ValueError, match="outside its limits"):
        model.forward_kinematics(q)


# --- canonical orientation and rest states ------------------------------------------------
@pytest.mark.parametrize("category", CATEGORIES)
def test_objects_stand_on_the_floor_upright(objects, category):
    for model in objects[category]:
        v = np.concatenate(_world_vertices(model, model.rest_states))
        a, b = _bounds(v)
        if category != "eyeglasses":
            assert abs(a[1]) < 1e-9, f"{model.name}: lowest point {a[1]} not on y = 0"
            # symmetric about x = 0 within a few cm (doors/handles may sit off-centre)
            assert abs(a[0] + b[0]) < 0.1 * (b[0] - a[0])


def test_laptop_display_opens_upwards_to_the_front(objects):
    for model in objects["laptop"]:
        rest = _world_vertices(model, model.rest_states)
        closed = _world_vertices(model, [0.0])
        base_top = rest[0][:, 1].max()
        # closed: the display lies on the base; at rest it stands behind the keyboard facing +z
        assert closed[1][:, 1].min() >= base_top - 0.002
        assert np.ptp(closed[1][:, 1]) < 0.03
        assert np.ptp(rest[1][:, 1]) > 0.15 and np.ptp(rest[1][:, 2]) < 0.03
        assert rest[1][:, 2].mean() < rest[0][:, 2].min() + 0.03


def test_box_lid_closes_the_top_and_opens_backwards_over_the_hinge(objects):
    caps = shells = 0
    for model in objects["box"]:
        base, lid = _world_vertices(model, [0.0])
        (b_lo, b_hi), (l_lo, l_hi) = _bounds(base), _bounds(lid)
        # closed: the lid is the top of the object and covers the body's walls (their top edges)
        assert l_hi[1] >= b_hi[1] - 1e-9
        w_lo, w_hi = _bounds(base[base[:, 1] >= b_hi[1] - 1e-9])
        assert l_lo[0] <= w_lo[0] + 1e-3 and l_hi[0] >= w_hi[0] - 1e-3
        if l_lo[1] < b_hi[1] - 1e-3:
            caps += 1  # a cap's rim hangs over the body's walls
        else:
            shells += 1
        thick = l_hi[1] - l_lo[1]
        # upright at 90 degrees: standing above the back edge, as thin along z as it was along y
        _, up = _world_vertices(model, [np.pi / 2])
        assert np.ptp(up[:, 2]) <= thick + 1e-6 and up[:, 2].mean() < b_lo[2] + 0.25 * (b_hi[2] - b_lo[2])
        assert up[:, 1].min() >= l_lo[1] - 0.007  # the hinge's offset behind the back face at most
        if model.joints[0].upper >= np.pi:  # flat open: behind the body
            _, flat = _world_vertices(model, [np.pi])
            assert flat[:, 2].max() <= b_lo[2] + 0.007
    assert caps and shells


def test_eyeglasses_temples_at_rest_are_at_right_angles_to_the_frame(objects):
    for model in objects["eyeglasses"]:
        verts = _world_vertices(model, model.rest_states)
        frame_a, frame_b = _bounds(verts[0])
        assert (frame_b - frame_a)[2] < 0.25 * (frame_b - frame_a)[0]  # the frame lies in the xy-plane
        for k, side in ((0, -1), (1, 1)):
            joint = model.joints[k]
            np.testing.assert_allclose(joint.axis, [0.0, side, 0.0])  # vertical hinges, positive folds
            assert np.sign(joint.pivot[0]) == side  # left temple at -x, right temple at +x
            v = verts[k + 1]
            a, b = _bounds(v)
            # straight back along -z, perpendicular to the frame
            assert b[2] <= joint.pivot[2] + 1e-9 and (b - a)[2] > 0.1
            assert (b - a)[0] < 0.01
            # folding swings the temple inwards, behind the frame
            q = model.rest_states.copy()
            q[k] = model.upper_limits[k]
            folded = _world_vertices(model, q)[k + 1]
            assert np.ptp(folded[:, 0]) > 0.1 and np.ptp(folded[:, 2]) < 0.05  # lies along x now
            mid_x = 0.5 * (folded[:, 0].min() + folded[:, 0].max())
            assert side * mid_x < side * joint.pivot[0] - 0.04  # towards the centre
            assert folded[:, 2].max() < frame_b[2]


def _side_door_opens_forwards(model):
    """A door on a vertical hinge: upright in front of the body, the free edge swings to +z."""
    joint = model.joints[0]
    np.testing.assert_allclose(np.abs(joint.axis), [0.0, 1.0, 0.0])
    rest = _world_vertices(model, model.rest_states)
    a, b = _bounds(rest[1])
    base_a, base_b = _bounds(rest[0])
    assert a[2] + b[2] > base_a[2] + base_b[2]  # in front of the body's centre (a thick door may be inset)
    assert b[2] >= base_b[2] - (b - a)[2]  # reaching the front face
    assert (b - a)[1] > (b - a)[2]  # upright
    side = np.sign(joint.axis[1])  # -y: hinged on the left (door to its right), +y: on the right
    assert side * (a[0] + b[0]) / 2 < side * joint.pivot[0]
    q = np.array([min(np.pi / 2, model.upper_limits[0])])
    opened = _world_vertices(model, q)[1]
    assert opened[:, 2].mean() > rest[1][:, 2].mean() + 0.05


def test_oven_door_closes_the_front_and_opens_forwards_and_down(objects):
    for model in objects["oven"]:
        joint = model.joints[0]
        if abs(joint.axis[1]) > 0.5:  # the side-hinged variant
            _side_door_opens_forwards(model)
            continue
        np.testing.assert_allclose(joint.axis, [1.0, 0.0, 0.0])
        rest = _world_vertices(model, model.rest_states)
        opened = _world_vertices(model, model.upper_limits)
        a, b = _bounds(rest[1])
        assert a[2] >= joint.pivot[2] - 1e-9 and (b - a)[1] > (b - a)[2]  # upright, in front of the body
        assert a[1] >= joint.pivot[1] - 1e-9  # the hinge is the door's bottom edge
        oa, ob = _bounds(opened[1])
        assert (ob - oa)[2] > (ob - oa)[1] and ob[1] < joint.pivot[1] + 0.08  # folded down, forwards


def _top_lid_opens_upwards(model):
    """A lid lying flat on top whose free edge (the front, or the side opposite a side hinge) rises."""
    joint = model.joints[0]
    a, b = _bounds(_world_vertices(model, model.rest_states)[1])
    assert (b - a)[1] < min((b - a)[0], (b - a)[2])  # lying flat
    assert a[1] >= joint.pivot[1] - 1e-9  # on top of the hinge line
    if abs(joint.axis[0]) > 0.5:  # hinged along its back edge: the lid lies in front of the hinge
        np.testing.assert_allclose(joint.axis, [-1.0, 0.0, 0.0])
        assert a[2] >= joint.pivot[2] - 1e-9
        free = (b - a)[2]
    else:  # hinged along its left (axis +z) or right (axis -z) edge: the lid lies on the other side
        np.testing.assert_allclose(np.abs(joint.axis), [0.0, 0.0, 1.0])
        left = joint.axis[2] > 0
        assert (a[0] >= joint.pivot[0] - 1e-9) if left else (b[0] <= joint.pivot[0] + 1e-9)
        free = (b - a)[0]
    q = np.array([min(np.pi / 2, model.upper_limits[0])])
    assert _world_vertices(model, q)[1][:, 1].max() > b[1] + 0.5 * free  # the free edge rose


def test_washing_machine_front_door_hinges_on_its_left_side_and_top_lid_at_its_back_or_side(objects):
    for model in objects["washing_machine"]:
        joint = model.joints[0]
        if abs(joint.axis[1]) < 0.5:  # top loader
            _top_lid_opens_upwards(model)
            continue
        a, b = _bounds(_world_vertices(model, model.rest_states)[1])
        np.testing.assert_allclose(joint.axis, [0.0, -1.0, 0.0])
        _side_door_opens_forwards(model)
        assert 0.5 < (b - a)[1] / (b - a)[0] < 2.0  # round-ish


def test_some_top_loaders_hinge_their_lid_along_a_side_edge():
    """Side hinges on both sides occur (issue #35), open upwards and obey the convention."""
    from ancsh.data.conventions import convention, convention_violations

    found = {}
    for seed in instance_seeds("washing_machine", "train"):
        model = make_object("washing_machine", seed)
        axis = model.joints[0].axis
        if abs(axis[2]) > 0.5:
            found.setdefault(float(np.sign(axis[2])), model)
        if len(found) == 2:
            break
    assert sorted(found) == [-1.0, 1.0]
    for model in found.values():
        _top_lid_opens_upwards(model)
        assert convention_violations(model, convention("washing_machine")) == [], model.name


@pytest.mark.parametrize("category", ["microwave", "safe"])
def test_side_hinged_doors_stand_in_front_and_open_forwards(objects, category):
    for model in objects[category]:
        _side_door_opens_forwards(model)


def test_drawers_at_rest_are_closed_inside_the_cabinet(objects):
    from ancsh.data.procedural.drawer import MAX_HANDLE_PROTRUSION

    for model in objects["drawer"]:
        verts = _world_vertices(model, model.rest_states)
        ca, cb = _bounds(verts[0])
        for k in (1, 2, 3):
            da, db = _bounds(verts[k])
            assert np.all(da[[0, 1]] >= ca[[0, 1]] - 1e-9) and np.all(db[[0, 1]] <= cb[[0, 1]] + 1e-9)
            assert da[2] >= ca[2] - 1e-9
            assert db[2] <= cb[2] + MAX_HANDLE_PROTRUSION
        # drawers are stacked bottom to top: lowest, middle, top
        centres = [verts[k][:, 1].mean() for k in (1, 2, 3)]
        assert centres[0] < centres[1] < centres[2]
        # opening pulls each drawer straight out towards +z
        q = model.upper_limits
        opened = _world_vertices(model, q)
        for k in (1, 2, 3):
            np.testing.assert_allclose(opened[k] - verts[k], np.tile([0.0, 0.0, q[k - 1]], (len(verts[k]), 1)), atol=1e-12)


# --- determinism and split ----------------------------------------------------------------
@pytest.mark.parametrize("category", CATEGORIES)
def test_same_seed_gives_identical_meshes_and_joints(category):
    a, b = make_object(category, 5), make_object(category, 5)
    c = make_object(category, 6)
    for pa, pb in zip(a.parts, b.parts):
        np.testing.assert_array_equal(pa.vertices, pb.vertices)
        np.testing.assert_array_equal(pa.mesh.faces, pb.mesh.faces)
    for ja, jb in zip(a.joints, b.joints):
        np.testing.assert_array_equal(ja.pivot, jb.pivot)
        assert (ja.lower, ja.upper, ja.rest) == (jb.lower, jb.upper, jb.rest)
    assert a.parts[0].vertices.shape != c.parts[0].vertices.shape or not np.allclose(a.parts[0].vertices, c.parts[0].vertices)


@pytest.mark.parametrize("category", CATEGORIES)
def test_split_is_fixed_disjoint_and_large_enough(category):
    train, test = instance_seeds(category, "train"), instance_seeds(category, "test")
    assert len(train) >= 100 and len(test) >= 10
    assert len(set(train)) == len(train) and len(set(test)) == len(test)
    assert not set(train) & set(test)
    assert instance_seeds(category, "train") == train
    model = load_instance(category, "test", 3)
    np.testing.assert_array_equal(model.parts[0].vertices, make_object(category, test[3]).parts[0].vertices)


@pytest.mark.parametrize("category", CATEGORIES)
def test_instances_vary_within_the_category(objects, category):
    diags = []
    for model in objects[category]:
        v = np.concatenate(_world_vertices(model, model.rest_states))
        a, b = _bounds(v)
        diags.append(b - a)
    diags = np.array(diags)
    # every box dimension varies across instances (relative spread > 3 %)
    assert np.all(diags.std(axis=0) / diags.mean(axis=0) > 0.03)
    assert len({round(float(j.upper), 6) for mdl in objects[category] for j in mdl.joints[:1]}) > 10


def test_bad_arguments_are_rejected():
    with pytest.raises(ValueError, match="category"):
        make_object("toaster", 0)
    with pytest.raises(ValueError, match="seed"):
        make_object(CATEGORIES[0], -1)
    with pytest.raises(ValueError, match="split"):
        instance_seeds(CATEGORIES[0], "val")
    with pytest.raises(ValueError, match="index"):
        load_instance(CATEGORIES[0], "test", len(instance_seeds(CATEGORIES[0], "test")))


# --- mesh helpers -------------------------------------------------------------------------
def test_ring_prism_is_closed_with_the_expected_volume():
    outer = m.outline_rounded_rect(0.4, 0.3, 0.05, n=64)
    inner = m.outline_superellipse(0.1, 0.1, 2.0, n=64)
    ring = m.ring_prism(outer, inner, 0.02)
    solid_outer, solid_inner = m.prism(outer, 0.02), m.prism(inner, 0.02)
    assert ring.is_watertight and solid_outer.is_watertight
    assert ring.volume == pytest.approx(solid_outer.volume - solid_inner.volume, rel=1e-9)
    # the rounded rectangle outline has the requested extents
    np.testing.assert_allclose(np.ptp(outer, axis=0), [0.4, 0.3], rtol=0.02)
    with pytest.raises(ValueError, match="inner"):
        m.ring_prism(outer, inner[:10], 0.02)


@pytest.mark.slow
@pytest.mark.parametrize("category", CATEGORIES)
def test_every_split_instance_is_valid_and_within_the_size_range(category):
    lo, hi = CATEGORY_INFO[category].diagonal_range
    for split, step in (("train", 4), ("test", 1)):  # every test instance, a quarter of the training ones
        for index in range(0, len(instance_seeds(category, split)), step):
            model = load_instance(category, split, index)
            for part in model.parts:
                assert part.mesh.is_watertight and np.all(np.isfinite(part.vertices)), f"{model.name}: {part.name}"
            v = np.concatenate(_world_vertices(model, model.rest_states))
            diag = np.linalg.norm(v.max(axis=0) - v.min(axis=0))
            assert lo <= diag <= hi, f"{model.name}: rest diagonal {diag:.3f} m outside [{lo}, {hi}]"


# --- variants (issue #11): every one occurs among the instances and obeys the convention ---------
# A small upper oven door: shorter than half the front, centred above its middle.
SMALL_DOOR_LENGTH_FRAC = 0.5
# A drawer column this far (fraction of the width) from the centre stands beside a knee space;
# drawers starting this high (fraction of the height) stand above a shelf.
SIDE_COLUMN_X = 0.15
RAISED_DRAWERS = 0.25
# Hooked temples drop several times as far as straight ones (ratio of the extremes).
TEMPLE_DROP_SPREAD = 3.0


def _variants(category, measured) -> set:
    """The variant labels that ``measured`` (measure_instance results) show for ``category``."""
    labels = set()
    for mm in measured:
        if "hinge" in mm:
            labels.add(f"{mm['door_on']}/{mm['hinge']}")
        if category == "oven" and mm["door_length_frac"] < SMALL_DOOR_LENGTH_FRAC and mm["door_centre_height_frac"] > 0.5:
            labels.add("small upper door")
        if category == "safe":
            labels.add("recessed door" if mm["door_recess_frac"] > 0 else "door on the face")
        if category == "drawer":
            if abs(mm["drawer_column_x"]) > SIDE_COLUMN_X:
                labels.add("side column")
            elif mm["drawers_bottom_frac"] > RAISED_DRAWERS:
                labels.add("above a shelf")
            else:
                labels.add("full stack")
    return labels


EXPECTED_VARIANTS = {
    "oven": {"front/bottom", "front/left", "front/right", "small upper door"},
    "washing_machine": {"front/left", "top/back"},
    "microwave": {"front/left", "front/right"},
    "safe": {"front/left", "front/right", "recessed door", "door on the face"},
    "drawer": {"side column", "above a shelf", "full stack"},
}


@pytest.mark.parametrize("category", CATEGORIES)
def test_every_variant_occurs_and_obeys_the_convention(objects, category):
    from ancsh.data.conventions import convention, convention_violations
    from ancsh.data.measure import measure_instance

    conv = convention(category)
    for model in objects[category]:
        assert convention_violations(model, conv) == [], model.name
    measured = [measure_instance(model, conv) for model in objects[category]]
    assert EXPECTED_VARIANTS.get(category, set()) <= _variants(category, measured)
    if category == "eyeglasses":  # straight and hooked temples
        drops = [mm["temple_drop_ratio"] for mm in measured]
        assert max(drops) > TEMPLE_DROP_SPREAD * min(drops)
