"""Checks and joins a verifier applies to isolation's candidates: a segment that runs out of the view
(:func:`out_of_view`), one that lies behind its surroundings (:func:`behind_surroundings`), and the union of two
touching candidates that plane removal cut apart (:func:`merged_candidate`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..images import mask_bounds
from ..render import Intrinsics, backproject
from .grid import extent, fits, same_segment, check_size_range
from .proposals import Cluster, Isolation

__all__ = ["behind_surroundings", "merged_candidate", "out_of_view"]

#: A segment lies behind its surroundings (a wall or a curtain seen around nearer things, not an object) when at
#: least BACKGROUND_JUMPS of the pixels in a ring of BACKGROUND_RING pixels around it differ from its depth by a jump
#: (BACKGROUND_JUMP_M, or that share of the depth) and at least BACKGROUND_BEHIND of those jumps are nearer surfaces.
BACKGROUND_RING = 3

BACKGROUND_JUMP_M = 0.03

BACKGROUND_JUMPS = 0.2

BACKGROUND_BEHIND = 0.8

#: A segment runs out of the view (only part of it is seen: a sliver of wall or floor at the image's edge, or an
#: object cut by it) when at least OUT_OF_VIEW_SHARE of its outline lies within OUT_OF_VIEW_PIXELS of the image's edge
#: (or two grid strides of the isolation, whose segments can stop short of the edge by that much).
OUT_OF_VIEW_SHARE = 0.1

OUT_OF_VIEW_PIXELS = 3

#: Two candidates that touch in the image (within MERGE_REACH grid pixels) and share less than MERGE_OVERLAP of the
#: smaller one's grid pixels make one more candidate, their union (:func:`merged_candidate`): an object that plane
#: removal or a depth jump cut in two (a nearly closed laptop on the floor, its slab a few centimetres above it).
MERGE_REACH = 2

MERGE_OVERLAP = 0.5


def out_of_view(mask, stride: int = 1) -> tuple[bool, float]:
    """Whether the segment ``mask`` runs out of the image (module constants ``OUT_OF_VIEW_*``).

    Parameters
    ----------
    mask : (H, W) bool
    stride : int
        The grid stride of the isolation that found the segment (:attr:`Isolation.stride`).

    Returns
    -------
    (bool, float)
        The verdict and the share of the segment's outline (its pixels with a neighbour outside it) within
        ``max(OUT_OF_VIEW_PIXELS, 2 stride)`` of the image's edge (NaN for an empty mask).
    """
    from scipy.ndimage import binary_erosion

    m = np.asarray(mask, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask: expected an (H, W) image, got shape {m.shape}")
    if isinstance(stride, bool) or not isinstance(stride, (int, float, np.integer, np.floating)) or int(stride) != stride or stride < 1:
        raise ValueError(f"stride: expected a positive integer, got {stride!r}")
    bounds = mask_bounds(m)
    if bounds is None:
        return False, float("nan")
    H, W = m.shape
    rows = np.arange(max(0, bounds[0] - 1), min(H, bounds[1] + 1))  # the mask's window, one pixel around it
    cols = np.arange(max(0, bounds[2] - 1), min(W, bounds[3] + 1))
    mw = m[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
    outline = mw & ~binary_erosion(mw, border_value=0)
    n = int(np.count_nonzero(outline))
    k = max(OUT_OF_VIEW_PIXELS, 2 * int(stride))
    edge = ((rows < k) | (rows >= H - k))[:, None] | ((cols < k) | (cols >= W - k))[None, :]
    share = np.count_nonzero(outline & edge) / n
    return bool(share >= OUT_OF_VIEW_SHARE), float(share)


def behind_surroundings(depth, mask) -> tuple[bool, float, float]:
    """Whether the segment ``mask`` lies behind what surrounds it: a background surface (a wall, a curtain) seen
    around nearer things, not an object standing in front of its surroundings (module constants ``BACKGROUND_*``).

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    mask : (H, W) bool

    Returns
    -------
    (bool, float, float)
        The verdict; the share of the ring's measured pixels at a depth jump from the segment; the share of those
        jumps where the surroundings are nearer (NaN without jumps).
    """
    from scipy.ndimage import binary_dilation, grey_dilation, grey_erosion

    d = np.asarray(depth, dtype=np.float64)
    m = np.asarray(mask, dtype=bool)
    if d.shape != m.shape:
        raise ValueError(f"depth, mask: expected one shape, got {d.shape}, {m.shape}")
    if not m.any():
        return False, float("nan"), float("nan")
    r = BACKGROUND_RING
    v0, v1, u0, u1 = mask_bounds(m)
    win = (slice(max(0, v0 - 2 * r), v1 + 2 * r), slice(max(0, u0 - 2 * r), u1 + 2 * r))
    d, m = d[win], m[win]
    ring = binary_dilation(m, iterations=r) & ~m & (d > 0)
    size = 2 * r + 1
    farthest = grey_dilation(np.where(m, d, 0.0), size=(size, size))  # the segment's depths within reach of a pixel
    nearest = grey_erosion(np.where(m, d, np.inf), size=(size, size))
    jump = np.maximum(BACKGROUND_JUMP_M, BACKGROUND_JUMP_M * d)
    nearer = ring & (d < nearest - jump)
    farther = ring & (d > farthest + jump)
    n_ring, n_jump = int(np.count_nonzero(ring)), int(np.count_nonzero(nearer | farther))
    if n_ring == 0 or n_jump == 0:
        return False, 0.0 if n_ring else float("nan"), float("nan")
    jumps, behind = n_jump / n_ring, np.count_nonzero(nearer) / n_jump
    return bool(jumps >= BACKGROUND_JUMPS and behind >= BACKGROUND_BEHIND), float(jumps), float(behind)


def merged_candidate(isolation: Isolation, a: int, b: int, depth, intrinsics: Intrinsics,
                     size_range) -> tuple[Isolation, int] | None:
    """Candidates ``a`` and ``b`` of ``isolation`` as one more candidate, their union, for a caller whose verification
    rejected both (:func:`ancsh.learned.inference.predict.predict_depth`): an object cut in two by plane removal or a
    depth jump is fitted whole. ``(isolation with the union appended to its candidates, its index)``, or ``None``
    when the two do not touch in the image (within :data:`MERGE_REACH` grid pixels), overlap by
    :data:`MERGE_OVERLAP` or more of the smaller one (one holds the other: a candidate with its attached pieces),
    make a candidate there already (an IoU of :data:`SAME_SEGMENT_IOU`), or make one whose size does not fit
    ``size_range``.

    Parameters
    ----------
    isolation : Isolation
        From :func:`isolate_object` of ``depth``.
    a, b : int
        Candidate indices.
    depth : (H, W) float64
        The isolated image (metres).
    intrinsics : Intrinsics
    size_range : (float, float)
        As for :func:`isolate_object`: ``(lo, hi)`` metres.
    """
    from scipy.ndimage import binary_dilation

    lo, hi = check_size_range(size_range)
    for name, c in (("a", a), ("b", b)):
        if isinstance(c, bool) or not isinstance(c, (int, np.integer)) or not 0 <= c < len(isolation.segments):
            raise ValueError(f"{name}: expected a candidate index in [0, {len(isolation.segments)}), got {c!r}")
    ga, gb = isolation.segments[a], isolation.segments[b]
    shared = np.count_nonzero(ga & gb)
    if a == b or shared >= MERGE_OVERLAP * min(np.count_nonzero(ga), np.count_nonzero(gb)):
        return None
    if not np.any(binary_dilation(ga, iterations=MERGE_REACH) & gb):
        return None
    union = ga | gb
    if any(same_segment(union, o) for o in isolation.segments):
        return None
    mask = isolation.mask_of(a) | isolation.mask_of(b)
    vs, us = np.nonzero(mask)
    if len(vs) < 10:
        return None
    diag = extent(backproject(depth, intrinsics, mask), diagonal=True)
    if not fits(diag, lo, hi):
        return None
    s = isolation.stride
    ca, cb = isolation.clusters[a], isolation.clusters[b]
    cluster = Cluster(int(np.count_nonzero(union)) * s * s, diag, (float(us.mean()), float(vs.mean())), True,
                      level=max(ca.level, cb.level))
    new = len(isolation.clusters)
    return replace(isolation, clusters=isolation.clusters + (cluster,), segments=isolation.segments + (union,),
                   order=isolation.order + (new,)), new
