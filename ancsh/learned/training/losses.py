"""Training losses (paper Sec. 4.2): relaxed IoU for segmentation and joint association,
mean squares for NPCS, NPCS->NAOCS scale/translation and the 7-D joint vector.

Total loss ``L = w1 L_seg + w2 L_NPCS + w3 L_NAOCS + w4 L_association + w5 L_joint`` with the
paper's weights ``[1, 10, 1, 1, 1]``. "Mean square" here is the squared Euclidean error of a
point's vector, averaged over the supervised points.

Beside them, an optional pose-aware term (:func:`npcs_pose_loss`): per part, the rotation of a
differentiable weighted Procrustes fit of the predicted NPCS onto the true NPCS -- the
orientation error that a pose fit of the part cannot remove (see
:func:`ancsh.studies.table1.npcs_error_budget`).

Every mean over the batch goes through :func:`~ancsh.learned.distributed.batch_mean` /
:func:`~ancsh.learned.distributed.batch_ratio`: a plain mean in one process, the mean over the global
batch in a distributed training step.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch

from ..network.config import POSE_LOSSES
from ..distributed import batch_mean, batch_ratio

__all__ = ["Targets", "relaxed_iou_loss", "ancsh_loss", "direct_voting_loss", "LOSS_NAMES", "procrustes_rotation",
           "npcs_pose_loss", "POSE_LOSSES"]

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
    return batch_mean((1.0 - iou)[present])


def _masked_sq(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Squared error summed over the last axis, averaged over points (masked)."""
    sq = (pred - target).square()
    if mask is None:
        return batch_mean(sq.sum(-1))
    sq = sq * mask
    points = (mask.amax(dim=-1) > 0).sum()
    return batch_ratio(sq.sum(), points)


def _take_part(values: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """Select the hypothesis of part ``labels`` from ``(B, N, M, ...)`` values."""
    idx = labels.view(*labels.shape, 1, *([1] * (values.dim() - 3)))
    idx = idx.expand(*labels.shape, 1, *values.shape[3:])
    return values.gather(2, idx).squeeze(2)


class _PolarRotation(torch.autograd.Function):
    """``R = argmax_{R in SO(3)} tr(R^T C)`` for ``(..., 3, 3)`` ``C``, with a backward pass that stays finite.

    Forward: ``C = U diag(s) V^T`` (torch SVD), ``D = diag(1, 1, det(U V^T))``, ``R = U D V^T``.
    With ``s' = s D`` (the signed singular values), ``R`` is the orthogonal polar factor of
    ``C = U diag(s') (V D)^T``; its derivative is ``dR = U W (V D)^T`` with ``W`` antisymmetric,
    ``W_ij = (A_ij - A_ji) / (s'_i + s'_j)``, ``A = U^T dC V D``. The denominators vanish only
    where the rotation is not determined (two vanishing singular values: collinear or coincident
    points; or ``s_2 = s_3`` with a reflection); there they are clamped to ``eps``, so gradients stay
    finite (large but never NaN). The generic SVD gradient, with ``1 / (s_i^2 - s_j^2)`` terms, is
    not used.
    """

    @staticmethod
    def forward(ctx, C, eps):
        U, s, Vh = torch.linalg.svd(C)
        d = torch.linalg.det(U @ Vh).sign()
        d = torch.where(d == 0, torch.ones_like(d), d)
        sign = torch.stack([torch.ones_like(d), torch.ones_like(d), d], dim=-1)  # (..., 3)
        Vd = Vh.transpose(-1, -2) * sign.unsqueeze(-2)  # V D
        R = U @ Vd.transpose(-1, -2)
        ctx.save_for_backward(U, Vd, s * sign)
        ctx.eps = eps
        return R

    @staticmethod
    def backward(ctx, grad_R):
        U, Vd, s_signed = ctx.saved_tensors
        B = U.transpose(-1, -2) @ grad_R @ Vd
        denom = s_signed.unsqueeze(-1) + s_signed.unsqueeze(-2)
        denom = torch.where(denom.abs() < ctx.eps, torch.full_like(denom, ctx.eps), denom)
        Cg = (B - B.transpose(-1, -2)) / denom
        return U @ Cg @ Vd.transpose(-1, -2), None


def procrustes_rotation(cross_covariance: torch.Tensor, eps: float = 1e-6) -> torch.Tensor:
    """The rotation of a (weighted) Procrustes / Umeyama fit from its cross-covariance, differentiably.

    For source points ``p_n`` and target points ``q_n`` (weights ``w_n``), the rotation minimising
    ``sum w_n |R (p_n - mu_p) - (q_n - mu_q)|^2`` over SO(3) (reflections excluded) maximises
    ``tr(R^T C)`` with ``C = sum w_n (q_n - mu_q)(p_n - mu_p)^T``.

    Parameters
    ----------
    cross_covariance : (..., 3, 3) tensor
        ``C`` as above (target x source).
    eps : float
        Floor of ``|s_i + s_j|`` in the backward pass (see :class:`_PolarRotation`), positive.

    Returns
    -------
    (..., 3, 3) tensor
        Rotation matrices (det +1) ``R`` with ``q - mu_q ~ R (p - mu_p)``.
    """
    if cross_covariance.shape[-2:] != (3, 3):
        raise ValueError(f"cross_covariance: expected shape (..., 3, 3), got {tuple(cross_covariance.shape)}")
    if not eps > 0:
        raise ValueError(f"eps: expected a positive number, got {eps}")
    return _PolarRotation.apply(cross_covariance, float(eps))


def npcs_pose_loss(pred: torch.Tensor, true: torch.Tensor, labels: torch.Tensor, num_parts: int, *,
                   min_points: int = 4, min_spread: float = 1e-4, kind: str = "chordal") -> torch.Tensor:
    """Mean over (frame, part) of a distance of the Procrustes rotation ``R`` fitted from a part's
    predicted NPCS onto its true NPCS from the identity.

    ``R`` is the orientation error the predicted NPCS of the part carry (the quantity the pose of the
    part inherits); either loss is 0 exactly when every part's prediction is a rotation-free
    (translated, scaled, deformed without rotating) copy of the truth, and smooth at the truth.
    Points are weighted uniformly within their true part. ``kind``:

    - ``"chordal"``: the squared chordal distance ``|R - I|_F^2 = 4 (1 - cos theta)``, at most 8, the same
      for every axis of the error;
    - ``"displacement"``: the mean squared distance by which ``R`` moves the part's centred true NPCS
      ``q_i``, ``mean_i |(R - I) q_i|^2 = tr((R - I) S (R - I)^T)`` with ``S`` their covariance (NPCS units
      squared, the rotational share of the NPCS error): an error about an axis along which the part is
      long moves its points little. For a thin part (an eyeglasses temple) the rotation about its long
      axis is barely determined by its points, and the chordal loss's gradient there is about 100x the
      base's (measured on shipped eyeglasses frames); this one weighs that rotation by what it moves.

    Parts are left out (no loss, no gradient) when they are degenerate in the ground truth: fewer
    than ``min_points`` points, or true NPCS that do not span a plane (second eigenvalue of their
    covariance below ``min_spread`` times the first: collinear or coincident points). A degenerate
    *prediction* of a valid part gets finite gradients (:func:`procrustes_rotation`).

    Parameters
    ----------
    pred : (B, N, 3) tensor
        Predicted NPCS of each point's true part.
    true : (B, N, 3) tensor
        True NPCS.
    labels : (B, N) int64 tensor
        True part labels ``0..num_parts-1``.
    num_parts : int
    min_points : int
        At least 3.
    min_spread : float
        In ``[0, 1)``.
    kind : str
        One of :data:`POSE_LOSSES`.

    Returns
    -------
    () tensor
        0 (with a zero gradient) when no part qualifies.
    """
    if pred.dim() != 3 or pred.shape[-1] != 3 or true.shape != pred.shape or labels.shape != pred.shape[:2]:
        raise ValueError(f"pred, true, labels: expected (B, N, 3), (B, N, 3), (B, N), got {tuple(pred.shape)}, "
                         f"{tuple(true.shape)}, {tuple(labels.shape)}")
    if isinstance(min_points, bool) or not isinstance(min_points, int) or min_points < 3:
        raise ValueError(f"min_points: expected an integer >= 3, got {min_points!r}")
    if not 0 <= min_spread < 1:
        raise ValueError(f"min_spread: expected a number in [0, 1), got {min_spread!r}")
    if kind not in POSE_LOSSES:
        raise ValueError(f"kind: expected one of {POSE_LOSSES}, got {kind!r}")
    w = torch.nn.functional.one_hot(labels, num_parts).to(pred.dtype)  # (B, N, M)
    count = w.sum(1)  # (B, M)
    safe_count = count.clamp_min(1.0).unsqueeze(-1)

    def centred(x):  # (B, N, M, 3), zero outside the part
        mu = torch.einsum("bnm,bnc->bmc", w, x) / safe_count
        return (x.unsqueeze(2) - mu.unsqueeze(1)) * w.unsqueeze(-1)

    q, p = centred(true), centred(pred)
    C = torch.einsum("bnmi,bnmj->bmij", q, p)  # (B, M, 3, 3)
    with torch.no_grad():
        S = torch.einsum("bnmi,bnmj->bmij", q, q) / safe_count.unsqueeze(-1)  # covariance of the true NPCS
        ev = torch.linalg.eigvalsh(S)  # ascending
        valid = (count >= min_points) & (ev[..., 2] > 0) & (ev[..., 1] > min_spread * ev[..., 2])
    eye = torch.eye(3, dtype=pred.dtype, device=pred.device)
    # Invalid parts get a well-conditioned stand-in (R = I, zero loss); `where` passes them no gradient.
    safe = torch.diag(torch.tensor([3.0, 2.0, 1.0], dtype=pred.dtype, device=pred.device))
    C = torch.where(valid[..., None, None], C, safe)
    R = procrustes_rotation(C)
    if kind == "chordal":
        per_part = (R - eye).square().sum((-1, -2))
    else:
        D = R - eye
        per_part = (D @ S * D).sum((-1, -2))  # tr(D S D^T): exactly 0 at R = I
    return batch_ratio((per_part * valid).sum(), valid.sum())


def ancsh_loss(outputs: dict, targets: Targets, weights=(1.0, 10.0, 1.0, 1.0, 1.0), pose_weight: float = 0.0,
               pose_loss: str = "chordal") -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Weighted ANCSH loss; returns the total and the unweighted components keyed by :data:`LOSS_NAMES`.

    NPCS, scale and translation are taken at the ground-truth part (during training). With
    ``pose_weight > 0`` the total adds ``pose_weight *`` :func:`npcs_pose_loss` of kind ``pose_loss``
    (component ``"pose"``).
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
    if pose_weight:
        npcs = _take_part(outputs["npcs"], targets.labels)
        parts["pose"] = npcs_pose_loss(npcs, targets.npcs, targets.labels, outputs["npcs"].shape[2], kind=pose_loss)
        total = total + pose_weight * parts["pose"]
    return total, parts


def direct_voting_loss(outputs: dict, targets: Targets, weights=(1.0, 10.0, 1.0, 1.0, 1.0), pose_weight: float = 0.0,
                       pose_loss: str = "chordal") -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Loss of the direct-voting baseline: segmentation, association, camera-frame joint votes.

    The vote distance is compared in units of the normalised cloud (divided by ``cloud_scale``)
    so the loss does not depend on the object's size in metres. NPCS/NAOCS components are zero;
    ``pose_weight`` must be 0 (the network predicts no NPCS); ``pose_loss`` is accepted for the common signature and
    unused.
    """
    if pose_weight:
        raise ValueError(f"pose_weight: the direct-voting network predicts no NPCS, got {pose_weight}")
    s = outputs["cloud_scale"]
    unit = torch.ones(7, dtype=s.dtype, device=s.device)
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
