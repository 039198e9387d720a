"""Closed mesh pieces for the procedural categories (boxes, prisms, rings, cylinders).

Every function returns a closed, outward-oriented ``trimesh.Trimesh`` in metres. A part's
mesh is the concatenation of several such pieces (no boolean unions needed).

2D outlines are ``(N, 2)`` counter-clockwise loops that are star-shaped around the origin;
:func:`outline_superellipse` and :func:`outline_rounded_rect` sample them at the same
``N`` polar parameters, so an outer and an inner outline can be joined into a ring.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ...geometry.rotations import axis_angle_matrix

if TYPE_CHECKING:  # (imported where a mesh is made: not at import, it takes a second)
    import trimesh


def box(extents, center=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    """Axis-aligned box of ``extents`` (3,) centred at ``center`` (3,)."""
    import trimesh

    T = np.eye(4)
    T[:3, 3] = center
    return trimesh.creation.box(extents=np.asarray(extents, dtype=np.float64), transform=T)


def box_between(lo, hi) -> trimesh.Trimesh:
    """Axis-aligned box spanning the corners ``lo`` (3,) and ``hi`` (3,)."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    return box(hi - lo, (lo + hi) / 2)


def outline_superellipse(a: float, b: float, exponent: float = 2.0, n: int = 48) -> np.ndarray:
    """Superellipse ``|x/a|^e + |y/b|^e = 1`` sampled at ``n`` parameters, ``(n, 2)`` ccw.

    ``exponent`` 2 is an ellipse, larger values approach a rectangle.
    """
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False) + np.pi / n
    c, s = np.cos(t), np.sin(t)
    x = a * np.sign(c) * np.abs(c) ** (2.0 / exponent)
    y = b * np.sign(s) * np.abs(s) ** (2.0 / exponent)
    return np.stack([x, y], axis=1)


def outline_rounded_rect(width: float, height: float, radius: float, n: int = 48, center=(0.0, 0.0)) -> np.ndarray:
    """Rounded rectangle centred at ``center`` (2,), sampled along ``n`` polar rays from the
    origin (which must lie inside it), ``(n, 2)`` ccw."""
    radius = min(radius, 0.499 * min(width, height))
    center = np.asarray(center, dtype=np.float64)
    if abs(center[0]) >= width / 2 - radius / 2 or abs(center[1]) >= height / 2 - radius / 2:
        raise ValueError(f"center: {center.tolist()} must lie well inside the {width:.3g} x {height:.3g} rectangle")
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False) + np.pi / n
    d = np.stack([np.cos(t), np.sin(t)], axis=1)
    hx, hy = width / 2, height / 2
    # Distance along each ray to the rounded rectangle (convex: bisection on the inside test).
    lo, hi = np.zeros(n), np.full(n, np.hypot(hx + abs(center[0]), hy + abs(center[1])))
    for _ in range(40):
        mid = (lo + hi) / 2
        p = d * mid[:, None] - center
        q = np.maximum(np.abs(p) - np.array([hx - radius, hy - radius]), 0.0)
        inside = np.linalg.norm(q, axis=1) <= radius
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    return d * lo[:, None]


def taper(outline: np.ndarray, k: float) -> np.ndarray:
    """Scale ``x`` by ``1 + k * y / max|y|``: wider at the top for ``k > 0`` (aviator-like)."""
    ymax = np.abs(outline[:, 1]).max()
    out = outline.copy()
    out[:, 0] *= 1.0 + k * outline[:, 1] / ymax
    return out


def prism(outline, depth: float) -> trimesh.Trimesh:
    """Extrude a star-shaped ccw ``outline`` (N, 2) along z over ``[-depth/2, depth/2]``."""
    return ring_prism(outline, None, depth)


def ring_prism(outer, inner, depth: float) -> trimesh.Trimesh:
    """Closed extrusion along z of the region between ``outer`` and ``inner`` (both (N, 2), ccw,
    sampled at matching parameters); ``inner=None`` gives a solid prism (fan-capped)."""
    import trimesh

    outer = np.asarray(outer, dtype=np.float64)
    n = len(outer)
    z0, z1 = -depth / 2, depth / 2
    idx = np.arange(n)
    nxt = (idx + 1) % n
    verts = [np.c_[outer, np.full(n, z0)], np.c_[outer, np.full(n, z1)]]
    # outer side walls (outward for ccw outline)
    faces = [np.c_[idx, nxt, n + nxt], np.c_[idx, n + nxt, n + idx]]
    if inner is None:
        c0, c1 = 2 * n, 2 * n + 1
        verts.append(np.array([[0.0, 0.0, z0], [0.0, 0.0, z1]]))
        faces += [np.c_[np.full(n, c0), nxt, idx], np.c_[np.full(n, c1), n + idx, n + nxt]]
    else:
        inner = np.asarray(inner, dtype=np.float64)
        if inner.shape != outer.shape:
            raise ValueError(f"inner: expected shape {outer.shape} matching outer, got {inner.shape}")
        i0, i1 = 2 * n, 3 * n
        verts += [np.c_[inner, np.full(n, z0)], np.c_[inner, np.full(n, z1)]]
        faces += [
            np.c_[i0 + idx, i1 + nxt, i0 + nxt],  # inner walls face the hole
            np.c_[i0 + idx, i1 + idx, i1 + nxt],
            np.c_[idx, i0 + nxt, nxt],  # bottom cap (faces -z)
            np.c_[idx, i0 + idx, i0 + nxt],
            np.c_[n + idx, n + nxt, i1 + nxt],  # top cap (faces +z)
            np.c_[n + idx, i1 + nxt, i1 + idx],
        ]
    return trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=False)


def cylinder(radius: float, length: float, n: int = 24) -> trimesh.Trimesh:
    """Cylinder along z, centred at the origin."""
    return prism(outline_superellipse(radius, radius, 2.0, n), length)


def feet(radius: float, height: float, x: float, z: float, sections: int = 12) -> list:
    """Four vertical cylinders standing on y = 0 at ``(+-x, +-z)``."""
    foot = cylinder(radius, height, sections)
    return [along(foot, "y", (sx * x, height / 2, sz * z)) for sx in (-1, 1) for sz in (-1, 1)]


def bar_handle(length: float, radius: float, standoff: float) -> list:
    """A bar along x on two posts, standing on the plane z = 0 (centred at the origin) towards +z."""
    bar = along(cylinder(radius, length), "x", (0.0, 0.0, standoff + radius))
    post = cylinder(radius * 0.8, standoff, 12)
    return [bar] + [along(post, "z", (sx * (length / 2 - radius), 0.0, standoff / 2)) for sx in (-1, 1)]


def transformed(mesh: trimesh.Trimesh, *, rotation=None, translation=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    """A copy of ``mesh`` mapped by ``x -> rotation @ x + translation``."""
    T = np.eye(4)
    if rotation is not None:
        T[:3, :3] = rotation
    T[:3, 3] = translation
    out = mesh.copy()
    out.apply_transform(T)
    return out


def along(mesh: trimesh.Trimesh, axis: str, center=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    """Re-orient a z-extruded piece so its extrusion runs along ``axis`` ('x', 'y' or 'z'), then move it."""
    R = {
        "z": np.eye(3),
        "x": axis_angle_matrix(np.array([0.0, 1.0, 0.0]), np.pi / 2),
        "y": axis_angle_matrix(np.array([1.0, 0.0, 0.0]), -np.pi / 2),
    }[axis]
    return transformed(mesh, rotation=R, translation=center)


def rotated(mesh: trimesh.Trimesh, axis, angle: float, center=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    """Rotate ``mesh`` by ``angle`` (rad) about the line through ``center`` along ``axis``."""
    R = axis_angle_matrix(np.asarray(axis, dtype=np.float64), angle)
    c = np.asarray(center, dtype=np.float64)
    return transformed(mesh, rotation=R, translation=c - R @ c)


def concat(pieces) -> trimesh.Trimesh:
    """One mesh made of several closed pieces (vertices not merged)."""
    import trimesh

    pieces = list(pieces)
    if not pieces:
        raise ValueError("pieces: need at least one mesh piece")
    return trimesh.util.concatenate(pieces)
