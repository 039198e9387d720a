"""The pose-aware loss: a differentiable weighted Procrustes rotation of predicted onto true NPCS.

Checked in float64 against finite differences, at the truth (value 0), against a known rotation,
with reflections, and on degenerate parts (too few points, collinear, coincident predictions),
which must give finite values and gradients.
"""

import math

import numpy as np
import pytest
import torch

from ancsh.geometry.rotations import random_rotation
from ancsh.learned.training.losses import Targets, ancsh_loss, npcs_pose_loss, procrustes_rotation


def _frames(B=2, N=60, M=2, seed=0):
    g = torch.Generator().manual_seed(seed)
    true = torch.rand(B, N, 3, generator=g, dtype=torch.float64) - 0.5
    labels = torch.arange(N).remainder(M).expand(B, N).clone()
    return true, labels, g


def test_procrustes_rotation_recovers_a_known_rotation_and_excludes_reflections():
    rng = np.random.default_rng(0)
    p = torch.from_numpy(rng.normal(size=(30, 3)))
    R_true = torch.from_numpy(random_rotation(rng))
    q = p @ R_true.T + torch.tensor([0.3, -0.2, 1.0], dtype=torch.float64)
    C = (q - q.mean(0)).T @ (p - p.mean(0))
    torch.testing.assert_close(procrustes_rotation(C), R_true, rtol=0, atol=1e-10)
    # a mirrored target: the best proper rotation, never a reflection
    mirrored = q * torch.tensor([1.0, 1.0, -1.0], dtype=torch.float64)
    R = procrustes_rotation((mirrored - mirrored.mean(0)).T @ (p - p.mean(0)))
    torch.testing.assert_close(torch.linalg.det(R), torch.tensor(1.0, dtype=torch.float64))
    torch.testing.assert_close(R.T @ R, torch.eye(3, dtype=torch.float64), rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="cross_covariance"):
        procrustes_rotation(torch.zeros(3, 2))
    with pytest.raises(ValueError, match="eps"):
        procrustes_rotation(C, eps=0.0)


def test_procrustes_rotation_gradient_matches_finite_differences():
    g = torch.Generator().manual_seed(1)
    C = torch.randn(6, 3, 3, generator=g, dtype=torch.float64)
    C[0] = C[0] @ torch.diag(torch.tensor([1.0, 1.0, -1.0], dtype=torch.float64))  # det < 0: reflection branch
    C[1] = -C[1]
    assert (torch.linalg.det(C) < 0).any() and (torch.linalg.det(C) > 0).any()
    assert torch.autograd.gradcheck(procrustes_rotation, (C.requires_grad_(),), eps=1e-6, atol=1e-7)


@pytest.mark.parametrize("kind", ["chordal", "displacement"])
def test_pose_loss_is_zero_at_the_truth_and_for_rotation_free_errors(kind):
    true, labels, g = _frames()
    pred = true.clone().requires_grad_()
    loss = npcs_pose_loss(pred, true, labels, 2, kind=kind)
    loss.backward()
    assert abs(loss.item()) < 1e-20 and float(pred.grad.abs().max()) < 1e-12
    shifted = 0.7 * true + torch.tensor([0.1, 0.2, -0.3], dtype=torch.float64)  # scaled and shifted, not rotated
    assert float(npcs_pose_loss(shifted, true, labels, 2, kind=kind)) < 1e-20


def test_pose_loss_equals_the_chordal_distance_of_a_known_rotation():
    true, labels, _ = _frames(B=1, M=1)
    theta = 0.3
    c, s = math.cos(theta), math.sin(theta)
    R = torch.tensor([[c, -s, 0], [s, c, 0], [0, 0, 1.0]], dtype=torch.float64)
    pred = true @ R  # pred = R^T true: the fit of pred onto true rotates by R
    expected = 4 * (1 - c)
    assert abs(float(npcs_pose_loss(pred, true, labels, 1)) - expected) < 1e-12


@pytest.mark.parametrize("kind", ["chordal", "displacement"])
def test_pose_loss_gradient_matches_finite_differences(kind):
    true, labels, g = _frames(B=2, N=24, M=2, seed=2)
    pred = (true + 0.2 * torch.randn(true.shape, generator=g, dtype=torch.float64)).requires_grad_()
    assert torch.autograd.gradcheck(lambda p: npcs_pose_loss(p, true, labels, 2, kind=kind), (pred,), eps=1e-6, atol=1e-7)


def test_displacement_pose_loss_is_the_mean_squared_displacement_of_the_true_npcs():
    """``mean |(R - I) q|^2`` over the centred true NPCS, here for a known rotation about z."""
    true, labels, _ = _frames(B=1, M=1)
    theta = 0.3
    c, s = math.cos(theta), math.sin(theta)
    R = torch.tensor([[c, -s, 0], [s, c, 0], [0, 0, 1.0]], dtype=torch.float64)
    q = true[0] - true[0].mean(0)
    expected = ((q @ R.T - q).square().sum(1)).mean()
    got = npcs_pose_loss(true @ R, true, labels, 1, kind="displacement")
    assert abs(float(got) - float(expected)) < 1e-12


def test_displacement_pose_loss_weighs_a_thin_part_by_what_its_error_moves():
    """A bar along x (1 x 0.02 x 0.02): a rotation about its long axis moves its points by the thickness only,
    one about a short axis by the length; the chordal loss weighs the two alike."""
    g = torch.Generator().manual_seed(5)
    true = (torch.rand(1, 200, 3, generator=g, dtype=torch.float64) - 0.5) * torch.tensor([1.0, 0.02, 0.02], dtype=torch.float64)
    labels = torch.zeros(1, 200, dtype=torch.long)
    c, s = math.cos(0.1), math.sin(0.1)
    about_x = torch.tensor([[1.0, 0, 0], [0, c, -s], [0, s, c]], dtype=torch.float64)
    about_z = torch.tensor([[c, -s, 0], [s, c, 0], [0, 0, 1.0]], dtype=torch.float64)
    loss = {(k, n): float(npcs_pose_loss(true @ R, true, labels, 1, kind=k))
            for k in ("chordal", "displacement") for n, R in (("x", about_x), ("z", about_z))}
    assert abs(loss["chordal", "x"] - loss["chordal", "z"]) < 1e-9
    assert loss["displacement", "x"] < 1e-3 * loss["displacement", "z"]


def test_degenerate_parts_give_finite_loss_and_gradients():
    true, labels, g = _frames(B=3, N=40, M=3, seed=3)
    labels[0, :] = 0
    labels[0, :2] = 1  # frame 0: part 1 has two points, part 2 none
    true[1, labels[1] == 1] = torch.tensor([0.1, 0.2, 0.3], dtype=torch.float64) * torch.linspace(
        -1, 1, int((labels[1] == 1).sum()), dtype=torch.float64)[:, None]  # frame 1: part 1 collinear
    pred = true + 0.1 * torch.randn(true.shape, generator=g, dtype=torch.float64)
    pred[2, labels[2] == 2] = 0.25  # frame 2: part 2 predicted at one point (all singular values 0)
    pred[1, labels[1] == 0] = pred[1, labels[1] == 0][:, :1] * torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64)  # collinear
    pred.requires_grad_()
    loss = npcs_pose_loss(pred, true, labels, 3)
    loss.backward()
    assert torch.isfinite(loss.detach()) and torch.isfinite(pred.grad).all()
    # the parts left out (too few points, collinear truth) receive no gradient
    assert float(pred.grad[0, labels[0] == 1].abs().max()) == 0.0
    assert float(pred.grad[1, labels[1] == 1].abs().max()) == 0.0
    # no valid part at all: zero loss, zero gradient
    lone = torch.zeros(1, 3, 3, dtype=torch.float64, requires_grad=True)
    out = npcs_pose_loss(lone, torch.rand(1, 3, 3, dtype=torch.float64), torch.zeros(1, 3, dtype=torch.long), 2)
    out.backward()
    assert out.item() == 0.0 and torch.equal(lone.grad, torch.zeros_like(lone))


def test_pose_loss_rejects_bad_arguments():
    true, labels, _ = _frames()
    with pytest.raises(ValueError, match="pred, true, labels"):
        npcs_pose_loss(true[..., :2], true, labels, 2)
    with pytest.raises(ValueError, match="min_points"):
        npcs_pose_loss(true, true, labels, 2, min_points=2)
    with pytest.raises(ValueError, match="min_spread"):
        npcs_pose_loss(true, true, labels, 2, min_spread=1.0)
    with pytest.raises(ValueError, match="kind"):
        npcs_pose_loss(true, true, labels, 2, kind="geodesic")


def test_ancsh_loss_adds_the_weighted_pose_term_and_the_config_defaults_to_off():
    from ancsh.learned.network.config import TrainConfig
    from ancsh.learned.training.train import loss_function

    true, labels, g = _frames(B=2, N=30, M=2)
    B, N = labels.shape
    npcs = true.unsqueeze(2).repeat(1, 1, 2, 1) + 0.1 * torch.randn(B, N, 2, 3, generator=g, dtype=torch.float64)
    out = {"seg_logits": torch.randn(B, N, 2, generator=g, dtype=torch.float64), "npcs": npcs,
           "scale": torch.ones(B, N, 2, dtype=torch.float64), "translation": torch.zeros(B, N, 2, 3, dtype=torch.float64),
           "assoc_logits": torch.randn(B, N, 2, generator=g, dtype=torch.float64), "joint": torch.zeros(B, N, 7, dtype=torch.float64)}
    t = Targets(labels, true, torch.ones(B, N, dtype=torch.float64), torch.zeros(B, N, 3, dtype=torch.float64),
                labels.clone(), torch.zeros(B, N, 7, dtype=torch.float64), torch.ones(B, N, 7, dtype=torch.float64),
                torch.zeros(B, N, 7, dtype=torch.float64))
    base, parts = ancsh_loss(out, t)
    assert "pose" not in parts
    total, parts = ancsh_loss(out, t, pose_weight=2.5)
    torch.testing.assert_close(total, base + 2.5 * parts["pose"])
    assert float(parts["pose"]) > 0
    assert TrainConfig().pose_weight == 0.0
    assert "pose" in loss_function(TrainConfig(pose_weight=1.0))(out, t)[1]
    with pytest.raises(ValueError, match="pose_weight"):
        TrainConfig(pose_weight=-1.0)
    with pytest.raises(ValueError, match="pose_weight"):
        TrainConfig(kind="direct_voting", pose_weight=1.0)
    with pytest.raises(ValueError, match="pose_loss"):
        TrainConfig(pose_loss="geodesic")
    cfg = TrainConfig(pose_weight=1.0, pose_loss="displacement")
    _, parts = loss_function(cfg)(out, t)
    torch.testing.assert_close(parts["pose"], npcs_pose_loss(npcs.gather(2, labels[..., None, None].expand(B, N, 1, 3))[:, :, 0],
                                                             true, labels, 2, kind="displacement"))
