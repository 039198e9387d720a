"""Shipped network weights: export from a training checkpoint, load by category name.

A weights file (``ancsh/weights/<category>.pt``, package data, nothing is downloaded) is a
``torch.save`` dict::

    {"format": 1, "kind", "category", "config" (TrainConfig dict), "num_parts",
     "revolute" (K bools), "joint_parents", "joint_children", "state_dict",
     "step", "metrics" (dict of held-out scores)}

It omits the optimiser state, so it is a few MB. A full training checkpoint (``last.pt`` /
``best.pt`` of a run) is accepted too.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["LoadedNetwork", "WEIGHTS_DIR", "weights_path", "available_weights", "shipped_categories", "export_weights", "load_network",
           "weights_summary"]

FORMAT = 1
WEIGHTS_DIR = Path(__file__).resolve().parents[1] / "weights"


@dataclass(frozen=True)
class LoadedNetwork:
    """A network in eval mode with what is needed to interpret its output.

    Attributes
    ----------
    model : torch.nn.Module
    config : TrainConfig
    revolute : (K,) bool
    joint_parents, joint_children : (K,) int64
    num_parts : int
    metrics : dict
    source : str
        File it was loaded from.
    step : int or None
        Training step of the weights.
    """

    model: object
    config: object
    revolute: np.ndarray
    joint_parents: np.ndarray
    joint_children: np.ndarray
    num_parts: int
    metrics: dict
    source: str
    step: int | None = None

    @property
    def kind(self) -> str:
        return self.config.kind


def weights_path(category: str, kind: str = "ancsh") -> Path:
    """Path of the shipped weights of ``category`` (``<category>.pt``, or ``<category>_<kind>.pt`` for baselines)."""
    name = category if kind == "ancsh" else f"{category}_{kind}"
    return WEIGHTS_DIR / f"{name}.pt"


def available_weights() -> list[str]:
    """Names (file stems) of the shipped weight files."""
    return sorted(p.stem for p in WEIGHTS_DIR.glob("*.pt"))


def shipped_categories(kind: str = "ancsh") -> list[str]:
    """Procedural categories with shipped weights of ``kind`` (``"ancsh"`` or ``"direct_voting"``)."""
    from ..data.procedural import CATEGORIES

    return [c for c in CATEGORIES if weights_path(c, kind).is_file()]


def export_weights(checkpoint, out_path, *, metrics: dict | None = None) -> Path:
    """Write a compact weights file from a training checkpoint (see the module docstring)."""
    import torch

    ck = torch.load(Path(checkpoint), map_location="cpu", weights_only=False)
    if "model" not in ck or "config" not in ck:
        raise ValueError(f"checkpoint: {checkpoint} is not a training checkpoint")
    cfg = ck["config"]
    parents, children = _structure(ck)
    data = {
        "format": FORMAT,
        "kind": cfg["kind"],
        "category": cfg["category"],
        "config": cfg,
        "num_parts": int(ck["num_parts"]),
        "revolute": list(ck["revolute"]),
        "joint_parents": parents,
        "joint_children": children,
        "state_dict": {k: v.clone() for k, v in ck["model"].items()},
        "step": int(ck["step"]),
        "metrics": dict(metrics or {}),
    }
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(out.suffix + ".tmp")
    torch.save(data, tmp)
    tmp.replace(out)
    return out


def _structure(ck: dict) -> tuple[list, list]:
    K = len(ck["revolute"])
    parents = ck.get("joint_parents")
    children = ck.get("joint_children")
    if parents is None or children is None:  # chain 0 -> 1 -> ... (older checkpoints)
        parents, children = list(range(K)), list(range(1, K + 1))
    return [int(p) for p in parents], [int(c) for c in children]


def load_network(source, *, kind: str = "ancsh") -> LoadedNetwork:
    """Load a network by category name (shipped weights), weights file or training checkpoint.

    Parameters
    ----------
    source : str or Path
        A category name such as ``"laptop"`` (looks up :func:`weights_path`) or a file path.
    kind : str
        For a category name: ``"ancsh"`` or ``"direct_voting"``.

    Raises
    ------
    FileNotFoundError
        When no weights exist for the category / path, listing what is available.
    """
    import torch

    from .config import TrainConfig
    from .network import build_network

    path = Path(source)
    if not path.suffix and not path.exists():
        path = weights_path(str(source), kind)
        if not path.is_file():
            raise FileNotFoundError(
                f"source: no shipped weights for {source!r} ({kind}) at {path}; available: {available_weights() or 'none'}"
            )
    elif not path.is_file():
        raise FileNotFoundError(f"source: no such weights file {path}")
    ck = torch.load(path, map_location="cpu", weights_only=False)
    if "state_dict" in ck:
        state = ck["state_dict"]
        parents, children = ck["joint_parents"], ck["joint_children"]
    elif "model" in ck:
        state = ck["model"]
        parents, children = _structure(ck)
    else:
        raise ValueError(f"source: {path} is neither a weights file nor a training checkpoint")
    config = TrainConfig.from_dict(ck["config"])
    revolute = np.array(ck["revolute"], dtype=bool)
    model = build_network(config.kind, int(ck["num_parts"]), len(revolute), **config.network_kwargs())
    model.load_state_dict(state)
    model.eval()
    return LoadedNetwork(
        model=model,
        config=config,
        revolute=revolute,
        joint_parents=np.array(parents, dtype=np.int64),
        joint_children=np.array(children, dtype=np.int64),
        num_parts=int(ck["num_parts"]),
        metrics=dict(ck.get("metrics", {})),
        source=str(path),
        step=None if ck.get("step") is None else int(ck["step"]),
    )


def weights_summary() -> list[dict]:
    """One row per shipped weights file: kind, category, size, training step and wall time, held-out scores.

    The training wall time is the last ``elapsed_s`` of the ``<name>_history.csv`` shipped beside
    the weights (``nan`` without it); the scores are those stored in the file (held-out test frames,
    beside the trivial baselines: majority label, all-zero NPCS, mean axis).
    """
    import csv

    rows = []
    for name in available_weights():
        net = load_network(WEIGHTS_DIR / f"{name}.pt")
        history = WEIGHTS_DIR / f"{name}_history.csv"
        minutes, steps = float("nan"), None
        if history.is_file():
            with open(history, newline="") as f:
                last = list(csv.DictReader(f))[-1:]
            if last:
                minutes, steps = float(last[0]["elapsed_s"]) / 60.0, int(float(last[0]["step"]))
        m = net.metrics
        rows.append({
            "name": name, "kind": net.kind, "category": net.config.category, "parts": net.num_parts,
            "size_mb": (WEIGHTS_DIR / f"{name}.pt").stat().st_size / 1e6, "step": net.step,
            "trained_steps": steps, "train_min": minutes, "test_frames": m.get("test_frames"),
            **{k: m.get(k, float("nan")) for k in (
                "seg_acc", "seg_acc_majority", "npcs_err", "npcs_err_zero", "assoc_acc", "axis_err_deg")},
        })
    return rows
