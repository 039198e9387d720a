"""PointNet++ layers: sampling, grouping, interpolation, SA/FP blocks and the backbone.

Each layer is checked against a brute-force numpy reference and for gradient flow.
"""

import numpy as np
import pytest
import torch

from ancsh.learned.network.pointnet2 import (
    FeaturePropagation,
    PointNet2Backbone,
    SetAbstraction,
    ball_query,
    farthest_point_sample,
    gather_points,
    group_points,
    three_nn_interpolate,
)


def _cloud(B=2, N=50, seed=0, dtype=torch.float32):
    g = torch.Generator().manual_seed(seed)
    return torch.rand(B, N, 3, generator=g, dtype=dtype)


def test_fps_matches_greedy_reference():
    xyz = _cloud(2, 40, seed=1)
    idx = farthest_point_sample(xyz, 10)
    assert idx.shape == (2, 10) and idx.dtype == torch.int64
    for b in range(2):
        p = xyz[b].numpy()
        ref = [0]
        d = np.full(len(p), np.inf)
        for _ in range(9):
            d = np.minimum(d, ((p - p[ref[-1]]) ** 2).sum(1))
            ref.append(int(d.argmax()))
        assert idx[b].tolist() == ref
        assert len(set(ref)) == 10


def test_fps_rejects_bad_counts():
    with pytest.raises(ValueError, match="npoint"):
        farthest_point_sample(_cloud(1, 5), 6)
    with pytest.raises(ValueError, match="xyz"):
        farthest_point_sample(torch.zeros(5, 3), 2)


def test_ball_query_matches_brute_force():
    xyz = _cloud(2, 60, seed=2)
    centres = xyz[:, :7]
    r, k = 0.3, 5
    idx = ball_query(xyz, centres, r, k)
    assert idx.shape == (2, 7, k)
    for b in range(2):
        for s in range(7):
            d = torch.linalg.norm(xyz[b] - centres[b, s], dim=1)
            inside = torch.nonzero(d <= r).flatten().tolist()
            expected = inside[:k] + [inside[0]] * max(0, k - len(inside))
            assert idx[b, s].tolist() == expected


def test_ball_query_empty_ball_falls_back_to_nearest_point():
    xyz = torch.tensor([[[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]]])
    idx = ball_query(xyz, torch.tensor([[[0.9, 0, 5.0]]]), 0.1, 3)
    assert idx.tolist() == [[[1, 1, 1]]]
    with pytest.raises(ValueError, match="radius"):
        ball_query(xyz, xyz, 0.0, 1)
    with pytest.raises(ValueError, match="nsample"):
        ball_query(xyz, xyz, 0.1, 4)


def test_grouping_gives_relative_coordinates_and_features():
    xyz = _cloud(1, 20, seed=3)
    feats = torch.arange(20.0).view(1, 1, 20).repeat(1, 2, 1)
    centres = xyz[:, :4]
    idx = ball_query(xyz, centres, 0.5, 6)
    g = group_points(xyz, feats, centres, idx)
    assert g.shape == (1, 5, 4, 6)
    torch.testing.assert_close(g[0, :3].permute(1, 2, 0), xyz[0][idx[0]] - centres[0][:, None])
    torch.testing.assert_close(g[0, 3], idx[0].float())
    assert gather_points(xyz, idx).shape == (1, 4, 6, 3)


def test_three_nn_interpolation_reproduces_known_points_and_has_exact_gradients():
    known = _cloud(1, 8, seed=4, dtype=torch.float64)
    f = torch.randn(1, 3, 8, dtype=torch.float64)
    torch.testing.assert_close(three_nn_interpolate(known, known, f), f, atol=1e-5, rtol=0)
    xyz = _cloud(1, 5, seed=5, dtype=torch.float64).requires_grad_()
    f.requires_grad_()
    assert torch.autograd.gradcheck(lambda a, b: three_nn_interpolate(a, known, b), (xyz, f))


def test_set_abstraction_and_feature_propagation_shapes_and_gradients():
    torch.manual_seed(0)
    xyz = _cloud(2, 64, seed=6).requires_grad_()
    sa = SetAbstraction(16, 0.4, 8, 0, [8, 16])
    c, f = sa(xyz, None)
    assert c.shape == (2, 16, 3) and f.shape == (2, 16, 16)
    sa_all = SetAbstraction(None, None, None, 16, [32])
    c2, f2 = sa_all(c, f)
    assert c2.shape == (2, 1, 3) and f2.shape == (2, 32, 1)
    fp = FeaturePropagation(32 + 16, [24])
    up = fp(c, c2, f, f2)
    assert up.shape == (2, 24, 16)
    up.square().sum().backward()
    assert xyz.grad is not None and torch.isfinite(xyz.grad).all() and xyz.grad.abs().sum() > 0
    for m in (sa, sa_all, fp):
        assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in m.parameters())
    with pytest.raises(ValueError, match="radius, nsample"):
        SetAbstraction(4, None, None, 0, [8])


def test_backbone_per_point_features_and_gradients():
    torch.manual_seed(0)
    bb = PointNet2Backbone(width=0.125, npoints=(32, 8), nsamples=(8, 8))
    xyz = _cloud(2, 64, seed=7).requires_grad_()
    out = bb(xyz)
    assert out.shape == (2, bb.out_channels, 64)
    out.mean().backward()
    assert torch.isfinite(xyz.grad).all() and xyz.grad.abs().sum() > 0
    dead = [n for n, p in bb.named_parameters() if p.grad is None or p.grad.abs().sum() == 0]
    assert not dead
    with pytest.raises(ValueError, match="width"):
        PointNet2Backbone(width=0)
