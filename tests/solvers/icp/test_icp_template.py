"""Template correspondences: closest points on the posed model recover the ANCSH ground truth."""

import numpy as np
import pytest

from ancsh.geometry.rotations import random_rotation
from ancsh.geometry.transforms import Sim3
from ancsh.model import ArticulatedModel, Part, ancsh_ground_truth, random_articulated_model
from ancsh.solvers.icp.template import ArticulatedPose, ModelSurface, TemplateProvider, robust_weights
from ancsh.solvers.types import CorrespondenceProvider, Observation


def _scene(seed, num_parts=3):
    rng = np.random.default_rng(seed)
    model = random_articulated_model(rng, num_parts)
    q = model.random_states(rng)
    T_cam_base = Sim3(random_rotation(rng), np.array([0.0, 0.0, 2.0]) + rng.normal(0, 0.1, 3))
    pts_base, labels = model.surface_points(q, 300, rng)
    return model, q, T_cam_base, T_cam_base.apply(pts_base), labels


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_template_at_truth_recovers_ground_truth_npcs(seed):
    """Surface points of a random model (all sides), matched at the true estimate, get the true NPCS."""
    model, q, T, pts, labels = _scene(seed)
    provider = TemplateProvider(model, ArticulatedPose(T, q), visible=False)
    assert isinstance(provider, CorrespondenceProvider)
    c = provider.correspond(Observation(pts))
    gt = ancsh_ground_truth(model, q, T, pts, labels)
    same = c.part_labels == labels
    # Points on a contact between two parts may match either part; nearly all match their own.
    assert same.mean() > 0.97
    np.testing.assert_allclose(c.npcs[same], gt.npcs[same], atol=1e-5)
    np.testing.assert_allclose(c.npcs_scale, gt.npcs_scale)
    np.testing.assert_allclose(c.joint_axes_naocs, gt.joint_axes_naocs)
    np.testing.assert_allclose(c.joint_limits[:, 0], model.lower_limits - model.rest_states)
    assert np.all(c.distances < 1e-5) and np.all(c.weights == 1.0)


def test_template_gates_far_points_and_weights_robustly():
    model, q, T, pts, _ = _scene(3)
    provider = TemplateProvider(model, ArticulatedPose(T, q), max_distance=0.05, loss="cauchy", loss_scale=0.01,
                                visible=False)
    far = pts[:5] + np.array([0.0, 0.0, 1.0])  # 1 m behind: farther than the gate
    c = provider.correspond(np.concatenate([pts, far]))
    assert np.all(c.weights[-5:] == 0.0)
    assert np.all(c.weights[:-5] > 0.99)
    assert provider.correspond(np.zeros((0, 3))).num_points == 0


def test_npcs_normals_are_unit():
    model, q, T, pts, _ = _scene(4)
    c = TemplateProvider(model, ArticulatedPose(T, q), visible=False).correspond(pts)
    np.testing.assert_allclose(np.linalg.norm(c.normals_npcs, axis=1), 1.0, atol=1e-6)


def test_robust_weights():
    r = np.array([0.0, 0.5, 1.0, 2.0])
    np.testing.assert_allclose(robust_weights(r, "huber", 1.0), [1, 1, 1, 0.5])
    np.testing.assert_allclose(robust_weights(r, "cauchy", 1.0), [1, 0.8, 0.5, 0.2])
    np.testing.assert_allclose(robust_weights(r, "tukey", 1.0), [1, 0.5625, 0, 0])
    np.testing.assert_allclose(robust_weights(r, "none", 1.0), 1.0)
    with pytest.raises(ValueError, match="loss"):
        robust_weights(r, "l7", 1.0)
    with pytest.raises(ValueError, match="scale"):
        robust_weights(r, "huber", 0.0)


def test_template_rejects_bad_input():
    import trimesh

    rigid = ArticulatedModel(parts=(Part("box", trimesh.creation.box((0.1, 0.1, 0.1))),), joints=())
    with pytest.raises(ValueError, match="no movable joint"):
        TemplateProvider(rigid)
    model, q, T, pts, _ = _scene(5)
    with pytest.raises(ValueError, match="estimate"):
        TemplateProvider(model).correspond(pts)
    with pytest.raises(ValueError, match="estimate.q"):
        TemplateProvider(model, ArticulatedPose(T, model.upper_limits + 1.0))
    with pytest.raises(ValueError, match="max_distance"):
        TemplateProvider(model, max_distance=-1)
    with pytest.raises(ValueError, match="mesh"):
        ModelSurface(_meshless())


def _meshless():
    from ancsh.model import Joint

    return ArticulatedModel(parts=(Part("a"), Part("b")), joints=(Joint("j", "revolute", "a", "b", axis=[0, 0, 1]),))


def test_visible_matching_avoids_the_back_face_of_a_thin_part():
    """A point in front of a thin slab, closer to its back face, is matched to the front face."""
    import trimesh

    from ancsh.model import Joint

    slab = trimesh.creation.box((0.4, 0.4, 0.01))  # faces at z = +-0.005 (part frame)
    model = ArticulatedModel(
        parts=(Part("a", slab), Part("b", trimesh.creation.box((0.1, 0.1, 0.1), transform=_shift([1.0, 0, 0])))),
        joints=(Joint("j", "revolute", "a", "b", axis=[0, 1, 0], lower=-1, upper=1),),
    )
    # Camera at the origin looking along +z; the slab sits 1 m away, the estimate 1 cm too close:
    # the observed front-face point (z = 0.995 m in the camera) is nearer the estimate's back face.
    est = ArticulatedPose(Sim3(np.eye(3), [0.0, 0.0, 0.99]), np.zeros(1))
    pts = np.array([[0.01, 0.02, 0.995], [-0.05, 0.03, 0.995]])
    surface = ModelSurface(model)
    poses = est.part_poses(model)
    plain = surface.closest(pts, poses)
    np.testing.assert_allclose(plain.points_part[:, 2], 0.005, atol=1e-6)  # back face (z = +0.005 -> 0.995 m)
    vis = surface.closest(pts, poses, visible=True)
    np.testing.assert_allclose(vis.points_part[:, 2], -0.005, atol=1e-6)  # front face, seen by the camera
    np.testing.assert_allclose(vis.distances, 0.01 * np.linalg.norm(pts, axis=1) / pts[:, 2], atol=1e-6)  # along the ray
    np.testing.assert_allclose(np.abs(vis.normals_part[:, 2]), 1.0, atol=1e-6)


def _shift(t):
    M = np.eye(4)
    M[:3, 3] = t
    return M


@pytest.mark.parametrize("formulation", ["per_part", "soft", "exact_reduced"])
def test_solver_core_formulations_fit_template_correspondences(formulation):
    """The template is a CorrespondenceProvider: the core's fit() recovers the pose from it."""
    from ancsh.solvers import FitConfig, fit

    model, q, T, pts, _ = _scene(6, num_parts=2)
    provider = TemplateProvider(model, ArticulatedPose(T, q), visible=False)
    obs = Observation(pts)
    res = fit(obs, provider.correspond(obs), formulation=formulation, config=FitConfig(ransac=False), rng=0)
    assert res.ok, res.message
    for est, true in zip(res.T_cam_npcs, [T @ P @ Tn.inverse() for P, Tn in zip(model.forward_kinematics(q), provider.T_npcs_part)]):
        np.testing.assert_allclose(est.translation, true.translation, atol=1e-4)
        np.testing.assert_allclose(est.rotation, true.rotation, atol=1e-4)
    np.testing.assert_allclose(res.joint_states, q - model.rest_states, atol=1e-4)


def test_template_is_built_once_per_model_and_does_not_import_the_rigid_baselines():
    import ast
    import inspect

    import ancsh.solvers.icp.template as template_module
    from ancsh.solvers.icp.template import ModelTemplate

    imports = [n.module for n in ast.walk(ast.parse(inspect.getsource(template_module))) if isinstance(n, ast.ImportFrom)]
    assert "rigid" not in imports  # rigid.py imports template.py, never the reverse
    model = random_articulated_model(np.random.default_rng(0), 3)
    template = ModelTemplate(model)
    provider = TemplateProvider(template)
    moved = provider.at(ArticulatedPose(Sim3(), model.rest_states))
    assert moved.template is template and moved.surface is template.surface
    with pytest.raises(ValueError, match="surface"):
        ModelTemplate(model, surface=ModelTemplate(random_articulated_model(np.random.default_rng(1), 3)).surface)
