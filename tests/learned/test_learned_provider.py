"""LearnedProvider: network output -> valid Correspondences; weights export and loading."""

import numpy as np
import pytest
import torch

from ancsh.learned.inference.provider import DirectVotingPredictor, LearnedProvider
from ancsh.learned.training.train import Trainer
from ancsh.learned.network.weights import export_weights, load_network, weights_path
from ancsh.solvers.types import CorrespondenceProvider, Correspondences, Observation


@pytest.fixture
def tiny_weights(tmp_path, tiny_arrays, tiny_config):
    """Randomly initialised tiny networks saved as checkpoints and exported weights."""
    import dataclasses

    paths = {}
    for kind in ("ancsh", "direct_voting"):
        cfg = dataclasses.replace(tiny_config, kind=kind)
        trainer = Trainer(cfg, tiny_arrays, None, tmp_path / kind, progress=False)
        ck = trainer.save_checkpoint(tmp_path / kind / "last.pt")
        paths[kind] = export_weights(ck, tmp_path / f"{kind}.pt", metrics={"note": 1.0})
    return paths


def test_provider_returns_valid_correspondences(tiny_weights, tiny_arrays):
    provider = LearnedProvider(tiny_weights["ancsh"])
    assert isinstance(provider, CorrespondenceProvider)
    for n in (10, 64, 150):  # fewer points than the network input, equal, several chunks
        pts = np.random.default_rng(n).normal(size=(n, 3)) * 0.1 + [0, 0, 1.5]
        corr = provider.correspond(Observation(pts))
        assert isinstance(corr, Correspondences)
        assert corr.num_points == n and corr.num_parts == tiny_arrays.num_parts and corr.num_joints == 1
        assert corr.npcs.shape == (n, 3) and np.all(corr.npcs_scale > 0)
        assert np.all((corr.weights > 0) & (corr.weights <= 1))
        np.testing.assert_allclose(np.linalg.norm(corr.joint_axes_naocs, axis=1), 1)
        assert corr.joint_types[0].value == "revolute"
    again = provider.correspond(Observation(pts))
    np.testing.assert_array_equal(again.npcs, corr.npcs)  # deterministic per observation


def test_provider_refuses_an_object_of_another_structure(tiny_weights, tiny_arrays):
    provider = LearnedProvider(tiny_weights["ancsh"])
    names = [f"p{i}" for i in range(tiny_arrays.num_parts)]
    provider.check_structure(names, provider.joint_types)  # its own structure passes
    with pytest.raises(ValueError, match="cabinet_1: has 4 parts.*predicts"):
        provider.check_structure(names + ["a", "b"], ["prismatic"] * 3, where="cabinet_1")
    with pytest.raises(ValueError, match="prismatic"):
        provider.check_structure(names, ["prismatic"] * len(provider.joint_types))


def test_provider_prediction_is_per_point_and_order_equivariant(tiny_weights):
    provider = LearnedProvider(tiny_weights["ancsh"])
    pts = np.random.default_rng(1).normal(size=(64, 3)) * 0.1 + [0, 0, 1.5]
    a = provider.predict(pts)
    perm = np.random.default_rng(2).permutation(64)
    b = provider.predict(pts[perm])
    np.testing.assert_allclose(b.seg_prob, a.seg_prob[perm], atol=1e-5)
    np.testing.assert_allclose(a.seg_prob.sum(1), 1)


def test_direct_voting_predictor_gives_camera_joints(tiny_weights):
    pred = DirectVotingPredictor(tiny_weights["direct_voting"])
    pts = np.random.default_rng(3).normal(size=(80, 3)) * 0.1 + [0, 0, 1.5]
    axes, pivots, votes = pred.joints(Observation(pts))
    assert axes.shape == (1, 3) and pivots.shape == (1, 3) and np.all(np.isfinite(pivots))
    with pytest.raises(ValueError, match="direct_voting"):
        DirectVotingPredictor(tiny_weights["ancsh"])
    with pytest.raises(ValueError, match="ANCSH"):
        LearnedProvider(tiny_weights["direct_voting"])


def test_weights_round_trip_and_errors(tiny_weights, tmp_path, tiny_arrays):
    net = load_network(tiny_weights["ancsh"])
    ck = load_network(tmp_path / "ancsh" / "last.pt")
    x = torch.from_numpy(tiny_arrays.points[:2])
    with torch.no_grad():
        for k, v in net.model(x).items():
            torch.testing.assert_close(v, ck.model(x)[k])
    assert net.metrics == {"note": 1.0} and net.joint_parents.tolist() == [0] and net.joint_children.tolist() == [1]
    assert tiny_weights["ancsh"].stat().st_size < 5e6
    with pytest.raises(FileNotFoundError, match="no shipped weights"):
        load_network("no_such_category")
    with pytest.raises(FileNotFoundError, match="no such weights file"):
        load_network(tmp_path / "missing.pt")
    assert weights_path("laptop").name == "laptop.pt"
    with pytest.raises(ValueError, match="observation"):
        LearnedProvider(net).correspond(np.zeros((3, 3)))


def test_every_joint_keeps_its_voters_when_joints_compete_for_the_same_points():
    """Three joints whose most likely points are the same five (a drawer network on an odd view): forcing
    voters for the third must not take the second's, which left a joint without a vote and crashed."""
    from ancsh.learned.inference.provider import _joint_sets

    p = np.zeros((50, 4))
    p[:, 0] = 1.0
    p[:5, 1], p[:5, 2], p[:5, 3] = 0.9, 0.8, 0.95
    counts = np.bincount(_joint_sets(p, 3, 4), minlength=4)
    assert counts[1:].min() >= 4 and counts.sum() == 50
