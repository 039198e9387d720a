"""Rotation augmentation of training frames (camera rotations about the camera centre)."""

import dataclasses

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from ancsh.learned.network.config import TrainConfig
from ancsh.learned.network.normals import estimate_normals
from ancsh.learned.training.train import Trainer, camera_rotations, refine_rotations, rotate_batch


def _centroids(rng, n):
    return rng.normal(size=(n, 3)) * [0.3, 0.3, 0.1] + [0.0, 0.0, 2.0]


def test_camera_rotations_are_rolls_and_tilts_within_their_bounds():
    rng = np.random.default_rng(0)
    c = _centroids(rng, 50)
    ray = c / np.linalg.norm(c, axis=1, keepdims=True)
    seeds = [[7, i] for i in range(len(c))]
    roll = camera_rotations(c, np.radians(12.0), 0.0, seeds)
    tilt = camera_rotations(c, 0.0, np.radians(8.0), seeds)
    for R in (roll, tilt):
        np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    v_roll, v_tilt = Rotation.from_matrix(roll).as_rotvec(), Rotation.from_matrix(tilt).as_rotvec()
    # a roll turns about the ray to the centroid (which it leaves in place); a tilt about an axis across it
    np.testing.assert_allclose(np.einsum("bij,bj->bi", roll, ray), ray, atol=1e-12)
    np.testing.assert_allclose(np.einsum("bi,bi->b", v_tilt, ray), 0.0, atol=1e-12)
    assert np.degrees(np.linalg.norm(v_roll, axis=1)).max() <= 12.0 + 1e-9
    assert np.degrees(np.linalg.norm(v_tilt, axis=1)).max() <= 8.0 + 1e-9
    assert np.degrees(np.linalg.norm(v_roll, axis=1)).max() > 6.0  # the range is used, not a token angle
    np.testing.assert_array_equal(camera_rotations(c, 0.2, 0.1, seeds), camera_rotations(c, 0.2, 0.1, seeds))
    assert not np.allclose(camera_rotations(c, 0.2, 0.1, seeds), camera_rotations(c, 0.2, 0.1, [[8, i] for i in range(50)]))
    with pytest.raises(ValueError, match="centroids_cam"):
        camera_rotations(c[:, :2], 0.1, 0.1, seeds)
    with pytest.raises(ValueError, match="seeds"):
        camera_rotations(c, 0.1, 0.1, seeds[:3])


def test_rotated_batch_keeps_canonical_targets_and_rotates_camera_joint_vectors(tiny_arrays):
    points, targets = tiny_arrays.batch(np.arange(len(tiny_arrays)))
    points, targets = points.double(), dataclasses.replace(targets, joint_cam=targets.joint_cam.double())
    R = camera_rotations(points.mean(dim=1).numpy(), np.radians(30.0), np.radians(20.0), range(len(points)))
    rotated, t2 = rotate_batch(points, targets, R)
    # a rotation about the camera centre: distances kept, the points (and their centroid) turned by R
    Rt = torch.from_numpy(R)
    torch.testing.assert_close(torch.cdist(rotated, rotated), torch.cdist(points, points))
    torch.testing.assert_close(rotated, torch.einsum("bij,bnj->bni", Rt, points))
    for name in ("labels", "npcs", "scale", "translation", "association", "joint", "joint_mask"):
        assert getattr(t2, name) is getattr(targets, name), name  # canonical-frame targets are untouched
    # camera-frame joint vectors: point + distance * direction is the foot on the axis before and after
    foot = points + targets.joint_cam[..., 6:] * targets.joint_cam[..., 3:6]
    foot2 = rotated + t2.joint_cam[..., 6:] * t2.joint_cam[..., 3:6]
    torch.testing.assert_close(foot2, torch.einsum("bij,bnj->bni", Rt, foot))
    torch.testing.assert_close(t2.joint_cam[..., :3], torch.einsum("bij,bnj->bni", Rt, targets.joint_cam[..., :3]))
    torch.testing.assert_close(t2.joint_cam[..., 6:], targets.joint_cam[..., 6:])


def test_input_normals_turn_with_the_frames_a_refiner_is_trained_on(tiny_arrays):
    """A refinement network's training frames are turned far from the camera's view (into a perturbed NAOCS
    orientation); the normals it is given, signed to face the camera, must be the observed surface's normals turned
    with the points -- as the provider's rotation of its input at test time gives them -- not re-signed towards a
    viewpoint the points were never seen from."""
    points, targets = tiny_arrays.batch(np.arange(len(tiny_arrays)))
    points = points.double()
    R = refine_rotations(tiny_arrays.naocs_rotations(np.arange(len(tiny_arrays))), np.radians(15.0),
                         [[3, i] for i in range(len(points))])
    assert np.degrees(Rotation.from_matrix(R).magnitude()).max() > 60.0  # far from the camera's view
    rotated, _ = rotate_batch(points, targets, R)
    Rt = torch.from_numpy(R)
    turned = torch.einsum("bij,bnj->bni", Rt, estimate_normals(points))
    torch.testing.assert_close(estimate_normals(rotated), turned, atol=1e-6, rtol=0)
    # the provider rotates its input about the camera too: the same points, so the same normals
    torch.testing.assert_close(rotated, points @ Rt.transpose(1, 2))


def test_neighbourhoods_of_rotated_frames_equal_the_cached_ones(tiny_arrays, tiny_config):
    """Rotations keep distances, so the neighbourhoods cached once per frame stay those of the rotated frame."""
    trainer = Trainer(tiny_config, tiny_arrays, progress=False)
    points = torch.from_numpy(tiny_arrays.points).double()
    R = camera_rotations(points.mean(dim=1).numpy(), np.radians(40.0), np.radians(25.0), range(len(points)))
    rotated, _ = rotate_batch(points, tiny_arrays.batch(np.arange(len(tiny_arrays)))[1], R)
    before = trainer.model.neighbourhoods(points.float()).numpy()
    after = trainer.model.neighbourhoods(rotated.float()).numpy()
    for name, value in before.items():
        if np.issubdtype(value.dtype, np.integer):
            np.testing.assert_array_equal(after[name], value, err_msg=name)


def test_trainer_applies_the_augmentation_reproducibly(tmp_path, tiny_arrays, tiny_config):
    plain = dataclasses.replace(tiny_config, max_steps=4, batch_size=2, checkpoint_every=2)
    aug = dataclasses.replace(plain, augment_roll_deg=30.0, augment_tilt_deg=15.0)
    base = [s["total"] for s in Trainer(plain, tiny_arrays, progress=False).fit()]
    straight = [s["total"] for s in Trainer(aug, tiny_arrays, progress=False).fit()]
    assert not np.allclose(base, straight)  # the frames were rotated
    first = Trainer(aug, tiny_arrays, tiny_arrays, tmp_path / "run", progress=False)
    part1 = [s["total"] for s in first.fit(max_steps=2)]
    resumed = Trainer(aug, tiny_arrays, tiny_arrays, tmp_path / "run", progress=False)
    resumed.load_checkpoint(tmp_path / "run" / "last.pt")
    np.testing.assert_allclose(part1 + [s["total"] for s in resumed.fit()], straight, rtol=1e-5)


def test_config_bounds_the_augmentation_angles():
    assert TrainConfig(augment_roll_deg=10, augment_tilt_deg=5).augment_roll_deg == 10.0
    for bad in (dict(augment_roll_deg=-1.0), dict(augment_tilt_deg=95.0), dict(augment_roll_deg=True),
                dict(augment_tilt_deg="5")):
        with pytest.raises(ValueError, match=next(iter(bad))):
            TrainConfig(**bad)
