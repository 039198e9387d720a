"""Exact 3D IoU of oriented boxes by convex-polytope intersection.

The intersection of two boxes is a convex polytope whose vertices are (i) the corners
of either box inside the other and (ii) the points where an edge of either box crosses
a face of the other. Its volume is the volume of the convex hull of these points
(Qhull, via :class:`scipy.spatial.ConvexHull`). An empty, touching (flat) or
degenerate intersection has volume 0. No sampling or voxel grid is involved.
"""

from __future__ import annotations

import numpy as np
from .boxes import OrientedBox

# Relative tolerance (times the larger box diagonal) for "on or inside a box" and for
# calling an intersection flat. Points admitted within it change the volume by at most
# about tol * surface area.
_REL_TOL = 1e-10

# The 12 box edges as pairs of indices into OrientedBox.corners() (corners differ in one sign).
_EDGES = np.array(
    [(i, j) for i in range(8) for j in range(i + 1, 8) if bin(i ^ j).count("1") == 1]
)


def intersection_volume(a: OrientedBox, b: OrientedBox) -> float:
    """Volume of the intersection of two oriented boxes (same frame), exact up to rounding.

    Parameters
    ----------
    a, b : OrientedBox
        Boxes in one reference frame (e.g. the camera frame, metres).

    Returns
    -------
    float
        Intersection volume in the frame's cubic units; 0 for disjoint, touching or
        zero-volume boxes.
    """
    _check_box(a, "a")
    _check_box(b, "b")
    if a.volume == 0.0 or b.volume == 0.0:
        return 0.0
    # Each box lies in the ball of radius diagonal / 2 about its centre.
    if np.linalg.norm(a.center - b.center) > 0.5 * (a.diagonal + b.diagonal):
        return 0.0
    tol = _REL_TOL * max(a.diagonal, b.diagonal)
    ca, cb = a.corners(), b.corners()
    pts = np.concatenate(
        [
            ca[b.contains(ca, tol=tol)],
            cb[a.contains(cb, tol=tol)],
            _edge_face_crossings(ca, b, tol),
            _edge_face_crossings(cb, a, tol),
        ]
    )
    if pts.shape[0] < 4:
        return 0.0
    centred = pts - pts.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[2] <= tol * max(1.0, np.sqrt(pts.shape[0])):
        return 0.0  # flat: the boxes touch along a face, an edge or a corner
    from scipy.spatial import ConvexHull, QhullError  # scipy.spatial is slow to import

    try:
        return float(ConvexHull(pts).volume)
    except QhullError:
        # A sliver thicker than tol that Qhull still finds too thin: joggle the input (QJ);
        # the volume changes by far less than tol * surface area.
        return float(ConvexHull(pts, qhull_options="QJ").volume)


def box_iou(a: OrientedBox, b: OrientedBox) -> float:
    """Exact 3D intersection over union of two oriented boxes, in ``[0, 1]``.

    Parameters
    ----------
    a, b : OrientedBox
        Boxes in one reference frame.

    Returns
    -------
    float
        ``V(a & b) / (V(a) + V(b) - V(a & b))``; 0 when exactly one box has zero volume.

    Raises
    ------
    ValueError
        If both boxes have zero volume (the IoU is undefined).
    """
    inter = intersection_volume(a, b)
    union = a.volume + b.volume - inter
    if union <= 0.0:
        raise ValueError("a, b: both boxes have zero volume; their IoU is undefined")
    return float(min(inter / union, 1.0)) if inter > 0 else 0.0


def _edge_face_crossings(corners: np.ndarray, box: OrientedBox, tol: float) -> np.ndarray:
    """Points where the 12 edges of a box with ``corners`` (8, 3) cross the faces of ``box``."""
    # Work in the frame of `box`, where it is the axis-aligned slab |x_k| <= h_k.
    local = (corners - box.center) @ box.rotation
    h = 0.5 * box.extents
    p0, p1 = local[_EDGES[:, 0]], local[_EDGES[:, 1]]  # (12, 3)
    d = p1 - p0
    out = []
    for k in range(3):
        moving = np.abs(d[:, k]) > 0.0
        for side in (-h[k], h[k]):
            t = np.full(len(d), -1.0)
            t[moving] = (side - p0[moving, k]) / d[moving, k]
            ok = (t >= 0.0) & (t <= 1.0)
            x = p0[ok] + t[ok, None] * d[ok]
            x[:, k] = side
            out.append(x[np.all(np.abs(x) <= h + tol, axis=1)])
    pts_local = np.concatenate(out)
    return pts_local @ box.rotation.T + box.center


def _check_box(box, name: str) -> None:
    if not isinstance(box, OrientedBox):
        raise ValueError(f"{name}: expected an OrientedBox, got {type(box).__name__}")
