"""Training losses (paper Sec. 4.2): relaxed IoU for segmentation and joint association,
mean squares for NPCS, NPCS->NAOCS scale/translation and the 7-D joint vector.

Total loss ``L = w1 L_seg + w2 L_NPCS + w3 L_NAOCS + w4 L_association + w5 L_joint`` with the
paper's weights ``[1, 10, 1, 1, 1]``. "Mean square" here is the squared Euclidean error of a
point's vector, averaged over the supervised points.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch

__all__ = ["Targets", "relaxed_iou_loss", "ancsh_loss", "direct_voting_loss", "LOSS_NAMES"]

LOSS_NAMES = ("seg", "npcs", "naocs", "assoc", "joint")


@dataclass(frozen=True)
class Targets:
    """Per-point supervision of a batch (``B`` frames of ``N`` points), float32/int64 tensors.

    Attributes
    ----------
    labels : (B, N) int64
        Part labels ``0..M-1``.
    npcs : (B, N, 3)
        NPCS coordinates.
    scale : (B, N)
        NPCS -> NAOCS scale of the point's part.
    translation : (B, N, 3)
        NPCS -> NAOCS translation of the point's part.
    association : (B, N) int64
        0 = no joint, ``k + 1`` = joint ``k``.
    joint : (B, N, 7)
        NAOCS joint vector (axis, unit direction to the axis, distance).
    joint_mask : (B, N, 7)
        1 where ``joint`` is supervised (axis: associated points; the other four: revolute only).
    joint_cam : (B, N, 7)
        The same vector in the camera frame, distance in metres (direct-voting baseline).
    """

    labels: torch.Tensor
    npcs: torch.Tensor
    scale: torch.Tensor
    translation: torch.Tensor
    association: torch.Tensor
    joint: torch.Tensor
    joint_mask: torch.Tensor
    joint_cam: torch.Tensor

    def __getitem__(self, index) -> "Targets":
        return Targets(**{f.name: getattr(self, f.name)[index] for f in fields(self)})


def relaxed_iou_loss(logits: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """``1 -`` mean soft IoU between softmax probabilities and one-hot labels (Yi et al. 2018).

    For each frame and each class present in its labels, ``IoU = sum(p g) / (sum p + sum g - sum(p g))``;
    the loss averages ``1 - IoU`` over those (frame, class) pairs. It lies in ``[0, 1]`` and is 0
    exactly when the probabilities equal the one-hot labels.

    Parameters
    ----------
    logits : (B, N, C) tensor
    labels : (B, N) int64 tensor in ``0..C-1``
    """
    if logits.dim() != 3 or labels.shape != logits.shape[:2]:
        raise ValueError(f"logits, labels: expected (B, N, C) and (B, N), got {tuple(logits.shape)} and {tuple(labels.shape)}")
    p = logits.softmax(dim=-1)
    g = torch.nn.functional.one_hot(labels, logits.shape[-1]).to(p.dtype)
    inter = (p * g).sum(1)
    union = p.sum(1) + g.sum(1) - inter
    present = g.sum(1) > 0
    iou = inter / union.clamp_min(1e-8)
    return (1.0 - iou)[present].mean()


def _masked_sq(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Squared error summed over the last axis, averaged over points (masked)."""
    sq = (pred - target).square()
    if mask is None:
        return sq.sum(-1).mean()
    sq = sq * mask
    points = (mask.amax(dim=-1) > 0).sum()
    return sq.sum() / points.clamp_min(1)


def _take_part(values: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """Select the hypothesis of part ``labels`` from ``(B, N, M, ...)`` values."""
    idx = labels.view(*labels.shape, 1, *([1] * (values.dim() - 3)))
    idx = idx.expand(*labels.shape, 1, *values.shape[3:])
    return values.gather(2, idx).squeeze(2)


def ancsh_loss(outputs: dict, targets: Targets, weights=(1.0, 10.0, 1.0, 1.0, 1.0)) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Weighted ANCSH loss; returns the total and the unweighted components keyed by :data:`LOSS_NAMES`.

    NPCS, scale and translation are taken at the ground-truth part (during training).
    """
    parts = {
        "seg": relaxed_iou_loss(outputs["seg_logits"], targets.labels),
        "npcs": _masked_sq(_take_part(outputs["npcs"], targets.labels), targets.npcs),
        "naocs": _masked_sq(_take_part(outputs["scale"], targets.labels).unsqueeze(-1), targets.scale.unsqueeze(-1))
        + _masked_sq(_take_part(outputs["translation"], targets.labels), targets.translation),
        "assoc": relaxed_iou_loss(outputs["assoc_logits"], targets.association),
        "joint": _masked_sq(outputs["joint"], targets.joint, targets.joint_mask),
    }
    total = sum(w * parts[k] for w, k in zip(weights, LOSS_NAMES))
    return total, parts


def direct_voting_loss(outputs: dict, targets: Targets, weights=(1.0, 10.0, 1.0, 1.0, 1.0)) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Loss of the direct-voting baseline: segmentation, association, camera-frame joint votes.

    The vote distance is compared in units of the normalised cloud (divided by ``cloud_scale``)
    so the loss does not depend on the object's size in metres. NPCS/NAOCS components are zero.
    """
    s = outputs["cloud_scale"]
    unit = torch.ones(7, dtype=s.dtype)
    pred = outputs["joint"] / torch.cat([unit[:6].expand(*s.shape[:-1], 6), s], dim=-1)
    target = targets.joint_cam / torch.cat([unit[:6].expand(*s.shape[:-1], 6), s], dim=-1)
    zero = pred.new_zeros(())
    parts = {
        "seg": relaxed_iou_loss(outputs["seg_logits"], targets.labels),
        "npcs": zero,
        "naocs": zero,
        "assoc": relaxed_iou_loss(outputs["assoc_logits"], targets.association),
        "joint": _masked_sq(pred, target, targets.joint_mask),
    }
    total = sum(w * parts[k] for w, k in zip(weights, LOSS_NAMES))
    return total, parts
