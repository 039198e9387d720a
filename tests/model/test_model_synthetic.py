"""Seeded random articulated models: deterministic, well-formed, sensible sizes, chains and trees."""

import numpy as np
import pytest

from ancsh.geometry.transforms import Sim3
from ancsh.model import JointType, random_articulated_model, random_camera_pose, sample_frame


def _parent_indices(model):
    return [model.joint_parts(k)[0] for k in range(model.num_joints)]


def test_same_seed_same_model_different_seed_different():
    a = random_articulated_model(7, num_parts=4, tree=True)
    b = random_articulated_model(np.random.default_rng(7), num_parts=4, tree=True)
    c = random_articulated_model(8, num_parts=4, tree=True)
    for pa, pb in zip(a.parts, b.parts):
        np.testing.assert_array_equal(pa.vertices, pb.vertices)
    for ja, jb in zip(a.joints, b.joints):
        np.testing.assert_array_equal(ja.axis, jb.axis)
        assert (ja.lower, ja.upper, ja.rest, ja.type) == (jb.lower, jb.upper, jb.rest, jb.type)
    assert not np.allclose(a.parts[0].vertices, c.parts[0].vertices)


@pytest.mark.parametrize("seed", range(20))
def test_parts_and_joints_well_formed(seed):
    model = random_articulated_model(seed, num_parts=5, tree=seed % 2 == 1, random_canonical=True)
    assert model.num_parts == 5 and model.num_joints == 4 and model.base_index == 0
    for part in model.parts:
        v = part.vertices
        # A box: its edges (distances between vertices along the box axes) are 0.05-0.5 m.
        edges = sorted(np.linalg.norm(v[1:] - v[0], axis=1))[:3]
        assert all(0.05 <= e <= 0.5 for e in edges)
        assert part.mesh.is_watertight and part.mesh.volume > 0.05**3 * 0.99
    for j in model.joints:
        assert j.lower < j.upper and j.lower <= j.rest <= j.upper
        assert np.isfinite(j.lower) and np.isfinite(j.upper)
        if j.type == JointType.PRISMATIC:
            assert j.upper - j.lower >= 0.05
        else:
            assert j.upper - j.lower >= 0.4


def test_chain_and_tree_structure():
    chain = random_articulated_model(0, num_parts=5)
    assert _parent_indices(chain) == [0, 1, 2, 3]
    for seed in range(15):
        tree = random_articulated_model(seed, num_parts=5, tree=True)
        par = _parent_indices(tree)
        assert max(par.count(p) for p in set(par)) >= 2, par  # branching
        assert any(p != 0 for p in par), par  # a part hanging off a non-base part
    star = random_articulated_model(1, num_parts=3, tree=True)
    assert _parent_indices(star) == [0, 0]
    explicit = random_articulated_model(2, num_parts=4, parents=[0, 1, 1])
    assert _parent_indices(explicit) == [0, 1, 1]


def test_joint_types_argument():
    m = random_articulated_model(0, num_parts=4, joint_types="prismatic")
    assert all(j.type == JointType.PRISMATIC for j in m.joints)
    m = random_articulated_model(0, num_parts=3, joint_types=["revolute", JointType.PRISMATIC])
    assert [j.type for j in m.joints] == [JointType.REVOLUTE, JointType.PRISMATIC]
    m = random_articulated_model(0, num_parts=3, joint_types="revolute", unlimited_revolute=True)
    assert all(j.lower == -np.inf and j.upper == np.inf for j in m.joints)
    kinds = {j.type for s in range(10) for j in random_articulated_model(s, num_parts=4).joints}
    assert kinds == {JointType.REVOLUTE, JointType.PRISMATIC}
    single = random_articulated_model(0, num_parts=1)
    assert single.num_joints == 0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(num_parts=0), "num_parts: expected an integer >= 1"),
        (dict(num_parts=2.5), "num_parts: expected an integer >= 1"),
        (dict(num_parts=3, joint_types=["revolute"]), "joint_types: expected 2 types"),
        (dict(num_parts=2, joint_types="ball"), "joint_types: each must be"),
        (dict(num_parts=2, tree=True), "branching tree needs at least 3 parts"),
        (dict(num_parts=3, parents=[0, 2]), "parent of part 2 must be in 0..1"),
        (dict(num_parts=3, parents=[0]), "parents: expected 2 entries"),
        (dict(num_parts=3, parents=[0, 0], tree=True), "either parents or tree"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        random_articulated_model(0, **kwargs)


def test_bad_rng():
    with pytest.raises(TypeError, match="rng"):
        random_articulated_model("seed")


def test_camera_pose_and_frame():
    rng = np.random.default_rng(3)
    for _ in range(20):
        T = random_camera_pose(rng, distance=(1.0, 2.0))
        assert T.is_rigid and 1.0 <= np.linalg.norm(T.translation) <= 2.0 and T.translation[2] > 0.9
    with pytest.raises(ValueError, match="distance"):
        random_camera_pose(rng, distance=(2.0, 1.0))
    model = random_articulated_model(4, num_parts=3)
    f = sample_frame(model, 5, points_per_part=30)
    assert f.points_cam.shape == (90, 3) and f.part_labels.dtype == np.int64
    model.check_states(f.q)
    # Points are the base-frame surface points mapped by the camera pose.
    g = sample_frame(model, 9, points_per_part=30, q=f.q, T_cam_base=Sim3())
    h = sample_frame(model, 9, points_per_part=30, q=f.q, T_cam_base=f.T_cam_base)
    np.testing.assert_allclose(h.points_cam, f.T_cam_base.apply(g.points_cam), atol=1e-12)
    np.testing.assert_array_equal(h.part_labels, np.repeat([0, 1, 2], 30))
    with pytest.raises(ValueError, match="T_cam_base: expected a Sim3"):
        sample_frame(model, 5, T_cam_base=np.eye(4))
    with pytest.raises(ValueError, match="points_per_part"):
        sample_frame(model, 5, points_per_part=-1)
    with pytest.raises(ValueError, match="q: state"):
        sample_frame(model, 5, q=model.upper_limits + 1.0)
