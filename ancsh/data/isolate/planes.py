"""Supporting planes of isolation: RANSAC planes on the organised grid whose connected pieces are wider than any
object of the category, or wider than a typical one and running out of the view (:func:`remove_supports`)."""

from __future__ import annotations

import numpy as np

from .grid import DISK, SIZE_FACTOR, components, disk, extent, principal_axes

__all__ = ["grid_normals", "plane_threshold", "ransac_plane", "refine_plane", "remove_supports", "runs_out",
           "view_border"]

#: Plane inlier distance (metres; at least 2 % of the category's smallest size).
PLANE_THRESHOLD_M = 0.012

#: A plane's inliers turn with it: their surface normal within ~37 degrees of the plane's (cosine), normals
#: measured across NORMAL_SPAN grid pixels on each side.
PLANE_NORMAL_COS = 0.8

NORMAL_SPAN = 2

#: Pixels this near (metres) to two support planes, and within CORNER_REACH grid pixels of both planes' removed pieces
#: in the image, are support too (the rounded edge between them).
CORNER_MARGIN_M = 0.03

CORNER_REACH = 4

#: Plane RANSAC runs on at most this many of the free grid pixels (the inliers are then counted on all) and draws this
#: many triples: more triples on fewer points (3000 x 120 before) find the same largest plane at every seed (on a
#: staircase scene the candidate list changed with the seed: 4-6 planes removed, 3 of 10 seeds without the object's
#: segments; with 1000 x 400, 5-6 planes and the object's segments first at all 10), for about the same cost.
RANSAC_POINTS = 1000

RANSAC_ITERATIONS = 400

#: Planes are searched at most this many times, and only while the best holds this share of the grid.
MAX_PLANES = 8

MIN_PLANE_FRACTION = 0.03

#: A plane piece running out of the view has at least this many grid pixels within BORDER_REACH grid pixels of the
#: image's edge or of a region without depth joined to the edge (:func:`view_border`).
BORDER_PIXELS = 10

BORDER_REACH = 3

#: A region without depth joined to the image's edge is a sensor's dead band when it stays within this share of the
#: image's width (height) from the edge.
DEAD_BAND_SHARE = 0.1

#: A plane piece's ends grow back this many grid pixels along the plane's inliers for the border test (the opening
#: eats the tapering ends of a thin band).
BAND_END_PIXELS = 12


def plane_threshold(lo: float) -> float:
    """A point's largest distance from a plane it is on without noise to allow for (metres): :data:`PLANE_THRESHOLD_M`,
    at least 2 % of the category's smallest size ``lo``."""
    return max(PLANE_THRESHOLD_M, 0.02 * lo)


def grid_normals(P: np.ndarray, gv: np.ndarray, right: np.ndarray, down: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Surface normals ``(h, w, 3)`` of the grid points ``P`` (camera frame, metres) from the grid neighbours
    :data:`NORMAL_SPAN` pixels away on each side, where the pixels between are joined (``right``, ``down``: neighbours
    whose depths agree), and where they are defined ``(h, w)`` bool."""
    normals = np.zeros(P.shape)
    normal_ok = np.zeros(gv.shape, dtype=bool)
    k = NORMAL_SPAN
    if min(gv.shape) > 2 * k:
        rj = np.ones(gv.shape, dtype=bool)[:, :-2 * k].copy()
        for i in range(2 * k):
            rj &= right[:, i:right.shape[1] - 2 * k + i + 1]
        dj = np.ones(gv.shape, dtype=bool)[:-2 * k, :].copy()
        for i in range(2 * k):
            dj &= down[i:down.shape[0] - 2 * k + i + 1, :]
        joined = rj[k:-k, :] & dj[:, k:-k]
        n = np.cross(P[k:-k, 2 * k:] - P[k:-k, :-2 * k], P[2 * k:, k:-k] - P[:-2 * k, k:-k])
        length = np.linalg.norm(n, axis=-1)
        good = joined & (length > 0)
        normals[k:-k, k:-k][good] = n[good] / length[good][:, None]
        normal_ok[k:-k, k:-k] = good
    return normals, normal_ok


def remove_supports(P: np.ndarray, gv: np.ndarray, normals: np.ndarray, normal_ok: np.ndarray, right: np.ndarray,
                    down: np.ndarray, lo: float, hi: float, rng, tolerance=None) -> tuple[list, np.ndarray, int]:
    """The support planes of the grid: RANSAC planes (at most :data:`MAX_PLANES`) whose connected pieces, after an
    opening, are wider than the category's largest size ``hi`` times ``SIZE_FACTOR``, or wider than a typical one
    (``sqrt(lo hi)``, metres) and running out of the view; then the rounded edges where two supports meet.

    ``P`` are the grid points (camera frame, metres; in :func:`~.proposals.isolate_object` those of
    :func:`~.noise.plane_points`: smoothed where the sensor's noise calls for it); a point is on a plane within
    :func:`plane_threshold` or, where larger, its ``tolerance`` (``(h, w)`` metres, from the
    same function: the noise at its depth), and near a support for its corner within :data:`CORNER_MARGIN_M` or that
    tolerance.

    Returns ``(supports, support, planes)``: the support ``(h, w)`` bool after each removal (the candidates' depths
    of plane removal), the last support, and how many planes were removed."""
    from scipy.ndimage import binary_dilation, binary_opening

    support = np.zeros(gv.shape, dtype=bool)
    tried = np.zeros(gv.shape, dtype=bool)  # planes that were no support: kept, but not searched again
    planes = 0
    base = plane_threshold(lo)
    thresh = np.full(gv.size, base) if tolerance is None else np.maximum(np.ravel(tolerance), base)
    corner = np.maximum(CORNER_MARGIN_M, thresh.reshape(gv.shape))
    typical = np.sqrt(lo * hi)
    idx = np.flatnonzero(gv.ravel())
    flat = P.reshape(-1, 3)
    border = view_border(gv)
    near = []  # per support plane: grid pixels within CORNER_MARGIN_M of it
    supports = []  # the support after each removal
    for _ in range(MAX_PLANES):
        free = idx[~(support | tried).ravel()[idx]]
        if free.size < 50:
            break
        sample = free if free.size <= RANSAC_POINTS else rng.choice(free, RANSAC_POINTS, replace=False)
        n_plane, e = ransac_plane(flat[sample], thresh[sample], rng)  # the sample's plane, then its inliers among
        inl = np.flatnonzero(np.abs(flat[free] @ n_plane + e) < thresh[free])  # all free pixels, refitted
        inl = refine_plane(flat[free], inl, thresh[free])
        if inl.size < max(50, MIN_PLANE_FRACTION * idx.size):
            break
        on = np.zeros(gv.size, dtype=bool)
        on[free[inl]] = True
        on = on.reshape(gv.shape)
        # only where the surface turns like the plane: an object's face crossing it (a lid leaning on a
        # riser) is not part of the support
        q = flat[free[inl]]
        centre = q.mean(axis=0)
        normal = principal_axes(q - centre)[:, -1]
        on &= ~normal_ok | (np.abs(normals @ normal) >= PLANE_NORMAL_COS)
        # pieces of the plane after an opening: a face touching the support along a thin contact (a lid
        # leaning on a riser, in its plane) comes apart from it; the contact strip goes back to the support
        opened = binary_opening(on, structure=DISK, border_value=1) & on  # (the border value grows a frame)
        n_pieces, pieces = components(opened, right, down)
        removed = False
        before = support.copy()
        piece_sizes = np.bincount(pieces[pieces >= 0], minlength=n_pieces)
        others = []  # pieces that are no support by their own size
        for c in np.flatnonzero(piece_sizes >= 20):
            sel = pieces == c
            q = P[sel]
            # wider than any object of the category, or wider than a typical one and running out of the
            # view (a table top, a floor, a stair tread: an object's face rarely reaches the border)
            if np.linalg.norm(q.max(axis=0) - q.min(axis=0)) > typical and (
                    extent(q) > SIZE_FACTOR * hi or (extent(q) > typical and runs_out(sel, on, border))):
                support |= on & binary_dilation(sel, structure=DISK)
                removed = True
            else:
                others.append(sel)
        if removed:  # a support's other pieces that run out of the view: its ends beyond what stands on it
            for sel in others:
                if runs_out(sel, on, border):
                    support |= on & binary_dilation(sel, structure=DISK)
        tried |= on & ~support
        if removed:
            supports.append(support.copy())
            # near the plane and beside its removed pieces: the whole plane runs through other things too
            beside = binary_dilation(support & ~before, structure=disk(CORNER_REACH))
            near.append(beside & (np.abs((P - centre) @ normal) < corner))
        planes += int(removed)
    # where two supports meet (a stair's nosing, a table's edge against a wall) the surface is neither
    # plane: pixels near two of them are support too, so that objects standing there come apart
    for k in range(1, len(supports)):
        supports[k] = supports[k] | (gv & (np.sum(near[: k + 1], axis=0) >= 2))
    return supports, support, planes

def ransac_plane(points: np.ndarray, thresh, rng) -> tuple[np.ndarray, float]:
    """The plane ``n . x + e = 0`` (unit ``n``) through three of ``points`` (N, 3) with the most points within
    ``thresh`` metres (a number, or one per point), of :data:`RANSAC_ITERATIONS` random triples (all scored at once)."""
    triples = points[rng.integers(0, len(points), (RANSAC_ITERATIONS, 3))]
    n = np.cross(triples[:, 1] - triples[:, 0], triples[:, 2] - triples[:, 0])
    length = np.linalg.norm(n, axis=1)
    good = length > 1e-12
    if not good.any():
        return np.array([0.0, 0.0, 1.0]), -float(points[0, 2])
    n = n[good] / length[good, None]
    e = -np.einsum("ij,ij->i", n, triples[good, 0])
    counts = np.count_nonzero(np.abs(points @ n.T + e) < np.reshape(thresh, (-1, 1)), axis=0)
    best = int(np.argmax(counts))
    return n[best], float(e[best])


def refine_plane(points: np.ndarray, inliers: np.ndarray, thresh, rounds: int = 3) -> np.ndarray:
    """Least-squares refits of a RANSAC plane to its inliers (stable against the random sample); ``thresh``: metres, a
    number or one per point."""
    for _ in range(rounds):
        if inliers.size < 3:
            break
        p = points[inliers]
        c = p.mean(axis=0)
        normal = principal_axes(p - c)[:, -1]
        new = np.flatnonzero(np.abs((points - c) @ normal) < thresh)
        if np.array_equal(new, inliers):
            break
        inliers = new
    return inliers


def runs_out(piece: np.ndarray, on: np.ndarray, border: np.ndarray) -> bool:
    """Whether a plane's ``piece`` runs out of the view: at least :data:`BORDER_PIXELS` of it, grown back
    :data:`BAND_END_PIXELS` grid pixels along the plane's inliers ``on`` (the opening eats the ends of a thin band: a
    stair's riser seen from above), lie on the view's ``border``."""
    from scipy.ndimage import binary_dilation

    from ..images import mask_bounds

    v0, v1, u0, u1 = mask_bounds(piece)
    r = BAND_END_PIXELS
    win = (slice(max(0, v0 - r), v1 + r), slice(max(0, u0 - r), u1 + r))
    grown = binary_dilation(piece[win], iterations=r, mask=on[win])
    return np.count_nonzero(grown & border[win]) >= BORDER_PIXELS


def view_border(gv: np.ndarray) -> np.ndarray:
    """Where a surface runs out of the view (grid pixels): the image's edge, and beside a sensor's dead band -- pixels
    without depth joined to the edge that stay within :data:`DEAD_BAND_SHARE` of the image from it (a wide region
    without depth, such as a background beyond the range, is not the view's end: objects stand in front of it)."""
    from scipy.ndimage import binary_dilation, label

    h, w = gv.shape
    frame = np.zeros(gv.shape, dtype=bool)
    frame[[0, -1], :] = True
    frame[:, [0, -1]] = True
    band = np.zeros(gv.shape, dtype=bool)
    bh, bw = max(1, int(DEAD_BAND_SHARE * h)), max(1, int(DEAD_BAND_SHARE * w))
    band[:bh, :] = band[-bh:, :] = True
    band[:, :bw] = band[:, -bw:] = True
    lab, n = label(~gv)
    touching = np.unique(lab[frame & ~gv])
    beyond = np.unique(lab[~band & ~gv])  # regions reaching past the band
    dead = np.setdiff1d(touching[touching > 0], beyond)
    outside = np.isin(lab, dead)
    return binary_dilation(frame | outside, structure=np.ones((3, 3), dtype=bool), iterations=BORDER_REACH) & gv
