"""Surface normals as input channels (``TrainConfig.input_normals``): the estimate, the backbone's extra
inputs, and a network that trains, saves, reloads and predicts with them."""

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from ancsh.learned.network.config import TrainConfig
from ancsh.learned.network.models import build_network
from ancsh.learned.network.normals import estimate_normals, normal_neighbours
from ancsh.learned.network.pointnet2 import Neighbourhoods, PointNet2Backbone


def _sphere_patch(rng, n, centre, radius):
    """Points of the camera-facing half of a sphere and their outward normals."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 2] = -np.abs(d[:, 2])  # the half towards the camera at the origin
    return centre + radius * d, d


def test_normals_of_a_sphere_are_its_radii_facing_the_camera():
    rng = np.random.default_rng(0)
    pts, outward = _sphere_patch(rng, 2000, np.array([0.1, -0.05, 1.5]), 0.3)
    n = estimate_normals(torch.from_numpy(pts[None])).numpy()[0]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-9)
    assert (np.einsum("ni,ni->n", n, pts) <= 0).all()  # every normal faces the camera
    angle = np.degrees(np.arccos(np.clip(np.einsum("ni,ni->n", n, outward), -1, 1)))
    assert np.median(angle) < 3.0  # a curved surface: the 16-point patch tilts the estimate a little


def test_normals_turn_with_the_cloud_and_ignore_the_point_order():
    rng = np.random.default_rng(1)
    pts, _ = _sphere_patch(rng, 500, np.array([0.0, 0.0, 2.0]), 0.4)
    x = torch.from_numpy(pts[None])
    n = estimate_normals(x)[0].numpy()
    perm = rng.permutation(len(pts))
    np.testing.assert_allclose(estimate_normals(x[:, perm])[0].numpy(), n[perm], atol=1e-9)
    # a rotation about the camera centre keeps the viewpoint, so the signed normals rotate with the points
    R = Rotation.from_rotvec([0.1, -0.2, 0.15]).as_matrix()
    rotated = estimate_normals(torch.from_numpy((pts @ R.T)[None]))[0].numpy()
    np.testing.assert_allclose(rotated, n @ R.T, atol=1e-7)
    with pytest.raises(ValueError, match="points"):
        estimate_normals(x[..., :2])
    with pytest.raises(ValueError, match="k"):
        estimate_normals(x, k=2)


def test_cached_nearest_points_give_the_normals_of_the_cloud_rotated_moved_or_scaled():
    rng = np.random.default_rng(3)
    pts, _ = _sphere_patch(rng, 400, np.array([0.05, 0.1, 1.8]), 0.35)
    idx = normal_neighbours(torch.from_numpy(pts[None]))
    assert idx.shape == (1, 400, 16) and (idx[0, :, 0] == torch.arange(400)).all()  # each point is its own nearest
    R = Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix()
    centroid = pts.mean(axis=0)
    moved = {  # a camera-rotation augmentation; a refiner's canonicalisation (about the centroid, scaled, shifted)
        "about the camera": pts @ R.T,
        "canonicalised": 2.5 * (pts - centroid) @ R.T + np.array([0.0, 0.0, 0.3]),
    }
    for name, q in moved.items():
        x = torch.from_numpy(q[None])
        np.testing.assert_allclose(estimate_normals(x, neighbours=idx).numpy(), estimate_normals(x).numpy(), atol=1e-7,
                                   err_msg=name)
    with pytest.raises(ValueError, match="neighbours"):
        estimate_normals(torch.from_numpy(pts[None]), neighbours=idx[:, :100])
    with pytest.raises(ValueError, match="neighbours"):
        estimate_normals(torch.from_numpy(pts[None]), neighbours=idx[..., :2])


def test_the_k_d_tree_search_finds_the_exact_nearest_points():
    """On a CPU the nearest points come from a k-d tree: the exact ones (float64 distances), nearest first, in
    float32 and float64, batched; a cloud with repeated points (a frame with fewer points than the network takes is
    sampled with repeats) gets the same normals as its points once. The brute-force search on other devices
    (``cdist``, whose float32 matrix-product distances can swap near-ties) picks nearly every set alike."""
    rng = np.random.default_rng(6)
    clouds = np.stack([_sphere_patch(rng, 300, np.array([0.0, 0.1, 1.5]), 0.3)[0] for _ in range(3)])
    clouds[2, 150:] = clouds[2, :150]  # every point twice
    d_exact = np.linalg.norm(clouds[:, :, None] - clouds[:, None], axis=-1)
    nearest = np.sort(d_exact, axis=-1)[..., :16]
    for dtype in (torch.float32, torch.float64):
        x = torch.from_numpy(clouds).to(dtype)
        tree = normal_neighbours(x)
        assert tree.shape == (3, 300, 16) and tree.dtype == torch.int64
        np.testing.assert_allclose(np.take_along_axis(d_exact, tree.numpy(), axis=-1), nearest, rtol=0, atol=1e-6)
        brute = torch.cdist(x, x).topk(16, dim=-1, largest=False).indices
        same = np.mean([set(a) == set(b) for a, b in zip(tree[:2].reshape(-1, 16).tolist(), brute[:2].reshape(-1, 16).tolist())])
        assert same > 0.9, same
    x = torch.from_numpy(clouds)
    twice = estimate_normals(x[2:], k=16)[0].numpy()
    once = estimate_normals(x[2:, :150], k=8)[0].numpy()  # each of its 8 nearest points counted twice above
    np.testing.assert_allclose(twice[:150], once, atol=1e-9)
    np.testing.assert_allclose(twice[150:], once, atol=1e-9)
    # a cloud with a non-finite point is searched by brute force (what that search makes of it, as before)
    bad = x[:1].clone()
    bad[0, 5] = float("nan")
    assert normal_neighbours(bad).shape == (1, 300, 16)


def test_a_normals_network_takes_its_nearest_points_from_the_neighbourhoods():
    cfg = TrainConfig(num_points=64, width=0.125, npoints=(32, 8), nsamples=(8, 8), input_normals=True)
    torch.manual_seed(0)
    net = build_network("ancsh", 2, 1, **cfg.network_kwargs()).eval()
    plain = build_network("ancsh", 2, 1, **TrainConfig(num_points=64, width=0.125, npoints=(32, 8), nsamples=(8, 8)).network_kwargs())
    rng = np.random.default_rng(4)
    x = torch.from_numpy(np.stack([_sphere_patch(rng, 64, np.array([0.0, 0.0, 1.2]), 0.25)[0] for _ in range(2)]).astype(np.float32))
    nb = net.neighbourhoods(x)
    torch.testing.assert_close(nb.normal_idx, normal_neighbours(x))
    # through the per-frame cache's numpy round trip, as a training step takes them
    cached = Neighbourhoods.from_numpy(nb.numpy(), [1])
    torch.testing.assert_close(cached.normal_idx, nb.normal_idx[1:])
    torch.testing.assert_close(net(x[1:], cached)["npcs"], net(x[1:])["npcs"])
    # a network without normals has none to cache, and a cache without them still serves a normals network
    assert plain.neighbourhoods(x).normal_idx is None and "normal_idx" not in plain.neighbourhoods(x).numpy()
    without = Neighbourhoods.from_numpy({k: v for k, v in nb.numpy().items() if k != "normal_idx"})
    assert without.normal_idx is None
    torch.testing.assert_close(net(x, without)["npcs"], net(x)["npcs"])
    torch.testing.assert_close(nb.map(lambda v: v[:1]).normal_idx, nb.normal_idx[:1])


def test_the_neighbourhood_cache_of_a_network_without_normals_is_not_taken_for_one_with_them(tmp_path):
    from ancsh.learned.training.train import neighbourhood_cache

    kw = dict(num_points=64, width=0.125, npoints=(32, 8), nsamples=(8, 8))
    plain = build_network("ancsh", 2, 1, **TrainConfig(**kw).network_kwargs())
    net = build_network("ancsh", 2, 1, **TrainConfig(**kw, input_normals=True).network_kwargs())
    pts = np.random.default_rng(5).normal(size=(3, 64, 3)).astype(np.float32) + np.array([0, 0, 2], np.float32)
    path = tmp_path / "neighbourhoods.npz"
    assert "normal_idx" not in neighbourhood_cache(plain, pts, path=path)
    cache = neighbourhood_cache(net, pts, path=path)  # recomputed (another key), with the nearest points
    np.testing.assert_array_equal(cache["normal_idx"], normal_neighbours(torch.from_numpy(pts)).numpy())
    np.testing.assert_array_equal(neighbourhood_cache(net, pts, path=path)["normal_idx"], cache["normal_idx"])


def test_backbone_takes_the_features_in_both_layouts_and_refuses_missing_ones():
    torch.manual_seed(0)
    bb = PointNet2Backbone(width=0.125, npoints=(32, 8), nsamples=(8, 8), in_features=3).eval()
    xyz = torch.rand(2, 64, 3)
    feats = torch.nn.functional.normalize(torch.randn(2, 64, 3), dim=-1).requires_grad_()
    last = bb(xyz, features=feats)
    bb.channels_last = False
    torch.testing.assert_close(bb(xyz, features=feats), last, atol=1e-5, rtol=1e-5)
    bb.channels_last = True
    bb.train()
    bb(xyz, features=feats).mean().backward()
    assert feats.grad.abs().sum() > 0  # the features reach the output
    assert bb.sa1.mlp[0].in_channels == 6 and bb.fp1.mlp[0].in_channels == bb.sa1.out_channels + 6
    with pytest.raises(ValueError, match="features"):
        bb(xyz)
    with pytest.raises(ValueError, match="features"):
        PointNet2Backbone(width=0.125, npoints=(32, 8), nsamples=(8, 8))(xyz, features=feats)
    with pytest.raises(ValueError, match="in_features"):
        PointNet2Backbone(in_features=-1)


def test_config_builds_a_normals_network_whose_output_depends_on_the_normals():
    cfg = TrainConfig(num_points=64, width=0.125, npoints=(32, 8), nsamples=(8, 8), input_normals=True)
    assert cfg.network_kwargs()["normals"] is True
    assert TrainConfig.from_dict(cfg.to_dict()) == cfg
    net = build_network("ancsh", 2, 1, **cfg.network_kwargs()).eval()
    plain = build_network("ancsh", 2, 1, **TrainConfig(num_points=64, width=0.125, npoints=(32, 8), nsamples=(8, 8)).network_kwargs())
    assert sum(p.numel() for p in net.parameters()) > sum(p.numel() for p in plain.parameters())
    rng = np.random.default_rng(2)
    pts, _ = _sphere_patch(rng, 64, np.array([0.0, 0.0, 1.0]), 0.2)
    x = torch.from_numpy(pts[None].astype(np.float32))
    # the same cloud moved behind the camera (its centroid mirrored through the origin): the same centred
    # coordinates, every normal's sign flipped -- a network without normals cannot tell them apart
    n_x, n_far = estimate_normals(x), estimate_normals(x - 2 * x.mean(dim=1, keepdim=True))
    assert torch.allclose(n_x, -n_far, atol=1e-5)  # viewed from the other side: the signs flip
    out_x = net(x)["npcs"]
    out_far = net(x - 2 * x.mean(dim=1, keepdim=True))["npcs"]
    assert not torch.allclose(out_x, out_far, atol=1e-4)
    plain.eval()
    torch.testing.assert_close(plain(x)["npcs"], plain(x - 2 * x.mean(dim=1, keepdim=True))["npcs"], atol=1e-4, rtol=1e-4)
    with pytest.raises(ValueError, match="input_normals"):
        TrainConfig(input_normals="yes")
    with pytest.raises(ValueError, match="normals"):
        build_network("ancsh", 2, 1, normals=1)


def test_a_normals_network_trains_saves_and_predicts(tmp_path, tiny_arrays, tiny_config):
    import dataclasses

    from ancsh.learned.inference.provider import LearnedProvider
    from ancsh.learned.network.weights import export_weights, load_network
    from ancsh.learned.training.train import Trainer
    from ancsh.solvers.types import Observation

    cfg = dataclasses.replace(tiny_config, input_normals=True, max_steps=3, checkpoint_every=3, augment_roll_deg=20.0)
    tr = Trainer(cfg, tiny_arrays, tiny_arrays, out_dir=tmp_path / "run", progress=False)
    assert tr.neighbourhoods["normal_idx"].shape == (len(tiny_arrays.points), cfg.num_points, 16)  # cached per frame
    tr.fit(3)
    ck = tr.save_checkpoint(tmp_path / "run" / "last.pt")
    w = export_weights(ck, tmp_path / "laptop_normals.pt")
    loaded = load_network(w)
    assert loaded.config.input_normals and loaded.model.normals
    x = torch.from_numpy(tiny_arrays.points[:2].astype(np.float32))
    tr.model.eval()
    torch.testing.assert_close(loaded.model.eval()(x)["npcs"], tr.model(x)["npcs"])
    corr = LearnedProvider(loaded, seed=0).correspond(Observation(tiny_arrays.points[0].astype(np.float64)))
    assert np.isfinite(corr.npcs).all()


@pytest.mark.parametrize("kind,backbones", [("ancsh", 1), ("ancsh", 2), ("direct_voting", 1)])
def test_a_network_given_normals_predicts_what_it_predicted_without_them_and_trains_them(kind, backbones):
    from ancsh.learned.network.models import load_adding_normals

    torch.manual_seed(0)
    kw = dict(width=0.125, npoints=(32, 8), radii=(0.3, 0.6), nsamples=(8, 8), backbones=backbones)
    plain = build_network(kind, 2, 1, **kw).eval()
    with torch.no_grad():  # a trained-looking network: nothing at its initial values
        for p in plain.parameters():
            p.add_(0.1 * torch.randn_like(p))
    grown = build_network(kind, 2, 1, normals=True, **kw)
    load_adding_normals(grown, plain.state_dict())
    grown.eval()
    rng = np.random.default_rng(4)
    pts, _ = _sphere_patch(rng, 128, np.array([0.0, 0.1, 1.6]), 0.3)
    x = torch.from_numpy(pts[None]).float()
    out_plain, out_grown = plain(x), grown(x)
    assert out_plain.keys() == out_grown.keys()
    for key in out_plain:
        torch.testing.assert_close(out_grown[key], out_plain[key], rtol=1e-5, atol=1e-6)
    # the normals' weights start at zero and learn: they get gradients from the first step
    w = grown.backbone.sa1.mlp[0].weight
    assert torch.count_nonzero(w[:, 3:6]) == 0
    grown.train()
    sum(v.float().square().sum() for v in grown(x).values()).backward()
    assert torch.count_nonzero(w.grad[:, 3:6]) > 0
    with pytest.raises(ValueError, match="model"):
        load_adding_normals(plain, plain.state_dict())
    with pytest.raises(ValueError, match="state"):
        load_adding_normals(build_network(kind, 2, 1, normals=True, **kw), grown.state_dict())
