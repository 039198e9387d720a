"""Where the user says the object is: an :class:`ObjectHint` (a pixel or a box), read from the command line
(:func:`parse_hint`), checked against the image and turned into the candidates it points at (:func:`hinted_order`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ObjectHint", "check_hint_inside", "hinted_order", "parse_hint"]


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


def check_hint_inside(hint, W: int, H: int) -> None:
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


def hinted_order(hint: ObjectHint, order: list, clusters, segments, gi: np.ndarray, gj: np.ndarray) -> tuple | None:
    """The candidates in the order a hint gives: under the hint pixel (the largest whose size fits, else the smallest),
    or the nearest one; or mostly inside the hint box, then most pixels in it; then the others in ``order``.

    ``gi``, ``gj``: the grid row (column) of every image row (column). Returns ``(order, reason, hinted)`` as
    :func:`~ancsh.data.isolate.proposals.isolate_object` ranks, or ``None`` when no candidate has a pixel in the box."""
    every = list(range(len(clusters)))
    if hint.pixel is not None:
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
    else:
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
    return None
