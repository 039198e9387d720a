"""Choosing the checkpoint to ship: the full pipeline on *all* frames of a run's validation instances.

During training, :class:`~ancsh.learned.training.train.PoseValidation` scores a few hundred validation
frames every few hundred steps and keeps the best as ``best.pt``. With one score every 500 steps
and about ±0.5° of noise at 256 frames, the pick between ``best.pt`` and ``last.pt`` (or any other
checkpoint) is worth confirming on every frame of the validation instances before a network is
shipped. :func:`confirm_checkpoints` does that, and ``ancsh export`` turns it into a reproducible
step: it re-creates the run's validation split from its own config (the same
:func:`~ancsh.learned.training.train.split_by_instance` seed), scores each candidate through
``fit(..., "exact_reduced")`` and exports the lowest score (``pose_score`` = mean fitted part
rotation error + mean joint-axis error, degrees). Validation instances are never test instances:
the split is of the *training* shards.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["validation_frame_indices", "confirm_checkpoints", "choose"]


def validation_frame_indices(instance, val_instances, count: int | None = None) -> np.ndarray:
    """Frame indices (into the shards) of the validation instances, ``count`` of them evenly spaced.

    Parameters
    ----------
    instance : (F,) int array
        Instance of every frame of the shards (``TrainingArrays.instance``).
    val_instances : array of int
        The validation instances (``np.unique(val.instance)`` of :func:`~ancsh.learned.training.train.split_by_instance`).
    count : int, optional
        At most this many frames, evenly spaced over the validation frames in shard order
        (``TrainConfig.pose_val_frames``); ``None``: all of them.
    """
    frames = np.flatnonzero(np.isin(np.asarray(instance), np.asarray(val_instances)))
    if count is None or count >= len(frames):
        return frames
    if count < 1:
        raise ValueError(f"count: expected at least 1 frame, got {count}")
    return frames[np.linspace(0, len(frames) - 1, count).round().astype(int)]


def confirm_checkpoints(checkpoints, data, config, *, frames: int | None = None) -> list[dict]:
    """Score checkpoints of one run on its validation instances through the full pipeline.

    Parameters
    ----------
    checkpoints : sequence of path
        Training checkpoints (``best.pt``, ``last.pt``, ...) or weights files of the run's network.
    data : path or list of paths
        The run's training shards (the split is re-created from them).
    config : TrainConfig
        The run's config: ``num_points``, ``val_fraction`` and ``seed`` define the split exactly as in
        training; ``seed`` also seeds the provider and RANSAC (:class:`~ancsh.learned.training.train.PoseValidation`).
    frames : int, optional
        Score this many evenly spaced validation frames; ``None`` (default): all of them.

    Returns
    -------
    list of dict
        Per checkpoint, in the given order: ``checkpoint`` (path as given), ``step``, ``sha256``,
        ``frames`` and :meth:`PoseValidation.evaluate`'s ``pose_*`` means (degrees).
    """
    from .data import arrays_from_dataset
    from .train import PoseValidation, split_by_instance
    from ..network.weights import load_network

    checkpoints = [Path(c) for c in checkpoints]
    if not checkpoints:
        raise ValueError("checkpoints: expected at least one checkpoint")
    for c in checkpoints:
        if not c.is_file():
            raise FileNotFoundError(f"checkpoints: no file {c}")
    arrays = arrays_from_dataset(data, config.num_points, seed=config.seed)
    _, val = split_by_instance(arrays, config.val_fraction, config.seed)
    if val is None:
        raise ValueError("config: val_fraction is 0, so the run has no validation instances to score on")
    picks = validation_frame_indices(arrays.instance, np.unique(val.instance), frames)
    validation = PoseValidation.from_dataset(data, picks, seed=config.seed)
    rows = []
    for c in checkpoints:
        net = load_network(c)
        rows.append({"checkpoint": str(c), "step": net.step, "sha256": net.sha256, "frames": len(picks),
                     **validation.evaluate(net)})
    return rows


def choose(rows: list[dict]) -> dict:
    """The row of :func:`confirm_checkpoints` with the lowest ``pose_score`` (the first of equal ones)."""
    if not rows:
        raise ValueError("rows: nothing to choose from")
    return min(rows, key=lambda r: r["pose_score"])  # min keeps the first of equal scores
