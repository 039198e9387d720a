"""Oriented 3D boxes.

Box IoU (exact, by convex-polytope intersection) lives in :mod:`ancsh.geometry.box_iou`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._checks import as_array, as_points, as_rotation

# Sign pattern of the 8 corners, in the box frame (unit half extents).
_CORNER_SIGNS = np.array(
    [[sx, sy, sz] for sx in (-1.0, 1.0) for sy in (-1.0, 1.0) for sz in (-1.0, 1.0)]
)


@dataclass(frozen=True)
class OrientedBox:
    """A box with centre, orientation and full side lengths.

    Attributes
    ----------
    center : (3,) float64
        Box centre in the box's reference frame (e.g. camera, metres).
    rotation : (3, 3) float64
        Columns are the box axes expressed in the reference frame.
    extents : (3,) float64
        Full side lengths along the box axes, ``>= 0``.
    """

    center: np.ndarray
    rotation: np.ndarray
    extents: np.ndarray

    def __post_init__(self):
        c = as_array(self.center, "center", (3,))
        R = as_rotation(self.rotation, "rotation", tol=1e-5)
        e = as_array(self.extents, "extents", (3,))
        if np.any(e < 0):
            raise ValueError(f"extents: must be non-negative, got {e}")
        for name, value in (("center", c), ("rotation", R), ("extents", e)):
            value = value.copy()
            value.flags.writeable = False  # frozen means frozen, as in Sim3
            object.__setattr__(self, name, value)

    @classmethod
    def unchecked(cls, center, rotation, extents) -> "OrientedBox":
        """Build without validation, for hot loops whose values are valid by construction (a fit's boxes from its
        part poses): ``center`` ``(3,)``, ``rotation`` ``(3, 3)`` a rotation, ``extents`` ``(3,)`` non-negative; not
        checked. The arrays are copied and made read-only, as by the validating constructor."""
        self = object.__new__(cls)
        for name, value in (("center", center), ("rotation", rotation), ("extents", extents)):
            value = np.array(value, dtype=np.float64)
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        return self

    @classmethod
    def axis_aligned(cls, lower, upper) -> "OrientedBox":
        lo = as_array(lower, "lower", (3,))
        hi = as_array(upper, "upper", (3,))
        if np.any(hi < lo):
            raise ValueError("upper: must be >= lower in every coordinate")
        return cls(0.5 * (lo + hi), np.eye(3), hi - lo)

    @classmethod
    def tight_axis_aligned(cls, points) -> "OrientedBox":
        """Tight axis-aligned box of ``(N, 3)`` points (N >= 1)."""
        p = as_points(points, "points", min_points=1)
        return cls.axis_aligned(p.min(axis=0), p.max(axis=0))

    def corners(self) -> np.ndarray:
        """The 8 corners, ``(8, 3)``, in the reference frame."""
        return self.center + (_CORNER_SIGNS * (0.5 * self.extents)) @ self.rotation.T

    @property
    def volume(self) -> float:
        return float(np.prod(self.extents))

    @property
    def diagonal(self) -> float:
        return float(np.linalg.norm(self.extents))

    def contains(self, points, tol: float = 0.0) -> np.ndarray:
        """Boolean mask ``(N,)`` of points inside the box (with tolerance ``tol``)."""
        p = as_points(points, "points")
        local = (p - self.center) @ self.rotation
        return np.all(np.abs(local) <= 0.5 * self.extents + tol, axis=1)

    def transformed(self, T) -> "OrientedBox":
        """The box mapped by a :class:`~ancsh.geometry.transforms.Sim3` ``T``."""
        return OrientedBox(T.apply(self.center), T.rotation @ self.rotation, self.extents * T.scale)


def unit_diagonal(extents) -> np.ndarray:
    """Box side lengths ``(..., 3)`` scaled so that each box's diagonal is 1 (what every NPCS box has by
    definition); an all-zero row stays zero."""
    extents = np.asarray(extents, dtype=np.float64)
    norms = np.linalg.norm(extents, axis=-1, keepdims=True)
    return np.divide(extents, norms, out=extents.copy(), where=norms > 0)
