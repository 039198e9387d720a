"""Distributed training (ancsh.learned.distributed): 2 CPU processes (gloo) train like one process on the
same global batch -- losses, weights and batch-norm statistics -- and resume from rank 0's checkpoint.

The processes are started as torchrun would start them (RANK, WORLD_SIZE, LOCAL_RANK, MASTER_ADDR,
MASTER_PORT in the environment, read by ``init_distributed``).
"""

import os
import socket

import numpy as np
import pytest
import torch

from ancsh.learned.training.data import synthetic_arrays
from ancsh.learned.distributed import DistributedContext, init_distributed
from ancsh.learned.training.train import Trainer


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _arrays():
    """Eight frames of two objects, float64: a global batch of 4 splits into 2 frames per process."""
    import dataclasses

    a = synthetic_arrays(8, 64, seed=3, num_parts=2, joint_types="revolute", instances=2)
    return dataclasses.replace(a, **{f.name: getattr(a, f.name).astype(np.float64) for f in dataclasses.fields(a)
                                     if isinstance(getattr(a, f.name), np.ndarray) and getattr(a, f.name).dtype == np.float32})


def _rank_main(rank: int, world: int, port: int, config, out_dir: str, result: str) -> None:
    """One process of a torchrun-like launch: train steps 1-2 (rank 0 checkpoints), then a new trainer resumes
    from ``last.pt`` and trains steps 3-4, as ``ancsh train --resume`` would."""
    os.environ.update(RANK=str(rank), WORLD_SIZE=str(world), LOCAL_RANK=str(rank), MASTER_ADDR="127.0.0.1",
                      MASTER_PORT=str(port), OMP_NUM_THREADS="1")
    torch.set_default_dtype(torch.float64)
    ctx = init_distributed("cpu")
    assert (ctx.rank, ctx.world_size, ctx.device.type) == (rank, world, "cpu")
    first = Trainer(config, _arrays(), None, out_dir, progress=False, distributed=ctx)
    losses = first.fit(2)
    files = sorted(os.listdir(out_dir))
    ctx.barrier()
    resumed = Trainer(config, _arrays(), None, out_dir, progress=False, distributed=ctx)
    resumed.load_checkpoint(os.path.join(out_dir, "last.pt"))
    losses += resumed.fit(4)
    torch.save({"losses": losses, "model": resumed.model.state_dict(), "steps": [first.step, resumed.step],
                "files": files}, f"{result}.{rank}")
    torch.distributed.destroy_process_group()


def _launch(tmp_path, config) -> list[dict]:
    """Two processes; returns each rank's result."""
    result = str(tmp_path / "result")
    torch.multiprocessing.spawn(_rank_main, args=(2, _free_port(), config, str(tmp_path / "run"), result), nprocs=2,
                                join=True)
    return [torch.load(f"{result}.{r}", weights_only=True) for r in range(2)]


def _max_difference(a: dict, b: dict) -> float:
    return max(float((a[k].double() - b[k].double()).abs().max()) for k in a if a[k].is_floating_point())


@pytest.mark.slow
def test_two_processes_train_like_one_process_on_the_same_global_batch(tmp_path, tiny_config):
    """Two ranks of 2 frames each vs one process of 4 frames, 4 steps, with a checkpoint and a resume after step 2.

    Batch norm takes its statistics over both ranks (the network's batch norm couples the frames of a
    batch: per-rank statistics would train another network) and every loss is a mean over the global
    batch, so the two runs compute the same function; what differs is the order of the sums. The
    comparison runs in float64 so that this rounding stays far below what could reveal a mistake:
    losses agree to 1e-9 (measured: 3e-11), weights to 1e-5 of what the 4 steps changed them by
    (measured: 4e-7; Adam's normalised update magnifies rounding where a gradient entry is near 0).
    In float32 the same runs agree to 1e-5 at the first step, and the differences grow through Adam's
    updates to 5e-3 of the loss by step 4: rounding, as the float64 run shows.
    """
    import dataclasses

    config = dataclasses.replace(tiny_config, batch_size=4, lr=1e-3, checkpoint_every=1000, max_steps=4)
    torch.set_default_dtype(torch.float64)
    try:
        single = Trainer(config, _arrays(), progress=False)
        initial = {k: v.clone() for k, v in single.model.state_dict().items()}
        single_losses = single.fit(4)
    finally:
        torch.set_default_dtype(torch.float32)

    ranks = _launch(tmp_path, config)
    assert [r["steps"] for r in ranks] == [[2, 4], [2, 4]]
    assert {"last.pt", "config.json", "history.csv", "curves.png"} <= set(ranks[0]["files"])  # rank 0's, after step 2
    assert not list((tmp_path / "run").glob("*.tmp*"))

    assert ranks[0]["losses"] == ranks[1]["losses"]  # every rank logs the loss of the global batch
    for a, b in zip(ranks[0]["losses"], single_losses, strict=True):
        assert set(a) == set(b)
        for k in a:
            assert a[k] == pytest.approx(b[k], rel=1e-9), k
    assert single_losses[0]["total"] != pytest.approx(single_losses[-1]["total"], rel=1e-2)  # training moved

    w_ddp, w_single = ranks[0]["model"], single.model.state_dict()
    assert _max_difference(ranks[1]["model"], w_ddp) == 0.0  # the ranks hold the same weights
    for k, w in w_single.items():
        if not w.is_floating_point():
            assert torch.equal(w_ddp[k], w), k  # num_batches_tracked
        elif "running" in k:  # batch-norm running statistics: over the global batch too
            np.testing.assert_allclose(w_ddp[k].numpy(), w.numpy(), rtol=1e-7, atol=1e-9, err_msg=k)
        else:  # what 4 steps changed, against what distinguishes the two runs
            moved = float((w - initial[k]).abs().max())
            assert moved > 1e-4, k
            assert float((w_ddp[k] - w).abs().max()) <= 1e-5 * moved, k


def test_single_process_context_and_uneven_batches(monkeypatch):
    monkeypatch.delenv("WORLD_SIZE", raising=False)
    ctx = init_distributed("cpu")
    assert not ctx.active and ctx.is_main and ctx.device == torch.device("cpu")
    np.testing.assert_array_equal(ctx.local_batch(np.arange(5)), np.arange(5))
    two = DistributedContext(rank=1, world_size=2)
    np.testing.assert_array_equal(two.local_batch(np.arange(6)), [3, 4, 5])
    with pytest.raises(ValueError, match="batch_size: 5 frames do not split evenly over 2 processes"):
        two.local_batch(np.arange(5))
