"""The shipped laptop weights load by category name and beat trivial predictors on held-out instances."""

import numpy as np
import pytest

from ancsh.learned.weights import available_weights, load_network


@pytest.fixture(scope="module")
def laptop_test_frames(tmp_path_factory):
    from ancsh.data.generate import GenerationConfig, generate_dataset

    out = tmp_path_factory.mktemp("laptop_test")
    generate_dataset(GenerationConfig(category="laptop", split="test", seed=11, shard_size=4), 4, out, progress=False)
    return out


def test_laptop_weights_are_shipped_small_and_documented():
    assert "laptop" in available_weights()
    net = load_network("laptop")
    assert net.kind == "ancsh" and net.num_parts == 2 and net.revolute.tolist() == [True]
    assert net.metrics["seg_acc"] > net.metrics["seg_acc_majority"]
    assert net.metrics["npcs_err"] < net.metrics["npcs_err_zero"]


@pytest.mark.slow
def test_laptop_weights_beat_trivial_baselines_on_fresh_test_frames(laptop_test_frames):
    from ancsh.data.dataset import read_frames
    from ancsh.learned.data import arrays_from_dataset
    from ancsh.learned.provider import LearnedProvider
    from ancsh.learned.train import evaluate_arrays, trivial_baselines
    from ancsh.solvers.types import Observation

    net = load_network("laptop")
    arrays = arrays_from_dataset(laptop_test_frames)
    scores = evaluate_arrays(net.model, arrays, net.config)
    base = trivial_baselines(arrays)
    assert scores["seg_acc"] > base["seg_acc_majority"] + 0.1
    assert scores["npcs_err"] < 0.5 * base["npcs_err_zero"]
    assert scores["axis_err_deg"] < 20.0

    provider = LearnedProvider("laptop")
    frame = read_frames(laptop_test_frames)[0]
    corr = provider.correspond(Observation(frame.points))
    assert np.mean(corr.part_labels == frame.gt.part_labels) > base["seg_acc_majority"]
    angle = np.degrees(np.arccos(np.clip(abs(corr.joint_axes_naocs[0] @ frame.gt.joint_axes_naocs[0]), -1, 1)))
    assert angle < 20.0


def test_laptop_direct_voting_weights_beat_a_constant_axis():
    net = load_network("laptop", kind="direct_voting")
    assert net.kind == "direct_voting" and net.revolute.tolist() == [True]
    assert net.metrics["seg_acc"] > net.metrics["seg_acc_majority"]
    assert net.metrics["axis_err_deg"] < net.metrics["axis_err_deg_mean_axis"] / 4
