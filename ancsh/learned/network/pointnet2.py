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
from dataclasses import dataclass, fields

import numpy as np
import torch
from torch import nn

__all__ = [
    "farthest_point_sample",
    "farthest_point_sample_reference",
    "ball_query",
    "gather_points",
    "group_points",
    "three_nn_interpolate",
    "SetAbstraction",
    "FeaturePropagation",
    "PointNet2Backbone",
    "shared_mlp",
    "SharedMLP",
    "Neighbourhoods",
    "nearest_three",
    "interpolate_last",
]


def _check_xyz(xyz: torch.Tensor, name: str) -> None:
    if xyz.dim() != 3 or xyz.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (B, N, 3), got {tuple(xyz.shape)}")


@torch.no_grad()
def farthest_point_sample(xyz: torch.Tensor, npoint: int) -> torch.Tensor:
    """Iterative farthest-point sampling.

    The loop runs in numpy (its per-step cost is call overhead on small arrays) with the same
    float arithmetic as the torch formulation ``min(dist, ((xyz - centre) ** 2).sum(-1))``; ties
    go to the lowest index.

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
    px, py, pz = np.ascontiguousarray(xyz.detach().cpu().numpy().transpose(2, 0, 1))  # (B, N) each
    idx = np.zeros((B, npoint), dtype=np.int64)
    dist = np.full((B, N), np.inf, dtype=px.dtype)
    d, t = np.empty_like(dist), np.empty_like(dist)
    farthest = np.zeros(B, dtype=np.int64)
    rows = np.arange(B)
    for i in range(npoint):
        idx[:, i] = farthest
        np.subtract(px, px[rows, farthest][:, None], out=d)
        np.multiply(d, d, out=d)
        np.subtract(py, py[rows, farthest][:, None], out=t)
        d += t * t
        np.subtract(pz, pz[rows, farthest][:, None], out=t)
        d += t * t  # ((dx^2 + dy^2) + dz^2): the order of a sum over the last axis of 3
        np.minimum(dist, d, out=dist)
        farthest = dist.argmax(1)
    return torch.from_numpy(idx).to(xyz.device)


@torch.no_grad()
def farthest_point_sample_reference(xyz: torch.Tensor, npoint: int) -> torch.Tensor:
    """:func:`farthest_point_sample` as torch operations, one step per centre (the earlier implementation:
    the same indices, several times slower on a CPU; kept as the reference of tests and benchmarks)."""
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
    idx, w = nearest_three(xyz, known_xyz)
    return interpolate_last(known_features.transpose(1, 2), idx, w).transpose(1, 2)


def shared_mlp(channels: Sequence[int], dim: int) -> "SharedMLP":
    """Pointwise MLP of 1x1 convolutions with batch norm and ReLU (``dim`` is 1 or 2)."""
    conv, bn = (nn.Conv1d, nn.BatchNorm1d) if dim == 1 else (nn.Conv2d, nn.BatchNorm2d)
    layers: list[nn.Module] = []
    for c_in, c_out in zip(channels[:-1], channels[1:]):
        layers += [conv(c_in, c_out, 1, bias=False), bn(c_out), nn.ReLU(inplace=True)]
    return SharedMLP(*layers)


class SharedMLP(nn.Sequential):
    """``[Conv(1x1, no bias), BatchNorm, ReLU] * L`` applied channel-first (``forward``) or channel-last.

    :meth:`forward_last` evaluates the same parameters on channel-last ``(..., C)`` input as
    matrix products and batch norm over the flattened rows: the same function (the same
    batch statistics and running-stat updates), cheaper on a CPU than 1x1 convolutions on
    channel-first tensors. The parameters (and the state dict) are those of the convolutions.
    """

    def forward_last(self, x: torch.Tensor) -> torch.Tensor:
        """``(..., C_in) -> (..., C_out)``, channel-last."""
        lead = x.shape[:-1]
        h = x.reshape(-1, x.shape[-1])
        for conv, bn in self._pairs():
            h = torch.relu_(_batch_norm_rows(bn, h @ _matrix(conv).t()))
        return h.reshape(*lead, h.shape[-1])

    def forward_last_max(self, x: torch.Tensor, dim: int, keepdim: bool = False) -> torch.Tensor:
        """Maximum over ``dim`` of :meth:`forward_last` (channel-last, ``dim`` not the last axis).

        The last layer's batch norm and ReLU, ``relu(s h + t)`` per channel, are monotone in ``h``
        (increasing where ``s >= 0``, decreasing where ``s < 0``), so their maximum over ``dim`` is
        ``relu(s m + t)`` with ``m`` the maximum of ``h`` (or its minimum, where ``s < 0``): the same
        values, computed on the pooled rows instead of all of them. That saves passes over the
        largest activations when compiled (``torch.compile`` traces this path) and in eval mode; an
        uncompiled training step keeps the plain order, whose fused batch-norm kernel computes the
        statistics faster than the separate ``var_mean`` this order needs.
        """
        from .. import distributed

        pairs = self._pairs()
        bn = pairs[-1][1]
        if bn.training and (distributed.syncing() or not torch.compiler.is_compiling()):
            return _max_pool(self.forward_last(x), dim=dim, keepdim=keepdim)
        lead = x.shape[:-1]
        h = x.reshape(-1, x.shape[-1])
        for conv, layer_bn in pairs[:-1]:
            h = torch.relu_(_batch_norm_rows(layer_bn, h @ _matrix(conv).t()))
        h = h @ _matrix(pairs[-1][0]).t()
        scale, shift = _batch_norm_affine(bn, h)
        sign = torch.where(scale >= 0, 1.0, -1.0).to(h.dtype).detach()
        # amax: compiled, its backward (the gradient to the maxima, split over ties) fuses with the batch norm's
        pooled = (h * sign).reshape(*lead, h.shape[-1]).amax(dim=dim, keepdim=keepdim) * sign
        return torch.relu(pooled * scale + shift)

    def _pairs(self) -> list:
        """``[(conv, batch_norm), ...]`` per layer."""
        layers = list(self)
        return list(zip(layers[0::3], layers[1::3]))


def _matrix(conv: nn.Module) -> torch.Tensor:
    """The ``(C_out, C_in)`` matrix of a 1x1 convolution."""
    return conv.weight.reshape(conv.weight.shape[0], -1)


def _batch_norm_affine(bn: nn.modules.batchnorm._BatchNorm, h: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-channel ``scale, shift`` with ``bn(h) = h * scale + shift`` for ``(P, C)`` rows, with the semantics of
    ``bn.forward`` (batch statistics in training, running statistics updated as :class:`nn.BatchNorm1d` does:
    momentum, cumulative average when it is ``None``, unbiased variance)."""
    use_batch = bn.training or not bn.track_running_stats
    if use_batch:
        var, mean = torch.var_mean(h, dim=0, correction=0)
        if bn.training and bn.track_running_stats:
            with torch.no_grad():
                bn.num_batches_tracked.add_(1)
                momentum = 1.0 / float(bn.num_batches_tracked) if bn.momentum is None else bn.momentum
                n = h.shape[0]
                bn.running_mean.mul_(1.0 - momentum).add_(momentum * mean.detach())
                bn.running_var.mul_(1.0 - momentum).add_((momentum * n / max(n - 1, 1)) * var.detach())
    else:
        mean, var = bn.running_mean, bn.running_var
    scale = torch.rsqrt(var + bn.eps)
    if bn.weight is not None:
        scale = bn.weight * scale
    shift = -mean * scale
    return scale, shift if bn.bias is None else bn.bias + shift


def _batch_norm_rows(bn: nn.modules.batchnorm._BatchNorm, h: torch.Tensor) -> torch.Tensor:
    """``bn`` applied to ``(P, C)`` rows with the semantics of ``bn.forward`` (train/eval, running stats).

    In training inside :func:`ancsh.learned.distributed.global_batch` (several processes), the
    statistics are those of every process's rows (:func:`~ancsh.learned.distributed.sync_batch_norm_rows`).
    """
    if bn.training:
        from .. import distributed

        if distributed.syncing():
            return distributed.sync_batch_norm_rows(bn, h)
    momentum = 0.0 if bn.momentum is None else bn.momentum
    use_batch = bn.training or not bn.track_running_stats
    if bn.training and bn.track_running_stats:
        bn.num_batches_tracked.add_(1)
        if bn.momentum is None:  # cumulative moving average, as nn.BatchNorm does
            momentum = 1.0 / float(bn.num_batches_tracked)
    running = not bn.training or bn.track_running_stats
    return nn.functional.batch_norm(
        h, bn.running_mean if running else None, bn.running_var if running else None,
        bn.weight, bn.bias, use_batch, momentum, bn.eps,
    )


@dataclass(frozen=True)
class Neighbourhoods:
    """Index tensors of one backbone pass that depend only on the input points.

    Farthest-point centres, ball-query neighbourhoods and three-nearest-neighbour interpolation
    indices and weights of :class:`PointNet2Backbone` for ``B`` clouds of ``N`` points
    (``S1, S2`` set-abstraction centres, ``K1, K2`` neighbours). They carry no gradient, so a
    training step can take them from a per-frame cache (:meth:`PointNet2Backbone.neighbourhoods`)
    instead of recomputing them; with them, the interpolation weights carry no gradient to the
    coordinates (the network's input points never require one).

    Attributes
    ----------
    centres1 : (B, S1) int64
        Indices into the ``N`` input points.
    groups1 : (B, S1, K1) int64
        Indices into the ``N`` input points.
    centres2 : (B, S2) int64
        Indices into the ``S1`` first-level centres.
    groups2 : (B, S2, K2) int64
        Indices into the ``S1`` first-level centres.
    interp2_idx, interp2_w : (B, S1, k2) int64 / float
        Interpolation of the second level onto the first (``k2 = min(3, S2)``, weights sum to 1).
    interp1_idx, interp1_w : (B, N, k1) int64 / float
        Interpolation of the first level onto the input points.
    normal_idx : (B, N, k) int64, optional
        :func:`~ancsh.learned.network.normals.normal_neighbours` of the input points, for a network with input
        normals (``None`` otherwise, or when its normals' neighbours are to be searched in the pass).
    """

    centres1: torch.Tensor
    groups1: torch.Tensor
    centres2: torch.Tensor
    groups2: torch.Tensor
    interp2_idx: torch.Tensor
    interp2_w: torch.Tensor
    interp1_idx: torch.Tensor
    interp1_w: torch.Tensor
    normal_idx: torch.Tensor | None = None

    def numpy(self) -> dict[str, np.ndarray]:
        """Compact numpy copies (indices int32, weights float32) keyed by field name; fields that are ``None`` left out."""
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if v is not None:
                out[f.name] = v.cpu().numpy().astype(np.float32 if v.is_floating_point() else np.int32)
        return out

    def map(self, fn) -> "Neighbourhoods":
        """A copy with ``fn`` applied to every tensor (fields that are ``None`` stay ``None``), e.g. a slice of frames."""
        return type(self)(**{f.name: None if getattr(self, f.name) is None else fn(getattr(self, f.name)) for f in fields(self)})

    @classmethod
    def from_numpy(cls, arrays: dict, index=None) -> "Neighbourhoods":
        """Tensors (int64 indices, float32 weights) from :meth:`numpy` output, optionally of frames ``index``
        (optional fields absent from ``arrays`` are ``None``)."""
        kw = {}
        for f in fields(cls):
            if f.name not in arrays and f.default is None:
                continue
            a = arrays[f.name] if index is None else arrays[f.name][index]
            t = torch.from_numpy(np.ascontiguousarray(a))
            kw[f.name] = t.float() if t.is_floating_point() else t.long()
        return cls(**kw)


def nearest_three(xyz: torch.Tensor, known_xyz: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Indices ``(B, N, k)`` and normalised inverse-squared-distance weights of the ``k = min(3, S)`` nearest known points."""
    k = min(3, known_xyz.shape[1])
    d2 = torch.cdist(xyz, known_xyz).square()
    d2, idx = d2.topk(k, dim=-1, largest=False)  # (B, N, k)
    w = 1.0 / (d2 + 1e-8)
    return idx, w / w.sum(-1, keepdim=True)


def interpolate_last(known_features: torch.Tensor, idx: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
    """Weighted sum of channel-last features ``(B, S, C)`` at ``idx`` ``(B, N, k)`` with ``w`` -> ``(B, N, C)``."""
    return (gather_points(known_features, idx) * w.unsqueeze(-1)).sum(2)


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

    def sample_and_group(self, xyz: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Centre indices ``(B, S)`` (FPS) and neighbourhoods ``(B, S, K)`` (ball query) of ``(B, N, 3)`` points."""
        centres = farthest_point_sample(xyz, self.npoint)
        return centres, ball_query(xyz, gather_points(xyz, centres), self.radius, self.nsample)

    def forward(self, xyz: torch.Tensor, features: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
        """``(B, N, 3), (B, C, N) | None -> (B, S, 3), (B, C', S)``."""
        if self.npoint is None:
            centres = xyz.new_zeros(xyz.shape[0], 1, 3)
            grouped = xyz.transpose(1, 2).unsqueeze(2)  # (B, 3, 1, N)
            if features is not None:
                grouped = torch.cat([grouped, features.unsqueeze(2)], dim=1)
        else:  # the reference path, as the step was before channel-last layers and cached neighbourhoods
            centres = gather_points(xyz, farthest_point_sample_reference(xyz, self.npoint))
            idx = ball_query(xyz, centres, self.radius, self.nsample)
            grouped = group_points(xyz, features, centres, idx)
        return centres, self.mlp(grouped).amax(dim=-1)

    def forward_last(self, xyz: torch.Tensor, features: torch.Tensor | None, centre_idx: torch.Tensor | None = None,
                     group_idx: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Channel-last :meth:`forward`: ``(B, N, 3), (B, N, C) | None -> (B, S, 3), (B, S, C')``.

        ``centre_idx`` ``(B, S)`` and ``group_idx`` ``(B, S, K)`` (from :meth:`sample_and_group`)
        skip the sampling and grouping when given.
        """
        if self.npoint is None:
            centres = xyz.new_zeros(xyz.shape[0], 1, 3)
            grouped = xyz if features is None else torch.cat([xyz, features], dim=-1)  # (B, N, 3 + C)
            return centres, self.mlp.forward_last_max(grouped, dim=1, keepdim=True)
        if centre_idx is None or group_idx is None:
            centre_idx, group_idx = self.sample_and_group(xyz)
        centres = gather_points(xyz, centre_idx)
        rel = gather_points(xyz, group_idx) - centres.unsqueeze(2)
        # Coordinates and features gathered apart: the backward scatters only the features' gradient.
        grouped = rel if features is None else torch.cat([rel, gather_points(features, group_idx)], dim=-1)  # (B, S, K, 3 + C)
        return centres, self.mlp.forward_last_max(grouped, dim=2)


def _max_pool(x: torch.Tensor, dim: int, keepdim: bool = False) -> torch.Tensor:
    """Maximum over ``dim`` whose backward scatters to one arg-max per output (``amax`` spreads the gradient
    over ties with a full-size comparison, several times slower). Ties come from repeated neighbours, which
    share their input, so the parameters' gradients are the same either way."""
    return x.max(dim=dim, keepdim=keepdim).values


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

    def forward_last(self, num_points: int, skip: torch.Tensor | None, known_features: torch.Tensor,
                     idx: torch.Tensor | None, w: torch.Tensor | None) -> torch.Tensor:
        """Channel-last :meth:`forward` with given interpolation (``idx``, ``w`` ``(B, N, k)`` from
        :func:`nearest_three`; ``None`` when a single known point is spread to all ``num_points``).

        ``(B, N, C1) | None, (B, S, C2) -> (B, N, C')``.
        """
        if idx is None:
            up = known_features.expand(-1, num_points, -1)
        else:
            up = interpolate_last(known_features, idx, w)
        if skip is not None:
            up = torch.cat([skip, up], dim=-1)
        return self.mlp.forward_last(up)


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
    in_features : int
        Per-point input features besides the coordinates (0 = none, the default; 3 = surface normals):
        the first set abstraction groups them with the coordinates and the last feature propagation
        takes them as skip features.

    Attributes
    ----------
    channels_last : bool
        Evaluate the layers channel-last (:meth:`SharedMLP.forward_last`, the default) or as the
        reference 1x1 convolutions on channel-first tensors (the same function, slower on a CPU;
        kept to measure against).
    """

    def __init__(self, width: float = 1.0, npoints=(512, 128), radii=(0.2, 0.4), nsamples=(32, 64), in_features: int = 0):
        super().__init__()
        if not width > 0:
            raise ValueError(f"width: expected a positive number, got {width}")
        if isinstance(in_features, bool) or not isinstance(in_features, int) or in_features < 0:
            raise ValueError(f"in_features: expected a non-negative integer, got {in_features!r}")

        def c(n: int) -> int:
            return max(8, int(round(n * width)))

        self.in_features = in_features
        self.sa1 = SetAbstraction(npoints[0], radii[0], nsamples[0], in_features, [c(64), c(64), c(128)])
        self.sa2 = SetAbstraction(npoints[1], radii[1], nsamples[1], c(128), [c(128), c(128), c(256)])
        self.sa3 = SetAbstraction(None, None, None, c(256), [c(256), c(512), c(1024)])
        self.fp3 = FeaturePropagation(c(1024) + c(256), [c(256), c(256)])
        self.fp2 = FeaturePropagation(c(256) + c(128), [c(256), c(128)])
        self.fp1 = FeaturePropagation(c(128) + 3 + in_features, [c(128), c(128), c(128)])
        self.out_channels = c(128)
        self.channels_last = True

    #: The parameters that read the input features: the first set abstraction (grouped as
    #: ``[relative xyz, features]``) and the last feature propagation (skip ``[xyz, features]``, then
    #: the upsampled features); in both the features' columns follow the first three.
    _FEATURE_INPUTS = ("sa1.mlp.0.weight", "fp1.mlp.0.weight")

    def state_with_input_features(self, state: dict) -> dict:
        """This backbone's parameters from ``state``, those of the same backbone without input features
        (``in_features = 0``), the weights on the features set to zero.

        The result computes the same per-point features as ``state`` whatever the input features are,
        so a trained network can be given new input channels (e.g. surface normals) and fine-tuned
        from the function it had; the new weights get gradients from the first step.

        Parameters
        ----------
        state : dict
            A ``state_dict()`` of a :class:`PointNet2Backbone` of the same widths with ``in_features = 0``.
        """
        own = self.state_dict()
        if set(state) != set(own):
            raise ValueError(f"state: expected the parameters {sorted(own)}, got {sorted(state)}")
        out = {}
        for name, target in own.items():
            source = state[name]
            if name in self._FEATURE_INPUTS:
                expected = (target.shape[0], target.shape[1] - self.in_features, *target.shape[2:])
                if tuple(source.shape) != expected:
                    raise ValueError(f"state: {name} has shape {tuple(source.shape)}, expected {expected} "
                                     f"(the same backbone without input features)")
                zeros = source.new_zeros((source.shape[0], self.in_features, *source.shape[2:]))
                source = torch.cat([source[:, :3], zeros, source[:, 3:]], dim=1)
            elif source.shape != target.shape:
                raise ValueError(f"state: {name} has shape {tuple(source.shape)}, expected {tuple(target.shape)}")
            out[name] = source.clone()
        return out

    @torch.no_grad()
    def neighbourhoods(self, xyz: torch.Tensor) -> Neighbourhoods:
        """Everything of a pass over ``(B, N, 3)`` points that depends only on the points."""
        _check_xyz(xyz, "xyz")
        c1, g1 = self.sa1.sample_and_group(xyz)
        l1_xyz = gather_points(xyz, c1)
        c2, g2 = self.sa2.sample_and_group(l1_xyz)
        i2, w2 = nearest_three(l1_xyz, gather_points(l1_xyz, c2))
        i1, w1 = nearest_three(xyz, l1_xyz)
        return Neighbourhoods(c1, g1, c2, g2, i2, w2, i1, w1)

    def _check_features(self, xyz: torch.Tensor, features: torch.Tensor | None) -> None:
        if self.in_features == 0:
            if features is not None:
                raise ValueError("features: this backbone takes no input features (in_features = 0)")
            return
        if features is None or features.shape != (*xyz.shape[:2], self.in_features):
            got = None if features is None else tuple(features.shape)
            raise ValueError(f"features: expected shape {(*xyz.shape[:2], self.in_features)}, got {got}")

    def forward(self, xyz: torch.Tensor, neighbourhoods: Neighbourhoods | None = None,
                features: torch.Tensor | None = None) -> torch.Tensor:
        """Per-point features ``(B, N, 3) -> (B, C, N)``.

        ``neighbourhoods`` (from :meth:`neighbourhoods` of the same points, e.g. cached per frame)
        skips sampling, grouping and the nearest-neighbour search; channel-last only. ``features``:
        ``(B, N, in_features)`` channel-last input features (required when ``in_features > 0``).
        """
        _check_xyz(xyz, "xyz")
        if self.channels_last:
            return self.forward_last(xyz, neighbourhoods, features).transpose(1, 2)
        if neighbourhoods is not None:
            raise ValueError("neighbourhoods: only supported with channels_last = True")
        self._check_features(xyz, features)
        f0 = None if features is None else features.transpose(1, 2)
        l1_xyz, l1 = self.sa1(xyz, f0)
        l2_xyz, l2 = self.sa2(l1_xyz, l1)
        l3_xyz, l3 = self.sa3(l2_xyz, l2)
        l2 = self.fp3(l2_xyz, l3_xyz, l2, l3)
        l1 = self.fp2(l1_xyz, l2_xyz, l1, l2)
        skip = xyz.transpose(1, 2) if f0 is None else torch.cat([xyz.transpose(1, 2), f0], dim=1)
        return self.fp1(xyz, l1_xyz, skip, l1)

    def forward_last(self, xyz: torch.Tensor, neighbourhoods: Neighbourhoods | None = None,
                     features: torch.Tensor | None = None) -> torch.Tensor:
        """Channel-last per-point features ``(B, N, 3) -> (B, N, C)`` (see :meth:`forward`)."""
        _check_xyz(xyz, "xyz")
        self._check_features(xyz, features)
        nb = self.neighbourhoods(xyz) if neighbourhoods is None else neighbourhoods
        l1_xyz, l1 = self.sa1.forward_last(xyz, features, nb.centres1, nb.groups1)
        l2_xyz, l2 = self.sa2.forward_last(l1_xyz, l1, nb.centres2, nb.groups2)
        _, l3 = self.sa3.forward_last(l2_xyz, l2)
        l2 = self.fp3.forward_last(l2.shape[1], l2, l3, None, None)
        l1 = self.fp2.forward_last(l1.shape[1], l1, l2, nb.interp2_idx, nb.interp2_w)
        skip = xyz if features is None else torch.cat([xyz, features], dim=-1)
        return self.fp1.forward_last(xyz.shape[1], skip, l1, nb.interp1_idx, nb.interp1_w)
