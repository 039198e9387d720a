"""Devices (ancsh.learned.devices): --device auto/cpu/cuda, a clear refusal of CUDA without a GPU, tensors
moved with their batch, and the GPU check script (run CPU against CPU here)."""

import numpy as np
import pytest
import torch

from ancsh.cli import main
from ancsh.learned.devices import model_device, move, resolve_device

no_cuda = pytest.mark.skipif(torch.cuda.is_available(), reason="checks the refusal on a machine without CUDA")


def test_resolve_device():
    assert resolve_device("cpu") == torch.device("cpu")
    assert resolve_device(torch.device("cpu")) == torch.device("cpu")
    assert resolve_device("auto") == torch.device("cuda" if torch.cuda.is_available() else "cpu")
    for bad in ("tpu", "gpu", 3, "meta"):
        with pytest.raises(ValueError, match="device: expected one of auto, cpu, cuda"):
            resolve_device(bad)


@no_cuda
def test_cuda_without_a_gpu_is_refused_naming_the_option(capsys, tmp_path):
    with pytest.raises(ValueError, match="--device cuda: torch sees no CUDA device here .*use --device cpu or --device auto"):
        resolve_device("cuda", argument="--device")
    with pytest.raises(ValueError, match="device cuda:1: torch sees no CUDA device"):
        resolve_device("cuda:1")
    for argv in (
        ["train", "--category", "laptop", "--data", str(tmp_path), "--out", str(tmp_path / "run"), "--device", "cuda"],
        ["evaluate", "--category", "laptop", "--frames", "1", "--out", str(tmp_path), "--device", "cuda"],
        ["predict", "--depth", str(tmp_path / "d.png"), "--intrinsics", str(tmp_path / "k.json"), "--category", "laptop",
         "--device", "cuda"],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "--device cuda: torch sees no CUDA device here" in err, (argv, err)
    assert not (tmp_path / "run").exists()


def test_move_puts_every_tensor_of_a_batch_on_the_device(tiny_arrays):
    from ancsh.learned.training.losses import Targets

    points, targets = move(tiny_arrays.batch(np.arange(2)), "cpu")
    assert isinstance(targets, Targets) and points.shape == (2, 64, 3)
    assert all(getattr(targets, k).device.type == "cpu" for k in ("labels", "npcs", "joint_cam"))
    assert move([torch.zeros(1), "text"], torch.device("cpu"))[1] == "text"
    assert model_device(torch.nn.Linear(2, 2)) == torch.device("cpu")
    assert model_device(torch.nn.ReLU()) == torch.device("cpu")


@pytest.mark.slow
def test_gpu_check_script_runs(capsys):
    """The GPU check, CPU against CPU (where no GPU is): every comparison is exact and it passes."""
    from ancsh.cli.bench.gpu_check import main as gpu_check

    assert gpu_check(["--device", "cpu", "--steps", "2"]) == 0
    out = capsys.readouterr().out
    assert "loss relative difference per step 0.0e+00 0.0e+00" in out and "segmentation agreement 1.0000" in out
    assert out.rstrip().endswith("PASS")
