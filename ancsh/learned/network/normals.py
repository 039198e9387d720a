"""Surface normals of a point cloud as a network's input channels (``TrainConfig.input_normals``).

Each point's normal is the smallest principal direction of its nearest points, signed to face the camera: a function
of the sampled points alone (no image grid), so the same for a training frame and for the points a prediction feeds
the network. The nearest-point search is the costly part: on a CPU a k-d tree per cloud, cached per training frame
(:attr:`~ancsh.learned.network.pointnet2.Neighbourhoods.normal_idx`) since it does not change under the rotations,
translations and scalings a step applies.
"""

from __future__ import annotations

import numpy as np
import torch

from .pointnet2 import _check_xyz, gather_points

__all__ = ["NORMAL_NEIGHBOURS", "estimate_normals", "normal_neighbours"]


NORMAL_NEIGHBOURS = 16
"""Nearest points (the point itself included) whose covariance gives a point's normal (:func:`estimate_normals`)."""


def _check_k(k) -> int:
    if isinstance(k, bool) or not isinstance(k, int) or k < 3:
        raise ValueError(f"k: expected an integer >= 3, got {k!r}")
    return k


@torch.no_grad()
def normal_neighbours(points: torch.Tensor, k: int = NORMAL_NEIGHBOURS) -> torch.Tensor:
    """Indices ``(B, N, min(k, N))`` of each point's nearest points (itself included), for :func:`estimate_normals`.

    The same for the points rotated, translated or uniformly scaled, so a training loop can take them from a
    per-frame cache (:attr:`~ancsh.learned.network.pointnet2.Neighbourhoods.normal_idx`) whatever rotation a step
    applies (camera-rotation augmentation, a refinement network's canonicalisation). No gradient.

    Parameters
    ----------
    points : (B, N, 3) tensor
        Points (any unit).
    k : int
        Neighbours, ``3 <= k``.
    """
    _check_xyz(points, "points")
    k = min(_check_k(k), points.shape[1])
    if points.device.type == "cpu" and bool(torch.isfinite(points).all()):
        return _kdtree_neighbours(points, k)
    return torch.cdist(points, points).topk(k, dim=-1, largest=False).indices


def _kdtree_neighbours(points: torch.Tensor, k: int) -> torch.Tensor:
    """:func:`normal_neighbours` on a CPU by a k-d tree per cloud: the same nearest points as the brute-force
    search (about half its time for 1024 points, which a prediction pays on every frame), nearest first."""
    from scipy.spatial import cKDTree

    clouds = points.detach().numpy().astype(np.float64)  # the tree's own type: no conversion per query
    idx = np.empty((*clouds.shape[:2], k), dtype=np.int64)
    for b, cloud in enumerate(clouds):
        idx[b] = cKDTree(cloud).query(cloud, k=k)[1]
    return torch.from_numpy(idx)


@torch.no_grad()
def estimate_normals(points: torch.Tensor, k: int = NORMAL_NEIGHBOURS, neighbours: torch.Tensor | None = None) -> torch.Tensor:
    """Unit surface normals of a cloud by principal components of each point's ``k`` nearest points.

    The normal is the eigenvector of the smallest eigenvalue of the neighbours' covariance, signed to
    face the origin of ``points``' frame (the camera, for camera-frame points): ``n . p <= 0``. It needs
    no image grid, so it is the same function of a training frame's sampled points and of the points a
    prediction feeds the network. No gradient.

    Parameters
    ----------
    points : (B, N, 3) tensor
        Points (any unit); the sign convention assumes the viewpoint at the origin.
    k : int
        Neighbours, ``3 <= k``; ``min(k, N)`` are used.
    neighbours : (B, N, k') int64 tensor, optional
        :func:`normal_neighbours` of these points (or of the same points rotated, translated or scaled),
        e.g. from a per-frame cache: skips the nearest-neighbour search, the costly part; ``k`` is then ``k'``.

    Returns
    -------
    (B, N, 3) tensor
        Unit normals, same dtype and device.
    """
    if neighbours is None:
        idx = normal_neighbours(points, k)
    else:
        _check_xyz(points, "points")
        if neighbours.dim() != 3 or neighbours.shape[:2] != points.shape[:2] or neighbours.shape[2] < 3:
            raise ValueError(f"neighbours: expected shape ({points.shape[0]}, {points.shape[1]}, >= 3) for points of shape "
                             f"{tuple(points.shape)}, got {tuple(neighbours.shape)}")
        idx = neighbours
    nb = gather_points(points, idx)
    centred = nb - nb.mean(dim=2, keepdim=True)
    cov = centred.transpose(-1, -2) @ centred  # (B, N, 3, 3)
    # float64: the smallest eigenvalue of a nearly flat neighbourhood is tiny beside the others
    normals = torch.linalg.eigh(cov.double())[1][..., 0].to(points.dtype)
    flip = (normals * points).sum(dim=-1, keepdim=True) > 0
    return torch.where(flip, -normals, normals)
