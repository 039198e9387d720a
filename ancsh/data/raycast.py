"""Ray casting from the camera centre against triangle meshes, in numpy.

The renderer's second backend (:class:`~ancsh.data.render.ModelRenderer` with ``backend="numpy"``,
and ``"auto"`` where open3d is not installed, e.g. on a GPU machine with only torch): every ray
the renderer casts starts at the camera centre, so a ray is a point ``(a, b) = (d_x / d_z,
d_y / d_z)`` of the normalised image plane. The rays are bucketed in a uniform grid over that
plane; each triangle in front of the camera is tested (Moeller-Trumbore) only against the rays
of the cells its projected bounding box covers, and the nearest hit per ray is kept. Triangles
that reach to or behind the camera plane (rare: a wall beside the camera) are tested against
every ray. The result is the one open3d's ``RaycastingScene.cast_rays`` gives for rays from the
origin, up to float rounding on triangle edges (``tests/data/test_raycast.py`` compares them).
"""

from __future__ import annotations

import numpy as np

__all__ = ["CameraRayCaster"]

# Vertices nearer the camera plane than this (metres) make a triangle "crossing": tested by brute force.
_NEAR = 1e-6
# Candidate (triangle, ray) pairs handled at once (bounds the temporary arrays to ~100 MB).
_CHUNK = 1 << 20
# |det| below this (relative to the edge lengths) is a ray parallel to the triangle: no hit.
_PARALLEL = 1e-12


class CameraRayCaster:
    """Nearest hits of rays from the camera centre on a set of triangle meshes.

    Parameters
    ----------
    meshes : sequence of ((V_j, 3) float, (F_j, 3) int)
        Vertices in the camera frame (metres) and faces of each geometry; a geometry without
        faces is never hit. The hit's geometry index is the position in this sequence.
    """

    def __init__(self, meshes):
        tris, owner = [], []
        for j, (v, f) in enumerate(meshes):
            v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
            f = np.asarray(f, dtype=np.int64).reshape(-1, 3)
            if not len(f):
                continue
            if f.min() < 0 or f.max() >= len(v):
                raise ValueError(f"meshes[{j}]: a face indexes a vertex outside its {len(v)} vertices")
            tris.append(v[f])
            owner.append(np.full(len(f), j, dtype=np.int64))
        self._tri = np.concatenate(tris) if tris else np.empty((0, 3, 3))
        self._owner = np.concatenate(owner) if owner else np.empty(0, dtype=np.int64)
        z = self._tri[:, :, 2]
        self._front = np.all(z > _NEAR, axis=1)
        t = self._tri[self._front]
        ab = t[:, :, :2] / t[:, :, 2:3]  # (M, 3, 2): projected vertices on the plane z = 1
        self._lo, self._hi = ab.min(axis=1), ab.max(axis=1)
        # edge functions E_k(a, b) = alpha a + beta b + gamma, oriented so that inside = all three >= 0
        nxt = ab[:, [1, 2, 0]]
        e = nxt - ab
        edges = np.stack([-e[..., 1], e[..., 0], e[..., 1] * ab[..., 0] - e[..., 0] * ab[..., 1]], axis=-1)
        area = e[:, 0, 0] * e[:, 2, 1] - e[:, 0, 1] * e[:, 2, 0]  # twice the signed area (up to sign)
        self._edges = (edges * np.sign(-area)[:, None, None]).reshape(-1, 9)
        self._flat = np.abs(area) <= 1e-14 * np.maximum(np.abs(ab).max(axis=(1, 2)), 1.0) ** 2  # seen edge-on
        # plane n . x = c: the hit of the ray d is t = c / (n . d)
        n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        self._plane = np.concatenate([n, np.einsum("ij,ij->i", n, t[:, 0])[:, None]], axis=1)

    def cast(self, directions) -> tuple[np.ndarray, np.ndarray]:
        """Ray parameter and geometry of the nearest hit of each ray ``t * d`` (``t > 0``).

        Parameters
        ----------
        directions : (..., 3) float
            Ray directions in the camera frame; rays with ``d_z <= 0`` (at or behind the camera
            plane) hit only triangles that reach there.

        Returns
        -------
        t : (...) float64
            Ray parameter of the hit (the hit point is ``t * d``: for ``d = (x, y, 1)`` it is the
            depth), ``inf`` for no hit.
        geometry : (...) int64
            Index of the hit geometry in ``meshes``, ``-1`` for no hit.
        """
        d = np.asarray(directions, dtype=np.float64)
        if d.shape[-1:] != (3,):
            raise ValueError(f"directions: expected shape (..., 3), got {d.shape}")
        shape = d.shape[:-1]
        d = d.reshape(-1, 3)
        best_t = np.full(len(d), np.inf)
        best_tri = np.full(len(d), -1, dtype=np.int64)
        if len(d) and len(self._tri):
            front_tris = np.flatnonzero(self._front)
            if len(front_tris):
                self._cast_front(d, front_tris, best_t, best_tri)
            for tri in np.flatnonzero(~self._front):  # brute force: every ray against this triangle
                rays = np.arange(len(d))
                self._test(d, rays, np.full(len(rays), tri), best_t, best_tri)
        geometry = np.where(best_tri >= 0, self._owner[np.maximum(best_tri, 0)] if len(self._owner) else -1, -1)
        return best_t.reshape(shape), geometry.reshape(shape)

    def _cast_front(self, d, front_tris, best_t, best_tri) -> None:
        rays = np.flatnonzero(d[:, 2] > 0)
        if not len(rays):
            return
        ab = d[rays, :2] / d[rays, 2:3]
        lo, hi = ab.min(axis=0), ab.max(axis=0)
        span = np.maximum(hi - lo, 1e-12)
        cell = max(float(np.sqrt(span[0] * span[1] / len(rays))), float(span.max()) / 1024.0, 1e-12)
        n = np.minimum(np.floor(span / cell).astype(np.int64) + 1, 1 << 20)
        ij = np.minimum(np.floor((ab - lo) / cell).astype(np.int64), n - 1)
        cell_of_ray = ij[:, 1] * n[0] + ij[:, 0]
        order = np.argsort(cell_of_ray, kind="stable")
        starts = np.searchsorted(cell_of_ray[order], np.arange(n[0] * n[1] + 1))
        # each triangle's cell rectangle, clipped to the grid
        c0 = np.floor((self._lo - lo) / cell).astype(np.int64)
        c1 = np.floor((self._hi - lo) / cell).astype(np.int64)
        keep = np.all(c1 >= 0, axis=1) & np.all(c0 < n, axis=1) & ~self._flat
        c0, c1 = np.maximum(c0[keep], 0), np.minimum(c1[keep], n - 1)
        tris = np.flatnonzero(keep)  # among the front triangles
        widths = c1[:, 0] - c0[:, 0] + 1
        cells_per_tri = widths * (c1[:, 1] - c0[:, 1] + 1)
        # enumerate (triangle, cell) pairs, about _CHUNK cells at a time
        cum = np.cumsum(cells_per_tri)
        edges = np.searchsorted(cum, np.arange(1, cum[-1] // _CHUNK + 1) * _CHUNK, side="right") if len(cum) else []
        edges = np.unique(np.concatenate([[0], edges, [len(tris)]]).astype(np.int64))
        for first, last in zip(edges[:-1], edges[1:]):
            sl = slice(first, last)
            k = np.repeat(np.arange(first, last), cells_per_tri[sl])
            local = np.arange(len(k)) - np.repeat(np.cumsum(cells_per_tri[sl]) - cells_per_tri[sl], cells_per_tri[sl])
            cells = (c0[k, 1] + local // widths[k]) * n[0] + c0[k, 0] + local % widths[k]
            counts = starts[cells + 1] - starts[cells]
            pair_tri = np.repeat(tris[k], counts)
            offsets = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
            pair_ray = order[np.repeat(starts[cells], counts) + offsets]  # among ``rays``
            for s in range(0, len(pair_ray), _CHUNK):
                self._test_front(d, rays, ab, pair_ray[s:s + _CHUNK], pair_tri[s:s + _CHUNK], front_tris, best_t, best_tri)

    def _test_front(self, d, rays, ab, ray, tri, front_tris, best_t, best_tri) -> None:
        """Inside test by edge functions on the image plane, then the plane's ray parameter."""
        a, b = ab[ray, 0], ab[ray, 1]
        E = self._edges[tri]
        inside = ((E[:, 0] * a + E[:, 1] * b + E[:, 2] >= 0) & (E[:, 3] * a + E[:, 4] * b + E[:, 5] >= 0)
                  & (E[:, 6] * a + E[:, 7] * b + E[:, 8] >= 0))
        ray, tri = ray[inside], tri[inside]
        P = self._plane[tri]
        dr = d[rays[ray]]
        denom = np.einsum("ij,ij->i", P[:, :3], dr)
        t = P[:, 3] / np.where(denom != 0, denom, np.inf)
        hit = t > 0
        _keep_nearest(rays[ray[hit]], front_tris[tri[hit]], t[hit], best_t, best_tri)

    def _test(self, d, ray, tri, best_t, best_tri) -> None:
        """Moeller-Trumbore for rays from the origin (the triangles that reach the camera plane)."""
        if not len(ray):
            return
        A, B, C = (self._tri[tri, i] for i in range(3))
        e1, e2 = B - A, C - A
        dr = d[ray]
        p = np.cross(dr, e2)
        det = np.einsum("ij,ij->i", e1, p)
        scale = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1) * np.linalg.norm(dr, axis=1)
        ok = np.abs(det) > _PARALLEL * np.maximum(scale, 1e-300)
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = -A
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("ij,ij->i", dr, q) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        _keep_nearest(ray[hit], tri[hit], t[hit], best_t, best_tri)


def _keep_nearest(ray, tri, t, best_t, best_tri) -> None:
    """Write the nearest of the hits ``(ray, tri, t)`` of each ray into ``best_t`` / ``best_tri`` where nearer."""
    if len(ray):
        order = np.lexsort((t, ray))
        ray, tri, t = ray[order], tri[order], t[order]
        first = np.ones(len(ray), dtype=bool)
        first[1:] = ray[1:] != ray[:-1]
        ray, tri, t = ray[first], tri[first], t[first]
        better = t < best_t[ray]
        best_t[ray[better]] = t[better]
        best_tri[ray[better]] = tri[better]
