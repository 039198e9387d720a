"""Find the object in a depth image without a mask: remove supporting planes, segment, rank candidates.
Long: one pipeline over the organised grid (planes, segments, ranking) and the checks and joins a verifier applies
to its candidates, all reading the same size constants and grid.

:func:`isolate_object` works on the organised image, subsampled to about
:data:`TARGET_GRID_PIXELS` pixels (a 1280x720 frame every 6th pixel): it removes planes wider than
any object of the category (floors, table tops, stair treads and risers, walls: RANSAC planes whose
connected pieces are wider than the category's largest size times :data:`SIZE_FACTOR`, or wider than
a typical one and running out of the view -- the image's edge or a region without depth joined to it, such as a
sensor's dead band; once a plane is a support, its other pieces that run out of the view are too: a riser's ends
beyond the objects standing in front of it), removes the rounded edges where two supports meet, splits the
rest into connected segments where neighbouring pixels' depths jump (more than a few grid spacings
at that depth) -- each segment also with the smaller ones attached to it across a small depth step (a door ajar),
as a second candidate -- and ranks the segments as candidates:

- with an :class:`ObjectHint`: the segment under the pixel ``(u, v)`` (or the nearest one), or
  with most pixels in the box;
- without one: segments whose size fits the category's ``diagonal_range`` first, nearer the
  image centre and nearer the category's typical size first (:data:`SIZE_PRIOR`; in tenths; within one, more
  pixels first); then the rest, closest in size first.

The result is a pixel mask of the first candidate plus every candidate (:class:`Isolation`:
``labels`` and the ranked ``order``), so that a caller who can judge a candidate (the category's
network and fit, :func:`ancsh.learned.inference.predict.predict_depth`) may verify several and
choose, and, when it rejects every one, join two that touch into one more candidate (:func:`merged_candidate`: an
object that plane removal cut in two). A mask given by the user always wins over this (``ancsh predict --mask``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .render import Intrinsics, backproject, valid_depth_pixels

__all__ = ["ObjectHint", "Cluster", "Isolation", "behind_surroundings", "isolate_object", "merged_candidate", "out_of_view",
           "parse_hint"]

# the opening that parts a support plane from a face touching it (radius 2 grid pixels)
_DISK = np.array([[0, 1, 1, 1, 0], [1, 1, 1, 1, 1], [1, 1, 1, 1, 1], [1, 1, 1, 1, 1], [0, 1, 1, 1, 0]], dtype=bool)

#: Planes and segments are found on the image subsampled to about this many pixels.
TARGET_GRID_PIXELS = 30000
#: Size factor: a segment fits the category when its diagonal is in ``[lo / f, hi * f]``; a plane
#: piece wider than ``hi * f`` is a support.
SIZE_FACTOR = 1.5
#: Neighbouring grid pixels belong to one segment when their depths differ by less than this many
#: grid spacings at that depth plus :data:`JUMP_NOISE_M` (a surface up to ~75 degrees from facing the camera).
JUMP_SPACINGS = 4.0
JUMP_NOISE_M = 0.006
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
#: image's edge or of a region without depth joined to the edge (:func:`_view_border`).
BORDER_PIXELS = 10
BORDER_REACH = 3
#: A region without depth joined to the image's edge is a sensor's dead band when it stays within this share of the
#: image's width (height) from the edge.
DEAD_BAND_SHARE = 0.1
#: A plane piece's ends grow back this many grid pixels along the plane's inliers for the border test (the opening
#: eats the tapering ends of a thin band).
BAND_END_PIXELS = 12
#: Two candidate segments (of different depths of plane removal) are one when their IoU reaches this.
SAME_SEGMENT_IOU = 0.9
#: Ranking without a hint: a segment whose diagonal is e times the category's typical one (the geometric mean of its
#: range) counts as this much farther from the image centre (in image widths): remnants of walls and stairs that just
#: fit the range come after object-sized segments.
SIZE_PRIOR = 0.25
#: Smaller segments touching a candidate at a median depth step below this share of the category's typical size are
#: attached to it in a second candidate (:func:`_with_attached`: a door ajar, parted from its object by a depth jump).
ATTACH_SHARE = 0.15
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
#: Segments smaller than this many grid pixels are noise.
MIN_SEGMENT_GRID_PIXELS = 20
#: Two candidates that touch in the image (within MERGE_REACH grid pixels) and share less than MERGE_OVERLAP of the
#: smaller one's grid pixels make one more candidate, their union (:func:`merged_candidate`): an object that plane
#: removal or a depth jump cut in two (a nearly closed laptop on the floor, its slab a few centimetres above it).
MERGE_REACH = 2
MERGE_OVERLAP = 0.5


@dataclass(frozen=True)
class ObjectHint:
    """Where the object is in the image: a pixel ``(u, v)`` or a box ``(u0, v0, u1, v1)`` (pixels)."""

    pixel: tuple | None = None
    box: tuple | None = None

    def __post_init__(self):
        if (self.pixel is None) == (self.box is None):
            raise ValueError("hint: give exactly one of pixel (u, v) or box (u0, v0, u1, v1)")
        if self.pixel is not None:
            p = tuple(float(x) for x in self.pixel)
            if len(p) != 2 or not all(np.isfinite(p)):
                raise ValueError(f"pixel: expected two finite numbers u,v, got {self.pixel!r}")
            object.__setattr__(self, "pixel", p)
        if self.box is not None:
            b = tuple(float(x) for x in self.box)
            if len(b) != 4 or not all(np.isfinite(b)) or b[2] <= b[0] or b[3] <= b[1]:
                raise ValueError(f"box: expected u0,v0,u1,v1 with u1 > u0 and v1 > v0, got {self.box!r}")
            object.__setattr__(self, "box", b)


def parse_hint(pixel: str | None = None, box: str | None = None) -> ObjectHint | None:
    """An :class:`ObjectHint` from command-line text ``"u,v"`` / ``"u0,v0,u1,v1"`` (``None`` without either)."""
    if pixel is None and box is None:
        return None
    if pixel is not None and box is not None:
        raise ValueError("--pixel, --box: give one of them, not both")
    name, text = ("--pixel", pixel) if pixel is not None else ("--box", box)
    try:
        values = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise ValueError(f"{name}: expected comma-separated pixel coordinates, got {text!r}") from None
    try:
        return ObjectHint(pixel=values) if pixel is not None else ObjectHint(box=values)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None


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


def isolate_object(depth, intrinsics: Intrinsics, category: str, *, hint: ObjectHint | None = None,
                   max_depth: float | None = None, rng=0) -> Isolation:
    """Candidate segments of the object of ``category`` in a depth image (see the module docstring).

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
    category : str
        A procedural category (its ``diagonal_range`` sizes the planes, segments and the ranking);
        other names use 0.1..2 m.
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
    from scipy.ndimage import binary_dilation, binary_opening

    from ..geometry._checks import check_generator

    rng = check_generator(rng)
    lo, hi = _size_range(category)
    d, valid = valid_depth_pixels(depth, intrinsics)
    if max_depth is not None:
        valid &= d <= max_depth
    H, W = d.shape
    _check_hint_inside(hint, W, H)
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
    # surface normals from the grid neighbours two pixels away on each side (where the pixels between are joined)
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
    # --- supporting planes: connected pieces wider than any object of the category ----------------------
    support = np.zeros(gv.shape, dtype=bool)
    tried = np.zeros(gv.shape, dtype=bool)  # planes that were no support: kept, but not searched again
    planes = 0
    thresh = max(PLANE_THRESHOLD_M, 0.02 * lo)
    typical = np.sqrt(lo * hi)
    idx = np.flatnonzero(gv.ravel())
    flat = P.reshape(-1, 3)
    border = _view_border(gv)
    near = []  # per support plane: grid pixels within CORNER_MARGIN_M of it
    supports = []  # the support after each removal
    for _ in range(MAX_PLANES):
        free = idx[~(support | tried).ravel()[idx]]
        if free.size < 50:
            break
        sample = free if free.size <= RANSAC_POINTS else rng.choice(free, RANSAC_POINTS, replace=False)
        n_plane, e = _ransac_plane(flat[sample], thresh, rng)  # the sample's plane, then its inliers among all free
        inl = np.flatnonzero(np.abs(flat[free] @ n_plane + e) < thresh)  # pixels, refitted
        inl = _refine_plane(flat[free], inl, thresh)
        if inl.size < max(50, MIN_PLANE_FRACTION * idx.size):
            break
        on = np.zeros(gv.size, dtype=bool)
        on[free[inl]] = True
        on = on.reshape(gv.shape)
        # only where the surface turns like the plane: an object's face crossing it (a lid leaning on a
        # riser) is not part of the support
        q = flat[free[inl]]
        centre = q.mean(axis=0)
        normal = _principal_axes(q - centre)[:, -1]
        on &= ~normal_ok | (np.abs(normals @ normal) >= PLANE_NORMAL_COS)
        # pieces of the plane after an opening: a face touching the support along a thin contact (a lid
        # leaning on a riser, in its plane) comes apart from it; the contact strip goes back to the support
        opened = binary_opening(on, structure=_DISK, border_value=1) & on  # (the border value grows a frame)
        n_pieces, pieces = _components(opened, right, down)
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
                    _extent(q) > SIZE_FACTOR * hi or (_extent(q) > typical and _runs_out(sel, on, border))):
                support |= on & binary_dilation(sel, structure=_DISK)
                removed = True
            else:
                others.append(sel)
        if removed:  # a support's other pieces that run out of the view: its ends beyond what stands on it
            for sel in others:
                if _runs_out(sel, on, border):
                    support |= on & binary_dilation(sel, structure=_DISK)
        tried |= on & ~support
        if removed:
            supports.append(support.copy())
            # near the plane and beside its removed pieces: the whole plane runs through other things too
            beside = binary_dilation(support & ~before, structure=_disk(CORNER_REACH))
            near.append(beside & (np.abs((P - centre) @ normal) < CORNER_MARGIN_M))
        planes += int(removed)
    # where two supports meet (a stair's nosing, a table's edge against a wall) the surface is neither
    # plane: pixels near two of them are support too, so that objects standing there come apart
    for k in range(1, len(supports)):
        supports[k] = supports[k] | (gv & (np.sum(near[: k + 1], axis=0) >= 2))
    # --- candidate segments at every depth of plane removal --------------------------------------------
    # (a plane removed late may take an object's face with it: a lid leaning on a stair's riser)
    levels = supports or [support]
    gi = np.minimum((np.arange(H) + s // 2) // s, g.shape[0] - 1)
    gj = np.minimum((np.arange(W) + s // 2) // s, g.shape[1] - 1)
    near_d = g[gi[:, None], gj[None, :]]
    near_jump = jump[gi[:, None], gj[None, :]]
    agree_depth = valid & (np.abs(d - near_d) < near_jump)

    def upsample(grid_mask):
        """Full-resolution pixels of a grid segment: their grid pixel is in it and their depth agrees."""
        return agree_depth & grid_mask[gi[:, None], gj[None, :]]

    segments, clusters = [], []
    for level, sup in enumerate(levels):
        n_seg, seg = _components(gv & ~sup, right, down)
        sizes = np.bincount(seg[seg >= 0], minlength=n_seg)
        for c in np.flatnonzero(sizes >= MIN_SEGMENT_GRID_PIXELS):
            base = seg == c
            for sel in (base, _with_attached(seg, c, sizes, g, ATTACH_SHARE * typical)):
                n = int(np.count_nonzero(sel)) * s * s
                # the same segment as at an earlier depth (a plane removed elsewhere), or as the segment without
                # what is attached to it
                if any(_same_segment(sel, o) for o in segments):
                    continue
                diag = _extent(P[sel], diagonal=True)
                segments.append(sel)
                clusters.append(Cluster(n, diag, (float(uu[sel].mean()), float(vv[sel].mean())),
                                        _fits(diag, lo, hi),
                                        level=level + 1 if supports else 0))
    # labels for pictures: every candidate, the deeper ones (smaller pieces) over the shallower
    final = np.full(gv.shape, -1, dtype=np.int64)
    for c in sorted(range(len(segments)), key=lambda c: clusters[c].level):
        final[segments[c]] = c
    near_seg = final[gi[:, None], gj[None, :]]
    labelled = agree_depth & (near_seg >= 0)
    labels[labelled] = near_seg[labelled]
    if not clusters:
        return Isolation(np.zeros(d.shape, dtype=bool), labels, (), None, planes,
                         "nothing left after removing planes and small pieces", stride=s)
    order, reason, hinted = _rank(clusters, segments, gi, gj, intrinsics, hint, lo, hi)
    return Isolation(upsample(segments[order[0]]), labels, tuple(clusters), order[0], planes, reason, order=tuple(order),
                     stride=s, hinted=tuple(hinted), segments=tuple(segments), _upsample=upsample)


def merged_candidate(isolation: Isolation, a: int, b: int, depth, intrinsics: Intrinsics,
                     category: str) -> tuple[Isolation, int] | None:
    """Candidates ``a`` and ``b`` of ``isolation`` as one more candidate, their union, for a caller whose verification
    rejected both (:func:`ancsh.learned.inference.predict.predict_depth`): an object cut in two by plane removal or a
    depth jump is fitted whole. ``(isolation with the union appended to its candidates, its index)``, or ``None``
    when the two do not touch in the image (within :data:`MERGE_REACH` grid pixels), overlap by
    :data:`MERGE_OVERLAP` or more of the smaller one (one holds the other: a candidate with its attached pieces),
    make a candidate there already (an IoU of :data:`SAME_SEGMENT_IOU`), or make one whose size does not fit
    ``category``.

    Parameters
    ----------
    isolation : Isolation
        From :func:`isolate_object` of ``depth``.
    a, b : int
        Candidate indices.
    depth : (H, W) float64
        The isolated image (metres).
    intrinsics : Intrinsics
    category : str
        As for :func:`isolate_object` (its ``diagonal_range``).
    """
    from scipy.ndimage import binary_dilation

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
    if any(_same_segment(union, o) for o in isolation.segments):
        return None
    mask = isolation.mask_of(a) | isolation.mask_of(b)
    vs, us = np.nonzero(mask)
    if len(vs) < 10:
        return None
    diag = _extent(backproject(depth, intrinsics, mask), diagonal=True)
    if not _fits(diag, *_size_range(category)):
        return None
    s = isolation.stride
    ca, cb = isolation.clusters[a], isolation.clusters[b]
    cluster = Cluster(int(np.count_nonzero(union)) * s * s, diag, (float(us.mean()), float(vs.mean())), True,
                      level=max(ca.level, cb.level))
    new = len(isolation.clusters)
    return replace(isolation, clusters=isolation.clusters + (cluster,), segments=isolation.segments + (union,),
                   order=isolation.order + (new,)), new


def _size_range(category: str) -> tuple[float, float]:
    """``(lo, hi)`` metres: the procedural category's ``diagonal_range``, 0.1..2 m for other names."""
    from .procedural import CATEGORY_INFO

    info = CATEGORY_INFO.get(category)
    return info.diagonal_range if info is not None else (0.1, 2.0)


def _fits(diagonal: float, lo: float, hi: float) -> bool:
    """Whether a candidate ``diagonal`` metres across fits the size range ``lo..hi`` (within :data:`SIZE_FACTOR`)."""
    return bool(lo / SIZE_FACTOR <= diagonal <= hi * SIZE_FACTOR)


def _same_segment(x: np.ndarray, y: np.ndarray) -> bool:
    """Whether two grid masks are one candidate: a like count (the cheap test), then an IoU of
    :data:`SAME_SEGMENT_IOU`."""
    nx, ny = np.count_nonzero(x), np.count_nonzero(y)
    return bool(min(nx, ny) >= SAME_SEGMENT_IOU * max(nx, ny)
                and np.count_nonzero(x & y) >= SAME_SEGMENT_IOU * np.count_nonzero(x | y))


def _with_attached(seg: np.ndarray, c: int, sizes: np.ndarray, g: np.ndarray, gap: float) -> np.ndarray:
    """Segment ``c`` of the component labels ``seg`` (-1 = none) with the smaller components that touch it in the
    image at a median depth step below ``gap`` metres (grid depths ``g``): a door ajar, a knob, a drawer front parted
    from the object by a depth jump. ``(h, w)`` bool; just segment ``c`` when nothing is attached."""
    sel = seg == c
    vs, us = np.nonzero(sel)
    win = (slice(max(0, vs.min() - 1), vs.max() + 2), slice(max(0, us.min() - 1), us.max() + 2))
    sw, gw = seg[win], g[win]
    ks, steps = [], []
    for a, b, da, db in ((sw[:, :-1], sw[:, 1:], gw[:, :-1], gw[:, 1:]), (sw[:-1, :], sw[1:, :], gw[:-1, :], gw[1:, :])):
        for x, y, dx, dy in ((a, b, da, db), (b, a, db, da)):
            touch = (x == c) & (y >= 0) & (y != c)
            ks.append(y[touch])
            steps.append(np.abs(dx[touch] - dy[touch]))
    ks, steps = np.concatenate(ks), np.concatenate(steps)
    if ks.size == 0:
        return sel
    order = np.argsort(ks, kind="stable")
    ks, steps = ks[order], steps[order]
    first = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    attached = [int(ks[i]) for i, group in zip(first, np.split(steps, first[1:]))
                if sizes[ks[i]] < sizes[c] and float(np.median(group)) < gap]
    return sel | np.isin(seg, attached) if attached else sel


def _runs_out(piece: np.ndarray, on: np.ndarray, border: np.ndarray) -> bool:
    """Whether a plane's ``piece`` runs out of the view: at least :data:`BORDER_PIXELS` of it, grown back
    :data:`BAND_END_PIXELS` grid pixels along the plane's inliers ``on`` (the opening eats the ends of a thin band: a
    stair's riser seen from above), lie on the view's ``border``."""
    from scipy.ndimage import binary_dilation

    vs, us = np.nonzero(piece)
    r = BAND_END_PIXELS
    win = (slice(max(0, vs.min() - r), vs.max() + r + 1), slice(max(0, us.min() - r), us.max() + r + 1))
    grown = binary_dilation(piece[win], iterations=r, mask=on[win])
    return np.count_nonzero(grown & border[win]) >= BORDER_PIXELS


def _view_border(gv: np.ndarray) -> np.ndarray:
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


def _disk(radius: int) -> np.ndarray:
    """A disk of ``radius`` grid pixels, as a structuring element."""
    yy, xx = np.mgrid[-radius:radius + 1, -radius:radius + 1]
    return yy ** 2 + xx ** 2 <= radius * radius + 1


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
    outline = m & ~binary_erosion(m, border_value=0)
    n = int(np.count_nonzero(outline))
    if n == 0:
        return False, float("nan")
    k = max(OUT_OF_VIEW_PIXELS, 2 * int(stride))
    edge = np.zeros(m.shape, dtype=bool)
    edge[:k, :] = edge[-k:, :] = True
    edge[:, :k] = edge[:, -k:] = True
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
    vs, us = np.nonzero(m)
    win = (slice(max(0, vs.min() - 2 * r), vs.max() + 2 * r + 1), slice(max(0, us.min() - 2 * r), us.max() + 2 * r + 1))
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


def _check_hint_inside(hint, W: int, H: int) -> None:
    """Refuse a hint pixel outside the image, or a hint box that does not overlap it (a hint is never ignored)."""
    if hint is None:
        return
    if hint.pixel is not None:
        u, v = hint.pixel
        if not (-0.5 <= u < W - 0.5 and -0.5 <= v < H - 0.5):
            raise ValueError(f"--pixel: ({u:g}, {v:g}) lies outside the {W}x{H} image")
    else:
        u0, v0, u1, v1 = hint.box
        if u1 < 0 or v1 < 0 or u0 > W - 1 or v0 > H - 1:
            raise ValueError(f"--box: ({u0:g}, {v0:g}, {u1:g}, {v1:g}) does not overlap the {W}x{H} image")


def _components(on: np.ndarray, right: np.ndarray, down: np.ndarray) -> tuple[int, np.ndarray]:
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
    if hint is not None and hint.pixel is not None:
        u, v = hint.pixel
        i = int(np.clip(round(v), 0, len(gi) - 1))
        j = int(np.clip(round(u), 0, len(gj) - 1))
        under = [c for c in order if segments[c][gi[i], gj[j]]]
        if under:  # the largest segment under the pixel whose size fits, else the smallest one
            under.sort(key=lambda c: (not clusters[c].fits_category,
                                      -clusters[c].pixels if clusters[c].fits_category else clusters[c].pixels))
            return under + [c for c in order if c not in under], f"under the hint pixel ({u:g}, {v:g})", under
        dist = [min(np.hypot(*(np.argwhere(segments[c]) - [gi[i], gj[j]]).T)) for c in every]
        first = int(np.argmin(dist))
        return [first] + [c for c in order if c != first], f"nearest the hint pixel ({u:g}, {v:g})", [first]
    if hint is not None:
        u0, v0, u1, v1 = hint.box
        rows = (gi >= gi[int(np.clip(v0, 0, len(gi) - 1))]) & (gi <= gi[int(np.clip(v1, 0, len(gi) - 1))])
        cols = (gj >= gj[int(np.clip(u0, 0, len(gj) - 1))]) & (gj <= gj[int(np.clip(u1, 0, len(gj) - 1))])
        r = np.unique(gi[rows])
        q = np.unique(gj[cols])
        inside = [np.count_nonzero(segments[c][np.ix_(r, q)]) / max(np.count_nonzero(segments[c]), 1) for c in every]
        counts = [np.count_nonzero(segments[c][np.ix_(r, q)]) for c in every]
        if max(counts) > 0:  # mostly inside the box, then most pixels in it
            ranked = sorted((c for c in every if counts[c] > 0), key=lambda c: (-round(inside[c], 1), -counts[c]))
            return ranked + [c for c in order if c not in ranked], "most pixels in the hint box", ranked
    if clusters[order[0]].fits_category:
        return order, f"size fits the category ({lo}..{hi} m, x{SIZE_FACTOR}) and nearest the image centre", []
    return order, "no segment fits the category's size: the closest in size", []


def _ransac_plane(points: np.ndarray, thresh: float, rng) -> tuple[np.ndarray, float]:
    """The plane ``n . x + e = 0`` (unit ``n``) through three of ``points`` (N, 3) with the most points within
    ``thresh`` metres, of :data:`RANSAC_ITERATIONS` random triples (all scored at once)."""
    triples = points[rng.integers(0, len(points), (RANSAC_ITERATIONS, 3))]
    n = np.cross(triples[:, 1] - triples[:, 0], triples[:, 2] - triples[:, 0])
    length = np.linalg.norm(n, axis=1)
    good = length > 1e-12
    if not good.any():
        return np.array([0.0, 0.0, 1.0]), -float(points[0, 2])
    n = n[good] / length[good, None]
    e = -np.einsum("ij,ij->i", n, triples[good, 0])
    counts = np.count_nonzero(np.abs(points @ n.T + e) < thresh, axis=0)
    best = int(np.argmax(counts))
    return n[best], float(e[best])


def _refine_plane(points: np.ndarray, inliers: np.ndarray, thresh: float, rounds: int = 3) -> np.ndarray:
    """Least-squares refits of a RANSAC plane to its inliers (stable against the random sample)."""
    for _ in range(rounds):
        if inliers.size < 3:
            break
        p = points[inliers]
        c = p.mean(axis=0)
        normal = _principal_axes(p - c)[:, -1]
        new = np.flatnonzero(np.abs((points - c) @ normal) < thresh)
        if np.array_equal(new, inliers):
            break
        inliers = new
    return inliers


def _extent(points: np.ndarray, *, diagonal: bool = False) -> float:
    """Largest robust extent (2nd-98th percentile along principal axes) or the diagonal of those extents."""
    p = points - points.mean(axis=0)
    p = p[:: max(1, len(p) // 2000)]
    q = np.sort(p @ _principal_axes(p), axis=0)
    n = len(q) - 1
    ext = q[int(round(0.98 * n))] - q[int(round(0.02 * n))]
    return float(np.linalg.norm(ext)) if diagonal else float(ext.max())


def _principal_axes(centred: np.ndarray) -> np.ndarray:
    """(3, 3) principal axes (columns, largest variance first) of centred points, from their 3x3 scatter."""
    _, vecs = np.linalg.eigh(centred.T @ centred)
    return vecs[:, ::-1]
