"""Shipped network weights: export from a training checkpoint, load by category name.

A weights file (``ancsh/weights/<category>.pt``, package data, nothing is downloaded) is a
``torch.save`` dict::

    {"format": 1, "kind", "category", "config" (TrainConfig dict), "num_parts",
     "revolute" (K bools), "joint_parents", "joint_children", "state_dict",
     "step", "metrics" (dict of held-out scores), "lineage"}

``lineage`` is ``None`` for a network trained from scratch; for one fine-tuned from other weights
(``TrainConfig.init_weights``) it is :func:`parent_record` of those weights: their SHA-256, step and
training wall time (their own run plus their lineage's), so the time behind a shipped file stays
known after the parent file is replaced.

It omits the optimiser state, so it is a few MB. A full training checkpoint (``last.pt`` /
``best.pt`` of a run) is accepted too.

Every file is read by :func:`read_torch_file` with ``torch.load(..., weights_only=True)``: only
tensors and plain containers/numbers/strings are unpickled, so a crafted file cannot run code; such a
file, a truncated one or one with missing entries is refused with a ``ValueError`` naming it.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...outputs import write_bytes_atomically

__all__ = ["LoadedNetwork", "WEIGHTS_DIR", "weights_dir", "weights_path", "weights_file_name", "available_weights", "shipped_categories", "export_weights", "load_network",
           "learning_curve_fit", "missing_weights_error", "weights_summary", "read_torch_file", "parent_record",
           "training_seconds"]

FORMAT = 1
WEIGHTS_DIR = Path(__file__).resolve().parents[2] / "weights"


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
    sha256 : str or None
        SHA-256 of the file's bytes, taken when it was loaded.
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
    sha256: str | None = None
    lineage: dict | None = None

    @property
    def kind(self) -> str:
        return self.config.kind


def read_torch_file(path, *, argument: str, required=()) -> dict:
    """Read a ``torch.save`` dict safely (``weights_only=True``: tensors and plain values only).

    Parameters
    ----------
    path : str or Path
        The file.
    argument : str
        The argument or option that named it (used in error messages, e.g. ``"--weights"``).
    required : iterable of str
        Keys the dict must hold.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Naming ``argument`` and the file: it holds other objects than tensors and plain values
        (refused unread: unpickling them could run code), it is truncated or not a torch file, it is
        not a dict, or it lacks a ``required`` key.
    """
    import pickle
    import warnings

    import torch

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{argument}: no such file {path}")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        first = str(exc).split("WeightsUnpickler error:")[-1].strip().splitlines()
        why = first[0] if first else ""
        raise ValueError(f"{argument}: {path} is not a plain weights file ({why}); refused without loading it, since "
                         "unpickling arbitrary objects could run code") from None
    except Exception as exc:  # truncated zip, garbage bytes, unknown format: never a traceback from torch
        raise ValueError(f"{argument}: {path} is not a readable torch file (truncated or corrupt? "
                         f"{type(exc).__name__}: {str(exc).splitlines()[0][:120] if str(exc) else ''})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{argument}: {path} holds a {type(data).__name__}, expected a weights or checkpoint dict")
    missing = [k for k in required if k not in data]
    if missing:
        raise ValueError(f"{argument}: {path} lacks the entries {missing}; is it a file made by ancsh?")
    return data


def weights_dir(category: str) -> Path:
    """Where ``category``'s networks and calibrations live: a built category's folder
    (:attr:`~ancsh.data.conventions.CategoryConvention.folder`), else the shipped :data:`WEIGHTS_DIR`."""
    from ...data.conventions import category_folder

    folder = category_folder(category)
    return WEIGHTS_DIR if folder is None else folder


def weights_file_name(category: str, kind: str = "ancsh") -> str:
    """``<category>.pt``, or ``<category>_<kind>.pt`` for the other networks (``refine``, baselines)."""
    return f"{category}.pt" if kind == "ancsh" else f"{category}_{kind}.pt"


def weights_path(category: str, kind: str = "ancsh") -> Path:
    """Path of the weights of ``category`` (:func:`weights_file_name`) in :func:`weights_dir`."""
    return weights_dir(category) / weights_file_name(category, kind)


def available_weights() -> list[str]:
    """Names (file stems) of the shipped weight files."""
    return sorted(p.stem for p in WEIGHTS_DIR.glob("*.pt"))


def shipped_categories(kind: str = "ancsh") -> list[str]:
    """Procedural categories with shipped weights of ``kind`` (``"ancsh"`` or ``"direct_voting"``)."""
    from ...data.procedural import CATEGORIES

    return [c for c in CATEGORIES if weights_path(c, kind).is_file()]


def export_weights(checkpoint, out_path, *, metrics: dict | None = None) -> Path:
    """Write a compact weights file from a training checkpoint (see the module docstring)."""
    import torch

    ck = read_torch_file(checkpoint, argument="checkpoint", required=("model", "config", "num_parts", "revolute", "step"))
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
        "lineage": _checkpoint_lineage(ck),
    }
    out = Path(out_path)
    buffer = io.BytesIO()  # serialised in memory: a full disk or a read-only folder fails a plain write (an OSError)
    torch.save(data, buffer)
    try:
        write_bytes_atomically(out, buffer.getbuffer())
    except OSError as exc:
        raise OSError(exc.errno, f"could not write the weights {out}: {exc.strerror or exc}") from None
    return out


def training_seconds(path) -> float:
    """Training wall time (s) behind a weights file: its run's history plus its lineage's.

    The run's time is the last ``elapsed_s`` of ``<stem>_history.csv`` beside ``path`` (0 without
    one); the lineage's is the ``train_s`` recorded in the file (:func:`parent_record`).
    """
    import csv

    path = Path(path)
    own = 0.0
    history = path.with_name(path.stem + "_history.csv")
    if history.is_file():
        with open(history, newline="") as f:
            rows = list(csv.DictReader(f))
        own = float(rows[-1]["elapsed_s"]) if rows else 0.0
    lineage = read_torch_file(path, argument="weights").get("lineage") or {}
    return own + float(lineage.get("train_s", 0.0))


def parent_record(loaded: "LoadedNetwork") -> dict:
    """What a fine-tuned network keeps of the weights it started from (``TrainConfig.init_weights``).

    Returns ``{"source": file name, "sha256", "step", "train_s"}``; ``train_s`` is
    :func:`training_seconds` of the parent (its run plus its own lineage), in seconds of wall time.
    """
    return {"source": Path(loaded.source).name, "sha256": loaded.sha256, "step": loaded.step,
            "train_s": training_seconds(loaded.source)}


def _checkpoint_lineage(ck: dict) -> dict | None:
    """The lineage of a checkpoint: its recorded parent, else (older checkpoints) one derived now.

    A checkpoint of a run started from ``init_weights="builtin"`` before parents were recorded
    gets the shipped weights of its category as they are at export (marked ``"derived_at_export"``):
    right as long as those were not replaced since the run started.
    """
    if ck.get("init") is not None:
        return dict(ck["init"])
    source = ck["config"].get("init_weights", "")
    if not source:
        return None
    cfg = ck["config"]
    loaded = load_network(cfg["category"] if source == "builtin" else source, kind=cfg["kind"])
    return {**parent_record(loaded), "derived_at_export": True}


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
    from ...outputs import file_sha256
    from .config import TrainConfig
    from .models import build_network

    path = Path(source)
    if not path.suffix and not path.exists():
        path = weights_path(str(source), kind)
        if not path.is_file():
            raise FileNotFoundError(
                f"source: no shipped weights for {source!r} ({kind}) at {path}; available: {available_weights() or 'none'}"
            )
    elif not path.is_file():
        raise FileNotFoundError(f"source: no such weights file {path}")
    ck = read_torch_file(path, argument="weights", required=("config", "num_parts", "revolute"))
    try:
        if "state_dict" in ck:
            state = ck["state_dict"]
            parents, children = ck["joint_parents"], ck["joint_children"]
        elif "model" in ck:
            state = ck["model"]
            parents, children = _structure(ck)
        else:
            raise ValueError("neither a weights file nor a training checkpoint (no state_dict / model entry)")
        config = TrainConfig.from_dict(ck["config"])
        revolute = np.array(ck["revolute"], dtype=bool)
        model = build_network(config.kind, int(ck["num_parts"]), len(revolute), **config.network_kwargs())
        model.load_state_dict(state)
    except (ValueError, TypeError, KeyError, RuntimeError) as exc:
        raise ValueError(f"weights: {path} does not hold a usable network: {str(exc).splitlines()[0][:200]}") from None
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
        sha256=file_sha256(path),
        lineage=ck.get("lineage") or ck.get("init"),
    )


def learning_curve_fit(elapsed_s, val_err, *, tail_fraction: float = 0.5) -> dict:
    """Power law ``err = a * t**b`` fitted to the late part of a validation curve, and what it projects.

    A least-squares line in log-log coordinates through the points with
    ``t >= (1 - tail_fraction) * t_final``. Extrapolation far beyond the measured range is only an
    order-of-magnitude guide (curves usually flatten further).

    Parameters
    ----------
    elapsed_s : (R,) float
        Training wall time of each validation, seconds (increasing, positive).
    val_err : (R,) float
        Validation error at those times (positive).
    tail_fraction : float
        Fraction of the run (by time, from its end) the fit uses, in ``(0, 1]``.

    Returns
    -------
    dict
        ``exponent`` ``b`` (negative while the error falls), ``points`` used, ``fitted_final``
        (the fit at the last time), and ``time_factor_2x`` / ``time_factor_5x``: the factors by
        which the training time must grow for 2x / 5x lower error (``inf`` when ``b >= 0``).

    Raises
    ------
    ValueError
        On mismatched lengths, non-positive or non-finite values, a bad ``tail_fraction``, or fewer
        than 3 points in the fitted range.
    """
    t = np.asarray(elapsed_s, dtype=np.float64)
    e = np.asarray(val_err, dtype=np.float64)
    if t.ndim != 1 or t.shape != e.shape:
        raise ValueError(f"val_err: expected the shape of elapsed_s {t.shape}, got {e.shape}")
    if not (np.all(np.isfinite(t)) and np.all(t > 0)):
        raise ValueError("elapsed_s: expected positive finite times")
    if not (np.all(np.isfinite(e)) and np.all(e > 0)):
        raise ValueError("val_err: expected positive finite errors")
    if not 0.0 < tail_fraction <= 1.0:
        raise ValueError(f"tail_fraction: expected a value in (0, 1], got {tail_fraction}")
    sel = t >= (1.0 - tail_fraction) * t.max()
    if sel.sum() < 3:
        raise ValueError(f"elapsed_s: {int(sel.sum())} points in the fitted range, need at least 3")
    b, log_a = np.polyfit(np.log(t[sel]), np.log(e[sel]), 1)
    with np.errstate(over="ignore", divide="ignore"):  # a flat curve projects no finite time
        factors = np.exp(np.log([2.0, 5.0]) / -b) if b < 0 else np.full(2, np.inf)
    return {
        "exponent": float(b), "points": int(sel.sum()), "fitted_final": float(np.exp(log_a) * t.max() ** b),
        "time_factor_2x": float(factors[0]), "time_factor_5x": float(factors[1]),
    }


def weights_summary() -> list[dict]:
    """One row per shipped weights file: kind (``refiner``: a refinement network), category, size, training step and
    wall time, held-out scores.

    The training wall time is the last ``elapsed_s`` of the ``<name>_history.csv`` shipped beside
    the weights (``nan`` without it), ``parent_min`` that of the weights a fine-tuned file started from
    (its lineage, 0 for a network trained from scratch); the scores are those stored in the file (held-out test frames,
    beside the trivial baselines: majority label, all-zero NPCS, mean axis). ``curve`` is
    :func:`learning_curve_fit` of the history's validation NPCS error (``None`` without one).
    ``pose_curve`` lists the history's pose validations (``TrainConfig.pose_val_every``: the fitted
    rotation and joint-axis errors of the validation instances through the full pipeline), each a dict
    of ``step``, ``minutes``, ``rot_deg``, ``axis_deg``, ``score`` (their sum, degrees); empty without any.
    ``num_threads``, ``batch_size`` and ``num_points`` are the training settings stored in the file's config.
    """
    import csv

    rows = []
    for name in available_weights():
        net = load_network(WEIGHTS_DIR / f"{name}.pt")
        history = WEIGHTS_DIR / f"{name}_history.csv"
        minutes, steps, curve, pose_curve = float("nan"), None, None, []
        if history.is_file():
            with open(history, newline="") as f:
                hist = list(csv.DictReader(f))
            pose_curve = [{"step": int(float(r["step"])), "minutes": float(r["elapsed_s"]) / 60.0,
                           "rot_deg": float(r["pose_rot_deg"]), "axis_deg": float(r["pose_axis_deg"]),
                           "score": float(r["pose_score"])} for r in hist if r.get("pose_score")]
            if hist:
                minutes, steps = float(hist[-1]["elapsed_s"]) / 60.0, int(float(hist[-1]["step"]))
            if hist and hist[0].get("val_npcs_err"):
                try:
                    curve = learning_curve_fit([float(r["elapsed_s"]) for r in hist], [float(r["val_npcs_err"]) for r in hist])
                except ValueError:  # too short a history to fit
                    curve = None
        m = net.metrics
        parent_min = float((net.lineage or {}).get("train_s", 0.0)) / 60.0
        rows.append({
            "name": name, "kind": net.kind, "refiner": bool(net.config.is_refiner), "category": net.config.category,
            "parts": net.num_parts,
            "size_mb": (WEIGHTS_DIR / f"{name}.pt").stat().st_size / 1e6, "step": net.step,
            "trained_steps": steps, "train_min": minutes, "parent_min": parent_min,
            "parent_step": (net.lineage or {}).get("step"), "test_frames": m.get("test_frames"), "curve": curve,
            "pose_curve": pose_curve,
            "num_threads": net.config.num_threads, "batch_size": net.config.batch_size,
            "num_points": net.config.num_points,
            **{k: m.get(k, float("nan")) for k in (
                "seg_acc", "seg_acc_majority", "npcs_err", "npcs_err_zero", "assoc_acc", "axis_err_deg")},
        })
    return rows


def missing_weights_error(category: str) -> FileNotFoundError:
    """The error for a category without ANCSH weights: for a built category folder, where they belong and how to make
    them; else the categories that have shipped ones."""
    from ...data.conventions import category_folder

    folder = category_folder(category)
    if folder is not None:
        return FileNotFoundError(f"category: {category!r} has no network yet ({weights_path(category)} is missing): "
                                 f"finish its build (`ancsh category build SPEC --urdfs ... --out {folder}` resumes it)")
    return FileNotFoundError(
        f"category: no shipped weights for {category!r}; available: {', '.join(shipped_categories()) or 'none'}"
    )
