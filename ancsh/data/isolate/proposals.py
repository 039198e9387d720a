"""Candidate segments of isolation (:func:`isolate_object`): the organised grid, support planes removed
(:mod:`.planes`), connected segments where neighbouring depths do not jump, ranked by size and centrality or by a
hint (:mod:`.hints`); :class:`Isolation` holds them for a caller who verifies them (:mod:`.verification`)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..images import mask_bounds
from ..render import Intrinsics, valid_depth_pixels
from .grid import SIZE_FACTOR, components, extent, fits, same_segment, check_size_range
from .hints import ObjectHint, check_hint_inside, hinted_order
from .noise import plane_points
from .planes import grid_normals, plane_threshold, remove_supports

__all__ = ["Cluster", "Isolation", "isolate_object"]

#: Planes and segments are found on the image subsampled to about this many pixels.
TARGET_GRID_PIXELS = 30000

#: Neighbouring grid pixels belong to one segment when their depths differ by less than this many
#: grid spacings at that depth plus :data:`JUMP_NOISE_M` (a surface up to ~75 degrees from facing the camera).
JUMP_SPACINGS = 4.0

JUMP_NOISE_M = 0.006

#: Ranking without a hint: a segment whose diagonal is e times the category's typical one (the geometric mean of its
#: range) counts as this much farther from the image centre (in image widths): remnants of walls and stairs that just
#: fit the range come after object-sized segments.
SIZE_PRIOR = 0.25

#: Smaller segments touching a candidate in the image whose nearest points in 3D come within this share of the
#: category's typical size of the candidate's, and whose union with it stays within the category's largest size, are
#: attached to it in a second candidate (:func:`with_attached`: a lid, a door ajar or a drawer front parted from its
#: object by a depth jump). Measured on stress scenes (seed 5, 16 a category; not the benchmark's stream): of the
#: touching pieces of 20 grid pixels or more that are their candidate's object, a median boundary step below 0.15 of
#: the typical size took 28 of 251 (and 4 of 490 pieces of other things); a 3D gap below 0.2 takes 145 (and 36).
ATTACH_SHARE = 0.2

#: Segments smaller than this many grid pixels are noise.
MIN_SEGMENT_GRID_PIXELS = 20


@dataclass(frozen=True)
class Cluster:
    """One candidate object: its pixel count (about), size (diagonal, metres), image centroid ``(u, v)``, whether
    its size fits the category and how many support planes were removed when it was found (``level``)."""

    pixels: int
    diagonal: float
    centroid_uv: tuple
    fits_category: bool
    level: int = 0

    def to_dict(self) -> dict:
        return {"pixels": self.pixels, "diagonal_m": self.diagonal, "centroid_uv": list(self.centroid_uv),
                "fits_category": self.fits_category, "planes_removed": self.level}


@dataclass(frozen=True)
class Isolation:
    """What :func:`isolate_object` found.

    Attributes
    ----------
    mask : (H, W) bool
        Pixels of the chosen object (all ``False`` when nothing was found).
    labels : (H, W) int64
        ``-2`` no depth, ``-1`` removed (a support plane or a tiny piece), ``c >= 0`` segment ``c`` (where
        candidates of several depths of plane removal overlap, the deepest one's).
    clusters : tuple of Cluster
        The segments (candidates).
    chosen : int or None
        Index of the chosen segment.
    planes : int
        Supporting planes removed.
    reason : str
        Why that segment was chosen.
    order : tuple of int
        Every segment, best candidate first (``order[0] == chosen``).
    stride : int
        The grid's subsampling (pixels).
    verified : tuple of dict
        Candidates a caller judged (:meth:`with_choice`), each ``{"segment", "status", "score", ...}``.
    hinted : tuple of int
        The candidates a hint points at (under the pixel, or in the box), best first; empty without a hint.
    segments : tuple of (h, w) bool
        Each candidate's pixels on the subsampled grid (:meth:`mask_of` gives full resolution). Candidates come
        from every depth of plane removal.
    """

    mask: np.ndarray
    labels: np.ndarray
    clusters: tuple = ()
    chosen: int | None = None
    planes: int = 0
    reason: str = ""
    order: tuple = ()
    stride: int = 1
    verified: tuple = ()
    hinted: tuple = ()
    segments: tuple = field(default=(), repr=False)
    _upsample: object = field(default=None, repr=False, compare=False)

    def mask_of(self, c: int) -> np.ndarray:
        """Full-resolution pixels (H, W) bool of candidate segment ``c``."""
        if self._upsample is None or not 0 <= c < len(self.segments):
            return self.labels == c
        return self._upsample(self.segments[c])

    def with_choice(self, chosen, reason: str, verified=()) -> "Isolation":
        """This isolation with segment ``chosen`` (or ``None``: none is the object) chosen by a caller's verification."""
        mask = self.mask_of(chosen) if chosen is not None else np.zeros_like(self.mask)
        return replace(self, mask=mask, chosen=chosen, reason=reason, verified=tuple(verified))

    def summary(self) -> str:
        if self.chosen is None:
            return f"isolation: no object found ({self.reason})"
        c = self.clusters[self.chosen]
        return (f"isolation: {self.planes} plane(s) removed, {len(self.clusters)} segment(s); chose segment "
                f"{self.chosen} ({c.pixels} pixels, {c.diagonal:.2f} m across): {self.reason}")

    def to_dict(self) -> dict:
        return {"planes_removed": self.planes, "clusters": [c.to_dict() for c in self.clusters], "chosen": self.chosen,
                "reason": self.reason, "order": list(self.order), "stride": self.stride, "hinted": list(self.hinted),
                "verified": list(self.verified)}


def isolate_object(depth, intrinsics: Intrinsics, size_range, *, hint: ObjectHint | None = None,
                   max_depth: float | None = None, rng=0) -> Isolation:
    """Candidate segments of an object of a category in a depth image (see the module docstring).

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
    size_range : (float, float)
        ``(lo, hi)`` metres: the box diagonal range of the category's objects (its
        :class:`~ancsh.data.category_types.CategoryConvention`'s ``diagonal_range``); it sizes the planes, segments
        and the ranking.
    hint : ObjectHint, optional
    max_depth : float, optional
        Metres; deeper pixels are ignored.
    rng : numpy.random.Generator or int
        Plane RANSAC seed.

    Returns
    -------
    Isolation
        ``mask`` = the first candidate's pixels (full resolution).
    """
    from ...geometry._checks import check_generator

    rng = check_generator(rng)
    lo, hi = check_size_range(size_range)
    d, valid = valid_depth_pixels(depth, intrinsics)
    if max_depth is not None:
        valid &= d <= max_depth
    H, W = d.shape
    check_hint_inside(hint, W, H)
    labels = np.full(d.shape, -2, dtype=np.int64)
    labels[valid] = -1
    if np.count_nonzero(valid) < 10:
        return Isolation(np.zeros(d.shape, dtype=bool), labels, reason=f"{np.count_nonzero(valid)} valid pixels")
    # --- the organised grid -------------------------------------------------------------------------
    s = max(1, int(round(np.sqrt(H * W / TARGET_GRID_PIXELS))))
    g = np.where(valid, d, 0.0)[::s, ::s]
    gv = g > 0
    vv, uu = np.mgrid[0:H:s, 0:W:s]
    P = np.stack([(uu - intrinsics.cx) / intrinsics.fx * g, (vv - intrinsics.cy) / intrinsics.fy * g, g], axis=-1)
    jump = JUMP_SPACINGS * s * g / min(intrinsics.fx, intrinsics.fy) + JUMP_NOISE_M  # per grid pixel (metres)
    right = gv[:, :-1] & gv[:, 1:] & (np.abs(g[:, :-1] - g[:, 1:]) < np.minimum(jump[:, :-1], jump[:, 1:]))
    down = gv[:-1, :] & gv[1:, :] & (np.abs(g[:-1, :] - g[1:, :]) < np.minimum(jump[:-1, :], jump[1:, :]))
    # where the sensor's noise is larger than a plane's tolerance (far from the camera raw normals scatter too widely
    # for any plane to hold together), planes are searched on points averaged over their surface's neighbours,
    # within the noise measured at their depth
    Q, tolerance = plane_points(P, gv, jump, plane_threshold(lo))
    normals, normal_ok = grid_normals(Q, gv, right, down)
    supports, support, planes = remove_supports(Q, gv, normals, normal_ok, right, down, lo, hi, rng, tolerance)
    # --- candidate segments at every depth of plane removal --------------------------------------------
    # (a plane removed late may take an object's face with it: a lid leaning on a stair's riser)
    levels = supports or [support]
    gi = np.minimum((np.arange(H) + s // 2) // s, g.shape[0] - 1)
    gj = np.minimum((np.arange(W) + s // 2) // s, g.shape[1] - 1)

    def nearest(grid):
        """A grid image at full resolution: each pixel its grid pixel's value (rows, then columns: a fourth of the
        time of one 2-D fancy index on a 1280 x 720 image)."""
        return np.take(np.take(grid, gi, axis=0), gj, axis=1)

    agree_depth = valid & (np.abs(d - nearest(g)) < nearest(jump))

    def upsample(grid_mask):
        """Full-resolution pixels of a grid segment: their grid pixel is in it and their depth agrees."""
        return agree_depth & nearest(grid_mask)

    typical = np.sqrt(lo * hi)
    segments, clusters = [], []
    for level, sup in enumerate(levels):
        n_seg, seg = components(gv & ~sup, right, down)
        sizes = np.bincount(seg[seg >= 0], minlength=n_seg)
        members = component_members(seg, n_seg)
        for c in np.flatnonzero(sizes >= MIN_SEGMENT_GRID_PIXELS):
            base = seg == c
            for sel in (base, with_attached(seg, c, sizes, P, ATTACH_SHARE * typical, hi, members)):
                n = int(np.count_nonzero(sel)) * s * s
                # the same segment as at an earlier depth (a plane removed elsewhere), or as the segment without
                # what is attached to it
                if any(same_segment(sel, o) for o in segments):
                    continue
                diag = extent(P[sel], diagonal=True)
                segments.append(sel)
                clusters.append(Cluster(n, diag, (float(uu[sel].mean()), float(vv[sel].mean())),
                                        fits(diag, lo, hi),
                                        level=level + 1 if supports else 0))
    # labels for pictures: every candidate, the deeper ones (smaller pieces) over the shallower
    final = np.full(gv.shape, -1, dtype=np.int64)
    for c in sorted(range(len(segments)), key=lambda c: clusters[c].level):
        final[segments[c]] = c
    near_seg = nearest(final)
    labelled = agree_depth & (near_seg >= 0)
    labels[labelled] = near_seg[labelled]
    if not clusters:
        return Isolation(np.zeros(d.shape, dtype=bool), labels, (), None, planes,
                         "nothing left after removing planes and small pieces", stride=s)
    order, reason, hinted = _rank(clusters, segments, gi, gj, intrinsics, hint, lo, hi)
    return Isolation(upsample(segments[order[0]]), labels, tuple(clusters), order[0], planes, reason, order=tuple(order),
                     stride=s, hinted=tuple(hinted), segments=tuple(segments), _upsample=upsample)


def with_attached(seg: np.ndarray, c: int, sizes: np.ndarray, points: np.ndarray, gap: float,
                  largest: float = np.inf, members: list | None = None) -> np.ndarray:
    """Segment ``c`` of the component labels ``seg`` (-1 = none) with the smaller components that touch it in the
    image and come within ``gap`` metres of it in 3D (their nearest points), each one's union with it no wider than
    ``largest`` metres (the diagonal of its bounding box in the camera's axes): a lid, a door ajar, a drawer front
    parted from the object by a depth jump. ``(h, w)`` bool; just segment ``c`` when nothing is attached.

    Parameters
    ----------
    seg : (h, w) int64
        Component labels of the grid.
    c : int
    sizes : (n,) int
        Grid pixels of each component.
    points : (h, w, 3) float64
        The grid's back-projected points (camera frame, metres).
    gap : float
        Metres.
    largest : float
        Metres.
    members : list of (m,) int64, optional
        Flat grid indices of each component (:func:`component_members` of ``seg``, computed when not given).
    """
    from scipy.spatial import cKDTree

    sel = seg == c
    if members is None:
        members = component_members(seg, len(sizes))
    flat = points.reshape(-1, 3)
    own = flat[members[c]]
    lo_c, hi_c = own.min(axis=0), own.max(axis=0)
    if np.linalg.norm(hi_c - lo_c) > largest:
        return sel  # already too wide for any union to stay within ``largest``
    v0, v1, u0, u1 = mask_bounds(sel)
    sw = seg[max(0, v0 - 1):v1 + 1, max(0, u0 - 1):u1 + 1]
    touching = set()
    for a, b in ((sw[:, :-1], sw[:, 1:]), (sw[:-1, :], sw[1:, :])):
        touching.update(np.unique(b[(a == c) & (b >= 0) & (b != c)]).tolist())
        touching.update(np.unique(a[(b == c) & (a >= 0) & (a != c)]).tolist())
    touching = [k for k in sorted(touching) if sizes[k] < sizes[c]]
    if not touching:
        return sel
    attached = []
    for k in touching:
        piece = flat[members[k]]
        lo_k, hi_k = piece.min(axis=0), piece.max(axis=0)
        # the boxes' distance first: most pieces are far off; then only the candidate's points within reach of the
        # piece's box can be within reach of the piece
        if np.linalg.norm(np.maximum(0.0, np.maximum(lo_c - hi_k, lo_k - hi_c))) >= gap:
            continue
        near = own[np.all((own > lo_k - gap) & (own < hi_k + gap), axis=1)]
        if len(near) == 0 or cKDTree(near).query(piece, distance_upper_bound=gap)[0].min() >= gap:
            continue
        if np.linalg.norm(np.maximum(hi_c, hi_k) - np.minimum(lo_c, lo_k)) <= largest:
            attached.append(k)
    return sel | np.isin(seg, attached) if attached else sel


def component_members(seg: np.ndarray, n: int) -> list:
    """Flat grid indices of each of the ``n`` components of the labels ``seg`` (-1 = none): a list of ``n`` arrays."""
    flat = seg.ravel()
    order = np.argsort(flat, kind="stable")
    first = np.searchsorted(flat[order], np.arange(n + 1))
    return [order[first[k]:first[k + 1]] for k in range(n)]


def _rank(clusters, segments, gi, gj, intr, hint, lo, hi) -> tuple[list, str, list]:
    """Candidate order (first = the choice), why the first was chosen, and the candidates a hint points at."""
    every = list(range(len(clusters)))
    centre = np.array([(intr.width - 1) / 2.0, (intr.height - 1) / 2.0])
    mid = np.sqrt(lo * hi)

    def prior(c):
        dist = np.linalg.norm(np.asarray(clusters[c].centroid_uv) - centre) / max(intr.width, intr.height)
        size_gap = abs(np.log(max(clusters[c].diagonal, 1e-6) / mid))
        # centrality (a share of the image) and nearness to the typical size (SIZE_PRIOR per e-fold), in tenths:
        # pieces of one object from different depths of plane removal sit alike, and the largest comes first
        return (not clusters[c].fits_category,
                round(dist + SIZE_PRIOR * size_gap, 1) if clusters[c].fits_category else size_gap, -clusters[c].pixels)

    order = sorted(every, key=prior)
    if hint is not None:
        hinted = hinted_order(hint, order, clusters, segments, gi, gj)
        if hinted is not None:
            return hinted
    if clusters[order[0]].fits_category:
        return order, f"size fits the category ({lo}..{hi} m, x{SIZE_FACTOR}) and nearest the image centre", []
    return order, "no segment fits the category's size: the closest in size", []
