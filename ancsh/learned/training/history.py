"""A training run's history: one :class:`HistoryRow` per logged step, written as ``history.csv`` and drawn as
``curves.png`` (losses, validation metrics and pose scores over steps)."""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np

from .losses import LOSS_NAMES


@dataclass(frozen=True)
class HistoryRow:
    """One row of a training history: measured by :meth:`Trainer.measure`, written by :meth:`Trainer.record`.

    Attributes
    ----------
    step : int
        Optimisation steps done.
    elapsed_s : float
        Training wall time so far, seconds (rounded to 0.1 s).
    lr : float
        Learning rate of the last step.
    train : mapping of str to float
        Mean training loss components since the previous row (``total`` and :data:`LOSS_NAMES`).
    val : mapping of str to float
        :func:`evaluate_arrays` on the validation frames; empty without validation frames.
    pose : mapping of str to float
        :meth:`PoseValidation.evaluate` (``pose_score``, ...); empty when it did not run for this row.
    """

    step: int
    elapsed_s: float
    lr: float
    train: Mapping[str, float] = field(default_factory=dict)
    val: Mapping[str, float] = field(default_factory=dict)
    pose: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self):
        for name in ("train", "val", "pose"):
            object.__setattr__(self, name, MappingProxyType(dict(getattr(self, name))))

    def to_dict(self) -> dict:
        """The flat row of ``history.csv``: ``step, elapsed_s, lr, train_<k>..., val_<k>...`` and the pose keys
        as :meth:`PoseValidation.evaluate` names them (``pose_...``)."""
        return {"step": self.step, "elapsed_s": self.elapsed_s, "lr": self.lr,
                **{f"train_{k}": v for k, v in self.train.items()},
                **{f"val_{k}": v for k, v in self.val.items()},
                **self.pose}

    def selection_score(self, *, pose: bool) -> float | None:
        """The number ``best.pt`` minimises: ``pose_score`` when ``pose`` (the run has a pose validation),
        else the validation loss; ``None`` when this row has not measured it."""
        return self.pose.get("pose_score") if pose else self.val.get("total")


def write_history_csv(history: Sequence[Mapping], path) -> None:
    """Write history rows (dicts, :meth:`HistoryRow.to_dict`) as CSV; the columns are the union of the rows'
    keys in order of first appearance, empty where a row lacks one."""
    keys: list[str] = []
    for row in history:
        keys += [k for k in row if k not in keys]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(history)


def plot_history(history: list[dict], path, title: str = "") -> None:
    """Training curves: losses (log scale) and validation metrics against the step, as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = [r["step"] for r in history]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for i, k in enumerate(("total", *LOSS_NAMES, "pose")):
        for prefix, style in (("train_", "-"), ("val_", "--")):  # one colour per loss: solid train, dashed val
            ys = [r.get(prefix + k, np.nan) for r in history]
            if np.any(np.isfinite(ys)) and np.nanmax(ys) > 0:
                axes[0].plot(steps, ys, style, color=f"C{i}", label=prefix + k)
    axes[0].set_yscale("log")
    axes[0].set_xlabel("step")
    axes[0].set_title("losses")
    axes[0].legend(fontsize=7, ncol=2)
    for k in ("val_seg_acc", "val_assoc_acc", "val_npcs_err"):
        ys = [r.get(k, np.nan) for r in history]
        if np.any(np.isfinite(ys)):
            axes[1].plot(steps, ys, label=k)
    axes[1].set_xlabel("step")
    axes[1].set_title("validation metrics")
    if axes[1].lines:  # none without validation frames
        axes[1].legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
