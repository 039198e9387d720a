"""Data-parallel training on several processes with ``torch.distributed`` (DDP), launched by ``torchrun``.

``torchrun --nproc_per_node 2 -m ancsh train --category laptop --data D --out R`` starts two processes;
each learns its rank from torchrun's environment (:func:`init_distributed`: gloo on CPUs, NCCL on
CUDA devices, one device per process). Every step takes the same *global* batch as a single process
(:meth:`~ancsh.learned.training.train.Trainer.batch_indices`) and each rank runs an equal, contiguous share
of it (:meth:`DistributedContext.local_batch`). Inside :func:`global_batch`

- batch norm takes its statistics over the global batch (:func:`sync_batch_norm_rows`: sums
  all-reduced with autograd, so the gradient is that of the global statistics), and
- each loss's mean is the global one (:func:`batch_mean`, :func:`batch_ratio`: the local sum over
  the global count, times the world size, which DDP's gradient averaging divides out again),

so a step of ``W`` processes computes the loss and gradient of one process on the whole batch, up to
float rounding (the sums are taken in another order). Rank 0 writes the run directory (config,
checkpoints, history, curves); every rank reads ``last.pt`` on ``--resume``, so a resumed run goes
on exactly as an uninterrupted one.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass

import numpy as np
import torch

__all__ = [
    "DistributedContext",
    "batch_mean",
    "batch_ratio",
    "global_batch",
    "init_distributed",
    "shutdown_distributed",
    "sync_batch_norm_rows",
    "syncing",
]


@dataclass(frozen=True)
class DistributedContext:
    """This process's place in a training run.

    Attributes
    ----------
    rank : int
        ``0 <= rank < world_size``; rank 0 writes the run directory.
    world_size : int
        Processes (1 = a plain single-process run).
    device : torch.device
        This process's device (``cuda:<local rank>`` on GPUs).
    group : object or None
        The process group of the statistics (a group of its own, apart from DDP's gradient traffic).
    """

    rank: int = 0
    world_size: int = 1
    device: torch.device = torch.device("cpu")
    group: object = None

    @property
    def is_main(self) -> bool:
        return self.rank == 0

    @property
    def active(self) -> bool:
        return self.world_size > 1

    def local_batch(self, indices: np.ndarray) -> np.ndarray:
        """This rank's contiguous share of a global batch (``len(indices)`` must divide by ``world_size``)."""
        if len(indices) % self.world_size:
            raise ValueError(f"batch_size: {len(indices)} frames do not split evenly over {self.world_size} processes; "
                             "use a batch size divisible by the number of processes")
        n = len(indices) // self.world_size
        return indices[self.rank * n:(self.rank + 1) * n]

    def average(self, values: torch.Tensor) -> torch.Tensor:
        """Mean over ranks of a (detached) tensor (itself in a single process)."""
        if not self.active:
            return values
        values = values.detach().clone()
        torch.distributed.all_reduce(values, group=self.group)
        return values / self.world_size

    def any(self, flag: bool) -> bool:
        """Whether ``flag`` is true on some rank (every rank gets the same answer)."""
        if not self.active:
            return bool(flag)
        t = torch.tensor([1.0 if flag else 0.0], device=self.device)
        torch.distributed.all_reduce(t, op=torch.distributed.ReduceOp.MAX, group=self.group)
        return bool(t.item() > 0)

    def barrier(self) -> None:
        if self.active:
            torch.distributed.barrier(group=self.group)

    def wrap(self, model: torch.nn.Module) -> torch.nn.Module:
        """``model`` in ``DistributedDataParallel`` (itself in a single process)."""
        if not self.active:
            return model
        from torch.nn.parallel import DistributedDataParallel

        import warnings

        ids = [self.device.index] if self.device.type == "cuda" else None
        with warnings.catch_warnings():  # torch 2.13 calls the option deprecated but keeps it for this use
            warnings.simplefilter("ignore", FutureWarning)
            # Batch-norm statistics are synchronised in the forward pass (sync_batch_norm_rows): no buffer broadcast.
            return DistributedDataParallel(model, device_ids=ids, broadcast_buffers=False)


def init_distributed(device="auto") -> DistributedContext:
    """Join the process group of a ``torchrun`` launch (``WORLD_SIZE``, ``RANK``, ``LOCAL_RANK``,
    ``MASTER_ADDR``, ``MASTER_PORT`` in the environment), or a single-process context without one.

    Parameters
    ----------
    device : str or torch.device
        ``"auto"``, ``"cpu"`` or ``"cuda"`` (:func:`~ancsh.learned.devices.resolve_device`); with
        CUDA each process takes device ``LOCAL_RANK`` and the NCCL backend, else gloo.
    """
    from .devices import resolve_device

    dev = resolve_device(device, argument="--device")
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1:
        return DistributedContext(device=dev)
    rank, local_rank = int(os.environ["RANK"]), int(os.environ.get("LOCAL_RANK", "0"))
    if dev.type == "cuda":
        if local_rank >= torch.cuda.device_count():
            raise ValueError(f"--device cuda: process {local_rank} on this node, but torch sees "
                             f"{torch.cuda.device_count()} CUDA device(s); start at most that many per node")
        dev = torch.device("cuda", local_rank)
        torch.cuda.set_device(dev)
    import torch.distributed as dist

    if not dist.is_initialized():
        dist.init_process_group("nccl" if dev.type == "cuda" else "gloo", rank=rank, world_size=world)
    return DistributedContext(rank=rank, world_size=world, device=dev, group=dist.new_group())


def shutdown_distributed(context: DistributedContext) -> None:
    """Leave the process group (at the end of a run)."""
    if context.active and torch.distributed.is_initialized():
        torch.distributed.destroy_process_group()


# --------------------------------------------------------------------------------------------
# statistics over the global batch
# --------------------------------------------------------------------------------------------
_GROUP = None  # while global_batch() is active: (process group, world size)


@contextlib.contextmanager
def global_batch(context: DistributedContext):
    """Within this block, batch-norm statistics and loss means are taken over the global batch (no-op in a
    single process). Training steps only: validation runs on one rank, outside it."""
    global _GROUP
    previous = _GROUP
    _GROUP = (context.group, context.world_size) if context.active else None
    try:
        yield
    finally:
        _GROUP = previous


def syncing() -> bool:
    """Whether a :func:`global_batch` block of several processes is active."""
    return _GROUP is not None


def _global_count(count) -> torch.Tensor:
    group, _ = _GROUP
    c = torch.as_tensor(count).detach().to(torch.float64).reshape(1).clone()
    c = c.to(_device_of(group, c))
    torch.distributed.all_reduce(c, group=group)
    return c[0]


def _device_of(group, tensor: torch.Tensor) -> torch.device:
    backend = torch.distributed.get_backend(group)
    return torch.device("cuda", torch.cuda.current_device()) if backend == "nccl" else tensor.device


def batch_ratio(total: torch.Tensor, count) -> torch.Tensor:
    """``total / max(count, 1)``; inside :func:`global_batch`, this rank's share of the global ratio: its
    ``total`` over the global ``count`` times the world size (DDP averages the gradients over ranks).

    Parameters
    ----------
    total : () tensor
        A sum over this rank's part of the batch.
    count : () tensor or int
        How many terms the mean has on this rank (no gradient).
    """
    if _GROUP is None:
        return total / torch.as_tensor(count).clamp_min(1)
    world = _GROUP[1]
    n = _global_count(count).to(total.device, total.dtype)
    return total * world / n.clamp_min(1)


def batch_mean(values: torch.Tensor) -> torch.Tensor:
    """``values.mean()``; inside :func:`global_batch`, this rank's share of the mean over every rank's values
    (see :func:`batch_ratio`)."""
    if _GROUP is None:
        return values.mean()
    return batch_ratio(values.sum(), values.numel())


class _AllReduceSum(torch.autograd.Function):
    """``sum over ranks`` with its gradient: every rank's output is the sum, so the gradient of a rank's input
    is the sum over ranks of the gradients of their outputs."""

    @staticmethod
    def forward(ctx, tensor, group):
        ctx.group = group
        out = tensor.clone()
        torch.distributed.all_reduce(out, group=group)
        return out

    @staticmethod
    def backward(ctx, grad):
        grad = grad.contiguous().clone()
        torch.distributed.all_reduce(grad, group=ctx.group)
        return grad, None


def sync_batch_norm_rows(bn: torch.nn.modules.batchnorm._BatchNorm, h: torch.Tensor) -> torch.Tensor:
    """Training-mode batch norm of ``(P, C)`` rows with the statistics of every rank's rows (inside
    :func:`global_batch`): ``nn.BatchNorm``'s function and running-statistics update on the global batch.

    The sums are all-reduced with autograd (:class:`_AllReduceSum`), so the gradient reaching this
    rank's rows includes the other ranks' losses through the shared mean and variance.
    """
    group, _ = _GROUP

    def all_reduce(t):
        return _AllReduceSum.apply(t, group)

    n_local = torch.full((1,), float(h.shape[0]), dtype=h.dtype, device=h.device)
    sums = all_reduce(torch.cat([h.sum(0), n_local]))
    n = sums[-1]
    mean = sums[:-1] / n
    centred = h - mean
    var = all_reduce((centred * centred).sum(0)) / n  # biased, two passes like nn.BatchNorm
    out = centred * torch.rsqrt(var + bn.eps)
    if bn.weight is not None:
        out = out * bn.weight + bn.bias
    if bn.track_running_stats:
        with torch.no_grad():
            bn.num_batches_tracked.add_(1)
            momentum = (1.0 / float(bn.num_batches_tracked)) if bn.momentum is None else bn.momentum
            bn.running_mean.mul_(1 - momentum).add_(mean.detach(), alpha=momentum)
            bn.running_var.mul_(1 - momentum).add_(var.detach() * (n / (n - 1).clamp_min(1)), alpha=momentum)
    return out
