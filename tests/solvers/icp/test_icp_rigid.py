"""Rigid ICP baselines and reading joint states off part poses."""

import numpy as np
import pytest

from ancsh.geometry.rotations import exp_so3, random_rotation
from ancsh.geometry.transforms import Sim3
from ancsh.model import random_articulated_model
from ancsh.solvers.icp import ArticulatedPose, joint_states_from_part_poses, per_part_icp, whole_object_icp
from ancsh.solvers.types import FitStatus
from ancsh.solvers.icp.rigid import RigidIcpConfig, sample_with_normals


@pytest.mark.parametrize("seed", [0, 1])
def test_joint_states_from_part_poses_inverts_forward_kinematics(seed):
    rng = np.random.default_rng(seed)
    model = random_articulated_model(rng, 4, tree=True)
    q = model.random_states(rng)
    T = Sim3(random_rotation(rng), rng.normal(size=3))
    poses = [T @ P for P in model.forward_kinematics(q)]
    np.testing.assert_allclose(joint_states_from_part_poses(model, poses), q, atol=1e-9)
    with pytest.raises(ValueError, match="T_cam_parts"):
        joint_states_from_part_poses(model, poses[:-1])


def _observation(seed):
    rng = np.random.default_rng(seed)
    model = random_articulated_model(rng, 3)
    q = model.random_states(rng)
    T = Sim3(random_rotation(rng), np.array([0.0, 0.0, 2.0]))
    pts, labels = model.surface_points(q, 400, rng)
    return model, q, T, T.apply(pts), labels


def test_whole_object_icp_recovers_a_small_rigid_offset():
    """With the true joint states, one rigid ICP removes a small pose error."""
    model, q, T, pts, _ = _observation(2)
    init = ArticulatedPose(Sim3(exp_so3([0.03, -0.02, 0.02]) @ T.rotation, T.translation + 0.01), q)
    res = whole_object_icp(model, pts, init)
    assert res.ok
    for est, true in zip(res.T_cam_parts, [T @ P for P in model.forward_kinematics(q)]):
        np.testing.assert_allclose(est.rotation, true.rotation, atol=5e-3)
        np.testing.assert_allclose(est.translation, true.translation, atol=5e-3)


def test_per_part_icp_with_true_labels_recovers_every_part():
    model, q, T, pts, labels = _observation(3)
    init = ArticulatedPose(Sim3(exp_so3([0.03, 0.0, -0.02]) @ T.rotation, T.translation - 0.01), q)
    res = per_part_icp(model, pts, init, labels=labels)
    for est, true in zip(res.T_cam_parts, [T @ P for P in model.forward_kinematics(q)]):
        np.testing.assert_allclose(est.translation, true.translation, atol=5e-3)
    np.testing.assert_allclose(res.q, q, atol=2e-2)


def test_rigid_baselines_report_failure_on_empty_input():
    model, q, T, _, _ = _observation(4)
    init = ArticulatedPose(T, q)
    for fit in (whole_object_icp, per_part_icp):
        res = fit(model, np.zeros((0, 3)), init)
        assert res.status == FitStatus.TOO_FEW_POINTS and "points" in res.message
    far = per_part_icp(model, np.random.default_rng(0).normal(size=(50, 3)) + [0, 0, 50.0], init)
    assert not far.ok
    with pytest.raises(ValueError, match="labels"):
        per_part_icp(model, np.zeros((4, 3)) + [0, 0, 2.0], init, labels=np.zeros(3, dtype=int))
    with pytest.raises(ValueError, match="max_distance"):
        RigidIcpConfig(max_distance=0.0)


def test_samples_lie_on_the_mesh_with_unit_normals():
    import trimesh

    box = trimesh.creation.box((0.2, 0.4, 0.6))
    p, n = sample_with_normals(box, 500, 0)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    # every sample lies on a face: one coordinate at the half extent, along the normal
    np.testing.assert_allclose(np.abs(np.sum(p * n, axis=1)), np.abs(n) @ np.array([0.1, 0.2, 0.3]), atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, match",
    [(dict(max_iterations=True), "max_iterations"), (dict(max_iterations=2.7), "max_iterations"),
     (dict(samples_per_part=9), "samples_per_part"), (dict(point_to_plane=1), "point_to_plane"),
     (dict(max_distance=float("inf")), "max_distance")],
)
def test_rigid_config_rejects_non_integer_and_out_of_range_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RigidIcpConfig(**kwargs)


def test_rigid_baselines_report_max_iter_when_the_iteration_limit_stops_them():
    """One ICP iteration from a 0.1 rad / 3 cm offset does not converge: MAX_ITER, not SUCCESS;
    the iteration count is not reported by open3d (-1)."""
    model, q, T, pts, labels = _observation(2)
    init = ArticulatedPose(Sim3(exp_so3([0.1, -0.05, 0.05]) @ T.rotation, T.translation + 0.03), q)
    one = RigidIcpConfig(max_iterations=1)
    for res in (whole_object_icp(model, pts, init, config=one), per_part_icp(model, pts, init, labels=labels, config=one)):
        assert res.status == FitStatus.MAX_ITER and "not converged" in res.message
        assert res.iterations == -1
    converged = whole_object_icp(model, pts, init, config=RigidIcpConfig(max_iterations=200))
    assert converged.status == FitStatus.SUCCESS and converged.message == "converged"
