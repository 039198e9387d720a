"""The ANCSH network (paper Sec. 4.2) and the direct joint-voting baseline network.

Both take a depth point cloud in the camera frame, centre it on its centroid and
scale it into the unit ball (:func:`normalize_cloud`), run PointNet++ and predict
per-point heads. NPCS/NAOCS outputs are scale-free; camera-space outputs of the
direct-voting network are mapped back to metres by :func:`denormalize_joint_votes`.

Heads of :class:`AncshNet` (``M`` parts, ``K`` joints, ``N`` points):

==================  =============  ===============================================
key                 shape          meaning
==================  =============  ===============================================
``seg_logits``      (B, N, M)      part segmentation
``npcs``            (B, N, M, 3)   NPCS coordinates for every part hypothesis
``scale``           (B, N, M)      NPCS -> NAOCS scale ``G_s`` per part hypothesis (> 0, softplus)
``translation``     (B, N, M, 3)   NPCS -> NAOCS translation ``G_t``
``assoc_logits``    (B, N, K + 1)  joint association (0 = none, k + 1 = joint k)
``joint``           (B, N, 7)      NAOCS axis (3), unit direction to the axis (3),
                                   distance to the axis (1)
==================  =============  ===============================================

The paper uses two PointNet++ backbones (segmentation + NPCS; NAOCS + joints);
``backbones=1`` shares one backbone between all heads (cheaper on a CPU).
"""

from __future__ import annotations

import dataclasses

import torch
from torch import nn

from .normals import estimate_normals, normal_neighbours
from .pointnet2 import Neighbourhoods, PointNet2Backbone, shared_mlp

__all__ = ["AncshNet", "DirectVotingNet", "build_network", "load_adding_normals", "load_matching", "normalize_cloud", "denormalize_joint_votes"]


def normalize_cloud(points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Centre ``(B, N, 3)`` points on their centroid and scale into the unit ball.

    Returns
    -------
    normalized : (B, N, 3) tensor
    centroid : (B, 1, 3) tensor
        In the input unit (metres).
    scale : (B, 1, 1) tensor
        Largest distance from the centroid; ``points = normalized * scale + centroid``.
    """
    if points.dim() != 3 or points.shape[-1] != 3:
        raise ValueError(f"points: expected shape (B, N, 3), got {tuple(points.shape)}")
    centroid = points.mean(dim=1, keepdim=True)
    centred = points - centroid
    scale = centred.norm(dim=-1).amax(dim=1).clamp_min(1e-6).view(-1, 1, 1)
    return centred / scale, centroid, scale


def denormalize_joint_votes(joint: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    """Map camera-space 7-D joint votes from the normalised cloud back to metres (distance only)."""
    return torch.cat([joint[..., :6], joint[..., 6:] * scale], dim=-1)


def _check_normals(normals) -> bool:
    if not isinstance(normals, bool):
        raise ValueError(f"normals: expected true or false, got {normals!r}")
    return normals


def _check_structure(num_parts: int, num_joints: int) -> None:
    if num_parts < 2:
        raise ValueError(f"num_parts: expected >= 2, got {num_parts}")
    if num_joints < 1:
        raise ValueError(f"num_joints: expected >= 1, got {num_joints}")


class _Head(nn.Sequential):
    """A per-point head: ``[Conv1d, BatchNorm, ReLU]`` then a ``Conv1d`` to ``c_out`` channels."""

    def __init__(self, c_in: int, c_out: int, hidden: int):
        super().__init__(shared_mlp([c_in, hidden], dim=1), nn.Conv1d(hidden, c_out, 1))

    def forward_last(self, x: torch.Tensor) -> torch.Tensor:
        """Channel-last ``(B, N, C_in) -> (B, N, C_out)`` with the same parameters."""
        conv = self[1]
        return nn.functional.linear(self[0].forward_last(x), conv.weight.squeeze(-1), conv.bias)


def _head(c_in: int, c_out: int, hidden: int) -> _Head:
    return _Head(c_in, c_out, hidden)


def _per_point(backbone, xyz: torch.Tensor, neighbourhoods, features=None) -> tuple[torch.Tensor, bool]:
    """Backbone features ``(B, N, C)`` (channel-last) or ``(B, C, N)``, and whether they are channel-last."""
    if backbone.channels_last:
        return backbone.forward_last(xyz, neighbourhoods, features), True
    return backbone(xyz, neighbourhoods, features), False


def _input_features(points: torch.Tensor, normals: bool, neighbourhoods: Neighbourhoods | None) -> torch.Tensor | None:
    """The backbone's per-point input features of camera-frame ``points``: their surface normals
    (:func:`~ancsh.learned.network.normals.estimate_normals`, facing the camera; with the cached nearest
    points of ``neighbourhoods.normal_idx`` where given) or none."""
    if not normals:
        return None
    return estimate_normals(points, neighbours=None if neighbourhoods is None else neighbourhoods.normal_idx)


def _neighbourhoods(backbone: PointNet2Backbone, points: torch.Tensor, normals: bool) -> Neighbourhoods:
    """A network's :class:`Neighbourhoods` of camera-frame ``points``: the backbone's of the normalised cloud,
    and with input ``normals`` the points' :func:`~ancsh.learned.network.normals.normal_neighbours`."""
    nb = backbone.neighbourhoods(normalize_cloud(points)[0])
    return dataclasses.replace(nb, normal_idx=normal_neighbours(points)) if normals else nb


def _apply(head: _Head, features: torch.Tensor, last: bool) -> torch.Tensor:
    """``head`` on features from :func:`_per_point`, as ``(B, N, C_out)``."""
    return head.forward_last(features) if last else head(features).transpose(1, 2)


class AncshNet(nn.Module):
    """ANCSH network: segmentation, NPCS, NPCS->NAOCS scale/translation, joint association, 7-D joint vector.

    Parameters
    ----------
    num_parts : int
        ``M >= 2``.
    num_joints : int
        ``K >= 1``.
    width, npoints, radii, nsamples :
        Backbone settings (:class:`~ancsh.learned.network.pointnet2.PointNet2Backbone`).
    backbones : int
        1 (shared) or 2 (the paper's layout).
    normals : bool
        Give the backbone each point's surface normal (estimated from the input cloud, facing the
        camera: :func:`~ancsh.learned.network.normals.estimate_normals`) beside its coordinates.
    """

    kind = "ancsh"

    def __init__(self, num_parts: int, num_joints: int, *, width=0.25, npoints=(256, 64), radii=(0.2, 0.4), nsamples=(32, 32), backbones=1,
                 normals: bool = False):
        super().__init__()
        _check_structure(num_parts, num_joints)
        if backbones not in (1, 2):
            raise ValueError(f"backbones: expected 1 or 2, got {backbones}")
        self.num_parts, self.num_joints = num_parts, num_joints
        self.normals = _check_normals(normals)
        kw = dict(width=width, npoints=npoints, radii=radii, nsamples=nsamples, in_features=3 if normals else 0)
        self.backbone = PointNet2Backbone(**kw)
        self.backbone2 = PointNet2Backbone(**kw) if backbones == 2 else None
        c = self.backbone.out_channels
        M, K = num_parts, num_joints
        self.seg_head = _head(c, M, c)
        self.npcs_head = _head(c, 3 * M, c)
        self.naocs_head = _head(c, 4 * M, c)
        self.assoc_head = _head(c, K + 1, c)
        self.joint_head = _head(c, 7, c)

    def neighbourhoods(self, points: torch.Tensor) -> Neighbourhoods:
        """Sampling, grouping and interpolation indices of camera-frame points ``(B, N, 3)`` (no gradient).

        They depend only on the points, so a training loop can compute them once per frame and
        pass them to :meth:`forward` (both backbones share them). With input normals they hold each
        point's nearest points too (``normal_idx``), which a rotation of the points leaves unchanged.
        """
        return _neighbourhoods(self.backbone, points, self.normals)

    def forward(self, points: torch.Tensor, neighbourhoods: Neighbourhoods | None = None) -> dict[str, torch.Tensor]:
        """Predict every head for camera-frame points ``(B, N, 3)``; see the module table.

        ``neighbourhoods``: :meth:`neighbourhoods` of the same points (computed when omitted).
        """
        xyz, _, _ = normalize_cloud(points)
        features = _input_features(points, self.normals, neighbourhoods)
        f1, last = _per_point(self.backbone, xyz, neighbourhoods, features)
        f2 = f1 if self.backbone2 is None else _per_point(self.backbone2, xyz, neighbourhoods, features)[0]
        B, N = points.shape[:2]
        M = self.num_parts
        naocs = _apply(self.naocs_head, f2, last)
        return {
            "seg_logits": _apply(self.seg_head, f1, last),
            "npcs": _apply(self.npcs_head, f1, last).reshape(B, N, M, 3),
            "scale": nn.functional.softplus(naocs[..., :M]) + 1e-4,
            "translation": naocs[..., M:].reshape(B, N, M, 3),
            "assoc_logits": _apply(self.assoc_head, f2, last),
            "joint": _apply(self.joint_head, f2, last),
        }


class DirectVotingNet(nn.Module):
    """Baseline: segmentation, joint association and 7-D joint votes directly in the camera frame.

    The 7-D vector is (camera-frame axis, unit direction from the point to the axis,
    distance to the axis in metres); the distance is predicted in the normalised
    cloud and scaled back by :func:`denormalize_joint_votes`.
    """

    kind = "direct_voting"

    def __init__(self, num_parts: int, num_joints: int, *, width=0.25, npoints=(256, 64), radii=(0.2, 0.4), nsamples=(32, 32), backbones=1,
                 normals: bool = False):
        super().__init__()
        _check_structure(num_parts, num_joints)
        if backbones != 1:
            raise ValueError(f"backbones: the direct-voting network has one backbone, got {backbones}")
        self.num_parts, self.num_joints = num_parts, num_joints
        self.normals = _check_normals(normals)
        self.backbone = PointNet2Backbone(width=width, npoints=npoints, radii=radii, nsamples=nsamples, in_features=3 if normals else 0)
        c = self.backbone.out_channels
        self.seg_head = _head(c, num_parts, c)
        self.assoc_head = _head(c, num_joints + 1, c)
        self.joint_head = _head(c, 7, c)

    def neighbourhoods(self, points: torch.Tensor) -> Neighbourhoods:
        """As :meth:`AncshNet.neighbourhoods`."""
        return _neighbourhoods(self.backbone, points, self.normals)

    def forward(self, points: torch.Tensor, neighbourhoods: Neighbourhoods | None = None) -> dict[str, torch.Tensor]:
        """``(B, N, 3)`` camera points -> ``seg_logits``, ``assoc_logits``, ``joint`` (distance in metres),
        ``cloud_scale`` ``(B, 1, 1)`` (metres per normalised unit, see :func:`normalize_cloud`).

        ``neighbourhoods`` as in :meth:`AncshNet.forward`."""
        xyz, _, scale = normalize_cloud(points)
        f, last = _per_point(self.backbone, xyz, neighbourhoods, _input_features(points, self.normals, neighbourhoods))
        joint = _apply(self.joint_head, f, last)
        return {
            "seg_logits": _apply(self.seg_head, f, last),
            "assoc_logits": _apply(self.assoc_head, f, last),
            "joint": denormalize_joint_votes(joint, scale),
            "cloud_scale": scale,
        }


def build_network(kind: str, num_parts: int, num_joints: int, **backbone) -> nn.Module:
    """Construct :class:`AncshNet` (``kind="ancsh"``) or :class:`DirectVotingNet` (``"direct_voting"``)."""
    classes = {"ancsh": AncshNet, "direct_voting": DirectVotingNet}
    if kind not in classes:
        raise ValueError(f"kind: expected one of {sorted(classes)}, got {kind!r}")
    return classes[kind](num_parts, num_joints, **backbone)


def load_adding_normals(model: nn.Module, state: dict) -> None:
    """Load into ``model`` (a network with input normals) the parameters ``state`` of the same network
    without them: the weights on the normals start at zero, so ``model`` then predicts exactly what the
    source network predicts, and fine-tuning starts from there (:meth:`PointNet2Backbone.state_with_input_features`).

    Parameters
    ----------
    model : AncshNet or DirectVotingNet
        Built with ``normals=True``; changed in place.
    state : dict
        ``state_dict()`` of the same kind of network, same widths and heads, built with ``normals=False``.
    """
    if not getattr(model, "normals", False):
        raise ValueError("model: expected a network with input normals (normals=True)")
    backbones = {name: m for name, m in model.named_children() if isinstance(m, PointNet2Backbone)}
    own = model.state_dict()
    if set(state) != set(own):
        raise ValueError(f"state: the source network has other parameters ({sorted(set(state) ^ set(own))[:4]} ...)")
    merged = {}
    for prefix, backbone in backbones.items():
        part = {k[len(prefix) + 1:]: v for k, v in state.items() if k.startswith(prefix + ".")}
        merged.update({f"{prefix}.{k}": v for k, v in backbone.state_with_input_features(part).items()})
    for name, value in state.items():
        if name not in merged:
            if value.shape != own[name].shape:
                raise ValueError(f"state: {name} has shape {tuple(value.shape)}, expected {tuple(own[name].shape)}")
            merged[name] = value
    model.load_state_dict(merged)


def load_matching(model: nn.Module, state: dict) -> int:
    """Load into ``model`` the parameters of ``state`` that have its parameters' names and shapes (a network of
    another part count or joint types: the backbone, not the part-sized heads); the others keep their values.

    Returns
    -------
    int
        How many parameters were copied.
    """
    own = model.state_dict()
    copied = {k: v for k, v in state.items() if k in own and tuple(own[k].shape) == tuple(v.shape)}
    model.load_state_dict({**own, **copied})
    return len(copied)
