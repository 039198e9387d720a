"""Losses: relaxed IoU properties and the weighted ANCSH / direct-voting totals."""

import pytest
import torch

from ancsh.learned.training.losses import LOSS_NAMES, ancsh_loss, direct_voting_loss, relaxed_iou_loss
from ancsh.learned.network.models import build_network


def _one_hot_logits(labels, C, big=50.0):
    return big * torch.nn.functional.one_hot(labels, C).float()


def test_relaxed_iou_is_zero_for_a_perfect_prediction_and_bounded():
    g = torch.Generator().manual_seed(0)
    labels = torch.randint(0, 4, (3, 40), generator=g)
    assert relaxed_iou_loss(_one_hot_logits(labels, 4), labels) < 1e-6
    for _ in range(5):
        loss = relaxed_iou_loss(torch.randn(3, 40, 4, generator=g) * 5, labels)
        assert 0.0 < loss <= 1.0
    wrong = (labels + 1) % 4
    assert relaxed_iou_loss(_one_hot_logits(wrong, 4), labels) > 1 - 1e-6


def test_relaxed_iou_is_minimal_at_the_truth_and_differentiable():
    labels = torch.tensor([[0, 0, 1, 2, 2, 2]])
    logits = torch.zeros(1, 6, 3, requires_grad=True)
    loss = relaxed_iou_loss(logits, labels)
    loss.backward()
    # the gradient step moves probability towards the true classes
    step = -logits.grad[0]
    assert all(step[i, labels[0, i]] > 0 for i in range(6))
    perfect = relaxed_iou_loss(_one_hot_logits(labels, 3), labels)
    assert perfect < loss


def test_relaxed_iou_rejects_mismatched_shapes():
    with pytest.raises(ValueError, match="logits, labels"):
        relaxed_iou_loss(torch.zeros(2, 5, 3), torch.zeros(2, 4, dtype=torch.long))


def _perfect_outputs(arrays, idx):
    points, t = arrays.batch(idx)
    B, N = t.labels.shape
    M = arrays.num_parts
    K = arrays.num_joints
    npcs = torch.zeros(B, N, M, 3)
    npcs.scatter_(2, t.labels[..., None, None].expand(-1, -1, 1, 3), t.npcs[:, :, None])
    scale = torch.ones(B, N, M)
    scale.scatter_(2, t.labels[..., None], t.scale[..., None])
    trans = torch.zeros(B, N, M, 3)
    trans.scatter_(2, t.labels[..., None, None].expand(-1, -1, 1, 3), t.translation[:, :, None])
    out = {
        "seg_logits": _one_hot_logits(t.labels, M),
        "npcs": npcs,
        "scale": scale,
        "translation": trans,
        "assoc_logits": _one_hot_logits(t.association, K + 1),
        "joint": t.joint * t.joint_mask,
    }
    return out, t


def test_ancsh_loss_vanishes_at_the_truth_and_weights_components(tiny_arrays):
    out, t = _perfect_outputs(tiny_arrays, [0, 1])
    total, parts = ancsh_loss(out, t)
    assert set(parts) == set(LOSS_NAMES)
    assert total < 1e-5
    out["npcs"] = out["npcs"] + 0.1
    total, parts = ancsh_loss(out, t, weights=(0, 10, 0, 0, 0))
    assert parts["npcs"] == pytest.approx(3 * 0.01, rel=1e-4)
    assert total == pytest.approx(10 * parts["npcs"].item(), rel=1e-5)


def test_joint_loss_ignores_unsupervised_entries(tiny_arrays):
    out, t = _perfect_outputs(tiny_arrays, [0])
    out["joint"] = out["joint"] + 5.0 * (1 - t.joint_mask)
    assert ancsh_loss(out, t)[1]["joint"] < 1e-9


def test_losses_backpropagate_through_the_networks(tiny_arrays, tiny_config):
    points, t = tiny_arrays.batch([0, 1])
    for kind, fn in (("ancsh", ancsh_loss), ("direct_voting", direct_voting_loss)):
        torch.manual_seed(0)
        net = build_network(kind, tiny_arrays.num_parts, tiny_arrays.num_joints, width=0.125, npoints=(32, 8), nsamples=(8, 8))
        total, parts = fn(net(points), t)
        total.backward()
        assert torch.isfinite(total)
        assert all(p.grad is not None for p in net.parameters())
        if kind == "direct_voting":
            assert parts["npcs"] == 0 and parts["joint"] > 0


def test_network_rejects_bad_structures():
    with pytest.raises(ValueError, match="num_parts"):
        build_network("ancsh", 1, 1)
    with pytest.raises(ValueError, match="num_joints"):
        build_network("direct_voting", 2, 0)
    with pytest.raises(ValueError, match="backbones"):
        build_network("direct_voting", 2, 1, backbones=2)
    with pytest.raises(ValueError, match="kind"):
        build_network("pointnet", 2, 1)
