"""``torch.compile`` of the network for training steps on a CPU.

Inductor traces the network's forward pass (channel-last layers, cached neighbourhoods, batch
norm in training mode with its running-statistics update) and, through AOTAutograd, its backward
pass, and generates fused C++/OpenMP kernels for the element-wise work between the matrix
products (batch norm + ReLU forward and backward, gathers, max-pooling): the same function with
fewer passes over the large activations. Compiling needs a C++ compiler (``g++``, or ``$CXX``)
and takes tens of seconds once per process (``docs/results/learned_cost.md``); shapes are static,
so a step with another batch size compiles again.

The compiled module shares the parameters and buffers of the network it wraps: checkpoints
are written from the network itself (state-dict keys without the ``_orig_mod.`` prefix) and
load into an uncompiled network.
"""

from __future__ import annotations

import os
import shutil

import torch
from torch import nn

__all__ = ["cxx_compiler", "compile_network"]


def cxx_compiler() -> str | None:
    """Path of the C++ compiler inductor would use on a CPU (``$CXX``, else ``g++``), or ``None`` when absent."""
    return shutil.which(os.environ.get("CXX", "g++"))


def compile_network(model: nn.Module) -> nn.Module:
    """``torch.compile(model, dynamic=False)``: a module sharing ``model``'s parameters and buffers.

    Compilation happens at the first call (training and eval mode compile separately).

    Raises
    ------
    RuntimeError
        When ``model`` is on the CPU and no C++ compiler is found (:func:`cxx_compiler`).
    """
    devices = {p.device.type for p in model.parameters()}
    if "cpu" in devices and cxx_compiler() is None:
        raise RuntimeError(f"compile: torch.compile on a CPU needs a C++ compiler, and {os.environ.get('CXX', 'g++')!r} "
                           "(the $CXX variable, else g++) is not on the PATH; install one or set compile = false "
                           "(the uncompiled step computes the same function, slower)")
    return torch.compile(model, dynamic=False)
