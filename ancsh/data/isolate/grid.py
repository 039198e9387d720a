"""Helpers of isolation's organised grid: connected components, robust extents, structuring elements, and the check
of the category's size range that sizes planes and segments."""

from __future__ import annotations

import numpy as np

__all__ = ["DISK", "SAME_SEGMENT_IOU", "SIZE_FACTOR", "components", "disk", "extent", "fits", "principal_axes",
           "same_segment", "check_size_range"]

# the opening that parts a support plane from a face touching it (radius 2 grid pixels)
DISK = np.array([[0, 1, 1, 1, 0], [1, 1, 1, 1, 1], [1, 1, 1, 1, 1], [1, 1, 1, 1, 1], [0, 1, 1, 1, 0]], dtype=bool)

#: Size factor: a segment fits the category when its diagonal is in ``[lo / f, hi * f]``; a plane
#: piece wider than ``hi * f`` is a support.
SIZE_FACTOR = 1.5

#: Two candidate segments (of different depths of plane removal) are one when their IoU reaches this.
SAME_SEGMENT_IOU = 0.9


def check_size_range(size_range, name: str = "size_range") -> tuple[float, float]:
    """``(lo, hi)`` metres, checked: the box diagonal range of the category's objects (a
    :class:`~ancsh.data.category_types.CategoryConvention`'s ``diagonal_range``, a loaded category's ``size_range``),
    ``0 < lo <= hi``, finite. A category name is refused: the caller resolves it (``ValueError`` naming ``name``)."""
    if isinstance(size_range, str):
        raise ValueError(f"{name}: expected (lo, hi) metres, got the name {size_range!r}: give its range (e.g. "
                         "CONVENTIONS[name].diagonal_range or load_category(name).size_range)")
    try:
        lo, hi = (float(x) for x in size_range)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected (lo, hi) metres, got {size_range!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= hi):
        raise ValueError(f"{name}: expected 0 < lo <= hi metres, got ({lo}, {hi})")
    return lo, hi


def fits(diagonal: float, lo: float, hi: float) -> bool:
    """Whether a candidate ``diagonal`` metres across fits the size range ``lo..hi`` (within :data:`SIZE_FACTOR`)."""
    return bool(lo / SIZE_FACTOR <= diagonal <= hi * SIZE_FACTOR)


def same_segment(x: np.ndarray, y: np.ndarray) -> bool:
    """Whether two grid masks are one candidate: a like count (the cheap test), then an IoU of
    :data:`SAME_SEGMENT_IOU`."""
    nx, ny = np.count_nonzero(x), np.count_nonzero(y)
    return bool(min(nx, ny) >= SAME_SEGMENT_IOU * max(nx, ny)
                and np.count_nonzero(x & y) >= SAME_SEGMENT_IOU * np.count_nonzero(x | y))


def components(on: np.ndarray, right: np.ndarray, down: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of the grid pixels ``on`` (4-neighbours joined where ``right`` / ``down``
    say their depths agree); ``(count, labels)`` with -1 off ``on``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    h, w = on.shape
    ids = np.full(on.shape, -1, dtype=np.int64)
    ids[on] = np.arange(np.count_nonzero(on))
    r = right & on[:, :-1] & on[:, 1:]
    dn = down & on[:-1, :] & on[1:, :]
    a = np.concatenate([ids[:, :-1][r], ids[:-1, :][dn]])
    b = np.concatenate([ids[:, 1:][r], ids[1:, :][dn]])
    n = int(np.count_nonzero(on))
    if n == 0:
        return 0, ids
    count, lab = connected_components(coo_matrix((np.ones(a.size), (a, b)), shape=(n, n)), directed=False)
    out = np.full(on.shape, -1, dtype=np.int64)
    out[on] = lab
    return int(count), out


def disk(radius: int) -> np.ndarray:
    """A disk of ``radius`` grid pixels, as a structuring element."""
    yy, xx = np.mgrid[-radius:radius + 1, -radius:radius + 1]
    return yy ** 2 + xx ** 2 <= radius * radius + 1


def extent(points: np.ndarray, *, diagonal: bool = False) -> float:
    """Largest robust extent (2nd-98th percentile along principal axes) or the diagonal of those extents."""
    p = points - points.mean(axis=0)
    p = p[:: max(1, len(p) // 2000)]
    q = np.sort(p @ principal_axes(p), axis=0)
    n = len(q) - 1
    ext = q[int(round(0.98 * n))] - q[int(round(0.02 * n))]
    return float(np.linalg.norm(ext)) if diagonal else float(ext.max())


def principal_axes(centred: np.ndarray) -> np.ndarray:
    """(3, 3) principal axes (columns, largest variance first) of centred points, from their 3x3 scatter."""
    _, vecs = np.linalg.eigh(centred.T @ centred)
    return vecs[:, ::-1]
