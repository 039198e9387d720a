"""Which torch device the networks run on: ``"cpu"``, ``"cuda"`` (``"cuda:1"``) or ``"auto"``.

The library's default is the CPU (the tested one); the commands' ``--device`` defaults to ``"auto"``,
which picks CUDA when torch sees a CUDA device and is the CPU everywhere else. The network's
operations create their tensors on the device of their input, so the same code runs on either;
``python -m ancsh.cli.bench.gpu_check`` compares a CUDA run with a CPU run on a machine with a GPU.
"""

from __future__ import annotations

__all__ = ["DEVICES", "add_device_argument", "model_device", "move", "resolve_device"]

DEVICES = ("auto", "cpu", "cuda")
"""The ``--device`` choices (a library call also takes ``"cuda:<index>"`` or a ``torch.device``)."""


def resolve_device(device="cpu", *, argument: str = "device"):
    """The ``torch.device`` for ``device``.

    Parameters
    ----------
    device : str or torch.device
        ``"auto"`` (CUDA when available, else CPU), ``"cpu"``, ``"cuda"`` or ``"cuda:<index>"``.
    argument : str
        The option's name in error messages (``"--device"`` on the command line).

    Raises
    ------
    ValueError
        For an unknown device, or CUDA where torch sees no CUDA device (naming ``argument``).
    """
    import torch

    if isinstance(device, torch.device):
        name = str(device)
    elif isinstance(device, str):
        name = device.strip().lower()
    else:
        raise ValueError(f"{argument}: expected one of {', '.join(DEVICES)}, got {device!r}")
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        dev = torch.device(name)
    except RuntimeError:
        raise ValueError(f"{argument}: expected one of {', '.join(DEVICES)} (or cuda:<index>), got {device!r}") from None
    if dev.type not in ("cpu", "cuda"):
        raise ValueError(f"{argument}: expected one of {', '.join(DEVICES)} (or cuda:<index>), got {device!r}")
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            build = "a CPU-only torch build" if torch.version.cuda is None else f"torch built for CUDA {torch.version.cuda}"
            raise ValueError(f"{argument} {name}: torch sees no CUDA device here ({build}); "
                             f"use {argument} cpu or {argument} auto")
        if dev.index is not None and dev.index >= torch.cuda.device_count():
            raise ValueError(f"{argument} {name}: torch sees {torch.cuda.device_count()} CUDA device(s)")
    return dev


def model_device(model):
    """The device of a module's parameters (CPU for a module without parameters)."""
    import torch

    for p in model.parameters():
        return p.device
    return torch.device("cpu")


def move(value, device):
    """``value`` with every tensor on ``device``: a tensor, or tuples / lists / dataclasses of them
    (e.g. ``(points, Targets)`` of a batch, :class:`~ancsh.learned.network.pointnet2.Neighbourhoods`)."""
    import dataclasses

    import torch

    if isinstance(value, torch.Tensor):
        return value.to(device, non_blocking=True)
    if isinstance(value, (tuple, list)):
        return type(value)(move(v, device) for v in value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.replace(value, **{f.name: move(getattr(value, f.name), device) for f in dataclasses.fields(value)
                                             if f.init})
    return value


def add_device_argument(parser) -> None:
    """``--device {auto,cpu,cuda}`` (default auto) for a command that runs a network."""
    parser.add_argument("--device", choices=DEVICES, default="auto",
                        help="torch device: auto (default: cuda when torch sees a CUDA device, else cpu), cpu, cuda")
