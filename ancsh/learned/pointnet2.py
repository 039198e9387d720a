"""PointNet++ layers in plain torch ops (CPU friendly, no compiled extensions).

Shapes follow the PointNet++ reference: coordinates ``xyz`` are ``(B, N, 3)``
float32 tensors, features are channel-first ``(B, C, N)``. Farthest-point
sampling and ball query return integer indices and carry no gradient; the
grouped coordinates and features do.

References: Qi et al., "PointNet++: Deep Hierarchical Feature Learning on
Point Sets in a Metric Space", NeurIPS 2017 (single-scale grouping).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

__all__ = [
    "farthest_point_sample",
    "ball_query",
    "gather_points",
    "group_points",
    "three_nn_interpolate",
    "SetAbstraction",
    "FeaturePropagation",
    "PointNet2Backbone",
    "shared_mlp",
]


def _check_xyz(xyz: torch.Tensor, name: str) -> None:
    if xyz.dim() != 3 or xyz.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (B, N, 3), got {tuple(xyz.shape)}")


@torch.no_grad()
def farthest_point_sample(xyz: torch.Tensor, npoint: int) -> torch.Tensor:
    """Iterative farthest-point sampling.

    Parameters
    ----------
    xyz : (B, N, 3) tensor
        Point coordinates.
    npoint : int
        Number of points to select, ``1 <= npoint <= N``.

    Returns
    -------
    (B, npoint) int64 tensor
        Indices into ``N``; the first index is always 0 (deterministic).
    """
    _check_xyz(xyz, "xyz")
    B, N, _ = xyz.shape
    if not 1 <= npoint <= N:
        raise ValueError(f"npoint: expected 1 <= npoint <= {N}, got {npoint}")
    idx = torch.zeros(B, npoint, dtype=torch.long, device=xyz.device)
    dist = torch.full((B, N), float("inf"), dtype=xyz.dtype, device=xyz.device)
    farthest = torch.zeros(B, dtype=torch.long, device=xyz.device)
    batch = torch.arange(B, device=xyz.device)
    for i in range(npoint):
        idx[:, i] = farthest
        centre = xyz[batch, farthest].unsqueeze(1)  # (B, 1, 3)
        dist = torch.minimum(dist, ((xyz - centre) ** 2).sum(-1))
        farthest = dist.argmax(-1)
    return idx


@torch.no_grad()
def ball_query(xyz: torch.Tensor, centres: torch.Tensor, radius: float, nsample: int) -> torch.Tensor:
    """Indices of up to ``nsample`` points within ``radius`` of each centre.

    Neighbours are taken in index order (as in the reference implementation);
    when fewer than ``nsample`` lie in the ball, the first neighbour is repeated.
    A centre that is itself a point of ``xyz`` always has at least one neighbour.

    Parameters
    ----------
    xyz : (B, N, 3) tensor
        Points to search.
    centres : (B, S, 3) tensor
        Query centres.
    radius : float
        Ball radius (same unit as ``xyz``), positive.
    nsample : int
        Neighbours per centre, ``1 <= nsample <= N``.

    Returns
    -------
    (B, S, nsample) int64 tensor
    """
    _check_xyz(xyz, "xyz")
    _check_xyz(centres, "centres")
    if radius <= 0:
        raise ValueError(f"radius: expected a positive number, got {radius}")
    N = xyz.shape[1]
    if not 1 <= nsample <= N:
        raise ValueError(f"nsample: expected 1 <= nsample <= {N}, got {nsample}")
    sqd = torch.cdist(centres, xyz).square_()  # (B, S, N)
    order = torch.arange(N, device=xyz.device).expand_as(sqd).clone()
    order[sqd > radius * radius] = N
    idx = order.topk(nsample, dim=-1, largest=False, sorted=True).values
    first = idx[..., :1].expand_as(idx)
    # A centre with no neighbour at all (only possible for foreign centres) falls back to its nearest point.
    nearest = sqd.argmin(-1, keepdim=True).expand_as(idx)
    first = torch.where(first == N, nearest, first)
    return torch.where(idx == N, first, idx)


def gather_points(values: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
    """Pick rows of channel-last ``values`` ``(B, N, C)`` with ``idx`` ``(B, ...)`` -> ``(B, ..., C)``."""
    B = values.shape[0]
    flat = idx.reshape(B, -1)
    out = torch.gather(values, 1, flat.unsqueeze(-1).expand(-1, -1, values.shape[-1]))
    return out.reshape(*idx.shape, values.shape[-1])


def group_points(xyz: torch.Tensor, features: torch.Tensor | None, centres: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
    """Group neighbourhoods: relative coordinates concatenated with features.

    Parameters
    ----------
    xyz : (B, N, 3) tensor
    features : (B, C, N) tensor or None
    centres : (B, S, 3) tensor
    idx : (B, S, K) int64 tensor from :func:`ball_query`

    Returns
    -------
    (B, 3 + C, S, K) tensor
        Coordinates relative to the centre, then the neighbours' features.
    """
    rel = gather_points(xyz, idx) - centres.unsqueeze(2)  # (B, S, K, 3)
    parts = [rel]
    if features is not None:
        parts.append(gather_points(features.transpose(1, 2), idx))
    return torch.cat(parts, dim=-1).permute(0, 3, 1, 2)


def three_nn_interpolate(xyz: torch.Tensor, known_xyz: torch.Tensor, known_features: torch.Tensor) -> torch.Tensor:
    """Inverse-distance interpolation from the three nearest known points.

    Parameters
    ----------
    xyz : (B, N, 3) tensor
        Target points.
    known_xyz : (B, S, 3) tensor
        Points carrying features.
    known_features : (B, C, S) tensor

    Returns
    -------
    (B, C, N) tensor
    """
    S = known_xyz.shape[1]
    if S == 1:
        return known_features.expand(-1, -1, xyz.shape[1])
    k = min(3, S)
    d2 = torch.cdist(xyz, known_xyz).square()
    d2, idx = d2.topk(k, dim=-1, largest=False)  # (B, N, k)
    w = 1.0 / (d2 + 1e-8)
    w = w / w.sum(-1, keepdim=True)
    neigh = gather_points(known_features.transpose(1, 2), idx)  # (B, N, k, C)
    return (neigh * w.unsqueeze(-1)).sum(2).transpose(1, 2)


def shared_mlp(channels: Sequence[int], dim: int) -> nn.Sequential:
    """Pointwise MLP of 1x1 convolutions with batch norm and ReLU (``dim`` is 1 or 2)."""
    conv, bn = (nn.Conv1d, nn.BatchNorm1d) if dim == 1 else (nn.Conv2d, nn.BatchNorm2d)
    layers: list[nn.Module] = []
    for c_in, c_out in zip(channels[:-1], channels[1:]):
        layers += [conv(c_in, c_out, 1, bias=False), bn(c_out), nn.ReLU(inplace=True)]
    return nn.Sequential(*layers)


class SetAbstraction(nn.Module):
    """Sample centres by FPS, group their ball neighbourhoods, apply a shared MLP, max-pool.

    ``npoint=None`` groups all points into one centroid (the global layer).
    """

    def __init__(self, npoint: int | None, radius: float | None, nsample: int | None, in_channels: int, mlp: Sequence[int]):
        super().__init__()
        if npoint is not None and (radius is None or nsample is None):
            raise ValueError("radius, nsample: required when npoint is given")
        self.npoint, self.radius, self.nsample = npoint, radius, nsample
        self.mlp = shared_mlp([in_channels + 3, *mlp], dim=2)
        self.out_channels = mlp[-1]

    def forward(self, xyz: torch.Tensor, features: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
        """``(B, N, 3), (B, C, N) | None -> (B, S, 3), (B, C', S)``."""
        if self.npoint is None:
            centres = xyz.new_zeros(xyz.shape[0], 1, 3)
            grouped = xyz.transpose(1, 2).unsqueeze(2)  # (B, 3, 1, N)
            if features is not None:
                grouped = torch.cat([grouped, features.unsqueeze(2)], dim=1)
        else:
            centres = gather_points(xyz, farthest_point_sample(xyz, self.npoint))
            idx = ball_query(xyz, centres, self.radius, self.nsample)
            grouped = group_points(xyz, features, centres, idx)
        return centres, self.mlp(grouped).amax(dim=-1)


class FeaturePropagation(nn.Module):
    """Interpolate coarse features onto fine points, concatenate skip features, shared MLP."""

    def __init__(self, in_channels: int, mlp: Sequence[int]):
        super().__init__()
        self.mlp = shared_mlp([in_channels, *mlp], dim=1)
        self.out_channels = mlp[-1]

    def forward(self, xyz: torch.Tensor, known_xyz: torch.Tensor, skip: torch.Tensor | None, known_features: torch.Tensor) -> torch.Tensor:
        """``(B, N, 3), (B, S, 3), (B, C1, N) | None, (B, C2, S) -> (B, C', N)``."""
        up = three_nn_interpolate(xyz, known_xyz, known_features)
        if skip is not None:
            up = torch.cat([skip, up], dim=1)
        return self.mlp(up)


class PointNet2Backbone(nn.Module):
    """PointNet++ part-segmentation backbone (SSG): three SA levels, three FP levels.

    Channel widths are the reference part-segmentation widths times ``width``.

    Parameters
    ----------
    width : float
        Channel multiplier (1.0 = reference widths 64..1024).
    npoints : (2,) ints
        Centres of the two local SA levels.
    radii : (2,) floats
        Ball radii of the two local levels, in units of the normalised input.
    nsamples : (2,) ints
        Neighbours per ball.
    """

    def __init__(self, width: float = 1.0, npoints=(512, 128), radii=(0.2, 0.4), nsamples=(32, 64)):
        super().__init__()
        if not width > 0:
            raise ValueError(f"width: expected a positive number, got {width}")

        def c(n: int) -> int:
            return max(8, int(round(n * width)))

        self.sa1 = SetAbstraction(npoints[0], radii[0], nsamples[0], 0, [c(64), c(64), c(128)])
        self.sa2 = SetAbstraction(npoints[1], radii[1], nsamples[1], c(128), [c(128), c(128), c(256)])
        self.sa3 = SetAbstraction(None, None, None, c(256), [c(256), c(512), c(1024)])
        self.fp3 = FeaturePropagation(c(1024) + c(256), [c(256), c(256)])
        self.fp2 = FeaturePropagation(c(256) + c(128), [c(256), c(128)])
        self.fp1 = FeaturePropagation(c(128) + 3, [c(128), c(128), c(128)])
        self.out_channels = c(128)

    def forward(self, xyz: torch.Tensor) -> torch.Tensor:
        """Per-point features ``(B, N, 3) -> (B, C, N)``."""
        _check_xyz(xyz, "xyz")
        l1_xyz, l1 = self.sa1(xyz, None)
        l2_xyz, l2 = self.sa2(l1_xyz, l1)
        l3_xyz, l3 = self.sa3(l2_xyz, l2)
        l2 = self.fp3(l2_xyz, l3_xyz, l2, l3)
        l1 = self.fp2(l1_xyz, l2_xyz, l1, l2)
        return self.fp1(xyz, l1_xyz, xyz.transpose(1, 2), l1)
