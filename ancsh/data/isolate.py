"""Find the object in a depth image without a mask: remove supporting planes, cluster, choose.

:func:`isolate_object` back-projects the valid pixels, removes large planes (tables, floors,
walls: open3d ``segment_plane``, kept only when the plane is wider than any object of the
category), clusters what is left with scikit-learn's ``DBSCAN`` and chooses one cluster:

- with an :class:`ObjectHint`: the cluster under the pixel ``(u, v)``, or with most points in the box;
- without one: among the clusters whose size fits the category's ``diagonal_range``, the one
  nearest the image centre (ties: more points); when none fits, the one whose size is closest.

The result is a pixel mask plus what was found (:class:`Isolation`), so a picture can show the
choice. A mask given by the user always wins over this (``ancsh predict --mask``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .render import Intrinsics, valid_depth_pixels

__all__ = ["ObjectHint", "Cluster", "Isolation", "isolate_object", "parse_hint"]

#: Clusters and planes are found on at most this many points (the rest follow their nearest one).
MAX_WORK_POINTS = 20000
#: Size factor: a cluster fits the category when its diagonal is in ``[lo / f, hi * f]``.
SIZE_FACTOR = 1.5


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
    """One candidate object: its pixel count, size (diagonal, metres) and image centroid ``(u, v)``."""

    pixels: int
    diagonal: float
    centroid_uv: tuple
    fits_category: bool

    def to_dict(self) -> dict:
        return {"pixels": self.pixels, "diagonal_m": self.diagonal, "centroid_uv": list(self.centroid_uv),
                "fits_category": self.fits_category}


@dataclass(frozen=True)
class Isolation:
    """What :func:`isolate_object` found.

    Attributes
    ----------
    mask : (H, W) bool
        Pixels of the chosen object (all ``False`` when nothing was found).
    labels : (H, W) int64
        ``-2`` no depth, ``-1`` removed (plane or DBSCAN noise), ``c >= 0`` cluster ``c``.
    clusters : tuple of Cluster
    chosen : int or None
        Index of the chosen cluster.
    planes : int
        Supporting planes removed.
    reason : str
        Why that cluster was chosen.
    """

    mask: np.ndarray
    labels: np.ndarray
    clusters: tuple = ()
    chosen: int | None = None
    planes: int = 0
    reason: str = ""

    def summary(self) -> str:
        if self.chosen is None:
            return f"isolation: no object found ({self.reason})"
        c = self.clusters[self.chosen]
        return (f"isolation: {self.planes} plane(s) removed, {len(self.clusters)} cluster(s); chose cluster "
                f"{self.chosen} ({c.pixels} pixels, {c.diagonal:.2f} m across): {self.reason}")

    def to_dict(self) -> dict:
        return {"planes_removed": self.planes, "clusters": [c.to_dict() for c in self.clusters], "chosen": self.chosen,
                "reason": self.reason}


def isolate_object(depth, intrinsics: Intrinsics, category: str, *, hint: ObjectHint | None = None,
                   max_depth: float | None = None, rng=0) -> Isolation:
    """Mask of the object of ``category`` in a depth image (see the module docstring).

    Parameters
    ----------
    depth : (H, W) float64
        Metres, 0 = no measurement.
    intrinsics : Intrinsics
    category : str
        A procedural category (its ``diagonal_range`` sizes the planes, clusters and the choice);
        other names use 0.1..2 m.
    hint : ObjectHint, optional
    max_depth : float, optional
        Metres; deeper pixels are ignored.
    rng : numpy.random.Generator or int
        Subsampling and plane RANSAC seed.
    """
    import open3d as o3d
    from sklearn.cluster import DBSCAN
    from sklearn.neighbors import NearestNeighbors

    from ..geometry._checks import check_generator
    from .procedural import CATEGORY_INFO

    rng = check_generator(rng)
    info = CATEGORY_INFO.get(category)
    lo, hi = info.diagonal_range if info is not None else (0.1, 2.0)
    d, valid = valid_depth_pixels(depth, intrinsics)
    if max_depth is not None:
        valid &= d <= max_depth
    labels = np.full(d.shape, -2, dtype=np.int64)
    vs, us = np.nonzero(valid)
    if us.size < 10:
        return Isolation(np.zeros(d.shape, dtype=bool), labels, reason=f"{us.size} valid pixels")
    z = d[vs, us]
    pts = np.stack([(us - intrinsics.cx) / intrinsics.fx * z, (vs - intrinsics.cy) / intrinsics.fy * z, z], axis=1)
    work = rng.choice(us.size, size=min(us.size, MAX_WORK_POINTS), replace=False)
    wp = pts[work]
    keep = np.ones(len(wp), dtype=bool)
    # --- supporting planes: wider than any object of the category ---------------------------------
    planes = 0
    thresh = max(0.01, 0.02 * lo)
    for _ in range(3):
        idx = np.flatnonzero(keep)
        if idx.size < 50:
            break
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(wp[idx]))
        o3d.utility.random.seed(int(rng.integers(2**31)))
        _, inl = pc.segment_plane(distance_threshold=thresh, ransac_n=3, num_iterations=300)
        inl = _refine_plane(wp[idx], np.asarray(inl, dtype=np.int64), thresh)
        if inl.size < 0.1 * idx.size or inl.size < 50:
            break
        if _extent(wp[idx[inl]]) <= SIZE_FACTOR * hi:
            break  # a face of the object, not a support
        keep[idx[inl]] = False
        planes += 1
    rest = np.flatnonzero(keep)
    wlab = np.full(len(wp), -1, dtype=np.int64)
    if rest.size >= 10:
        nn = NearestNeighbors(n_neighbors=min(5, rest.size)).fit(wp[rest])
        spacing = float(np.median(nn.kneighbors(wp[rest])[0][:, -1]))
        eps = max(3.0 * spacing, 0.02 * lo, 0.005)
        wlab[rest] = DBSCAN(eps=eps, min_samples=5).fit_predict(wp[rest])
    # every pixel takes the label of its nearest work point (planes/noise: -1)
    nn = NearestNeighbors(n_neighbors=1).fit(wp)
    near = nn.kneighbors(pts, return_distance=False)[:, 0]
    plab = wlab[near]
    labels[vs, us] = plab
    clusters = []
    for c in range(int(plab.max()) + 1 if plab.size else 0):
        sel = plab == c
        if np.count_nonzero(sel) < 20:
            labels[vs[sel], us[sel]] = -1
            clusters.append(Cluster(int(np.count_nonzero(sel)), 0.0, (float("nan"), float("nan")), False))
            continue
        diag = _extent(pts[sel], diagonal=True)
        clusters.append(Cluster(int(np.count_nonzero(sel)), diag, (float(us[sel].mean()), float(vs[sel].mean())),
                                bool(lo / SIZE_FACTOR <= diag <= hi * SIZE_FACTOR)))
    usable = [c for c, cl in enumerate(clusters) if cl.pixels >= 20]
    if not usable:
        return Isolation(np.zeros(d.shape, dtype=bool), labels, tuple(clusters), None, planes,
                         "nothing left after removing planes and noise")
    chosen, reason = _choose(clusters, usable, labels, intrinsics, hint, lo, hi)
    return Isolation(labels == chosen, labels, tuple(clusters), chosen, planes, reason)


def _choose(clusters, usable, labels, intr, hint, lo, hi):
    if hint is not None and hint.pixel is not None:
        u, v = hint.pixel
        vv, uu = np.nonzero(labels >= 0)
        k = int(np.argmin((uu - u) ** 2 + (vv - v) ** 2))
        return int(labels[vv[k], uu[k]]), f"under the hint pixel ({u:g}, {v:g})"
    if hint is not None:
        u0, v0, u1, v1 = hint.box
        counts = [np.count_nonzero(labels[int(max(v0, 0)):int(v1) + 1, int(max(u0, 0)):int(u1) + 1] == c) for c in usable]
        if max(counts) > 0:
            return usable[int(np.argmax(counts))], "most pixels in the hint box"
    fit = [c for c in usable if clusters[c].fits_category]
    centre = np.array([(intr.width - 1) / 2.0, (intr.height - 1) / 2.0])
    if fit:
        dist = [np.linalg.norm(np.asarray(clusters[c].centroid_uv) - centre) / max(intr.width, intr.height) for c in fit]
        order = sorted(range(len(fit)), key=lambda i: (round(dist[i], 2), -clusters[fit[i]].pixels))
        return fit[order[0]], f"size fits the category ({lo}..{hi} m, x{SIZE_FACTOR}) and nearest the image centre"
    mid = np.sqrt(lo * hi)
    best = min(usable, key=lambda c: abs(np.log(max(clusters[c].diagonal, 1e-6) / mid)))
    return best, "no cluster fits the category's size: the closest in size"


def _refine_plane(points: np.ndarray, inliers: np.ndarray, thresh: float, rounds: int = 3) -> np.ndarray:
    """Least-squares refits of a RANSAC plane to its inliers (stable against the random sample)."""
    for _ in range(rounds):
        if inliers.size < 3:
            break
        p = points[inliers]
        c = p.mean(axis=0)
        normal = np.linalg.svd(p - c, full_matrices=False)[2][-1]
        new = np.flatnonzero(np.abs((points - c) @ normal) < thresh)
        if np.array_equal(new, inliers):
            break
        inliers = new
    return inliers


def _extent(points: np.ndarray, *, diagonal: bool = False) -> float:
    """Largest robust extent (2nd-98th percentile along principal axes) or the diagonal of those extents."""
    p = points - points.mean(axis=0)
    _, _, Vt = np.linalg.svd(p[:: max(1, len(p) // 5000)], full_matrices=False)
    q = p @ Vt.T
    ext = np.percentile(q, 98, axis=0) - np.percentile(q, 2, axis=0)
    return float(np.linalg.norm(ext)) if diagonal else float(ext.max())
