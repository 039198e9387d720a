"""Hinged doors and lids for the box-shaped categories (oven, washing machine, microwave, safe).

A door is a slab on a revolute hinge along one edge of a rectangle on the body's front face
(or, for a top lid, on its top face). Conventions (:mod:`ancsh.data.conventions`): state 0 is
closed, a positive state opens the door outwards, the door lies in front of (or on top of)
the body at rest. The hinge edges and their joint axes, in the base frame (+y up, +z front,
+x right):

=============  ========================================  ======  ==================================
hinge          hinge line                                axis    positive state moves
=============  ========================================  ======  ==================================
``left``       the door's left (-x) vertical edge        ``-y``  the right edge towards +z
``right``      the door's right (+x) vertical edge       ``+y``  the left edge towards +z
``bottom``     the door's bottom horizontal edge         ``+x``  the top edge towards +z (and down)
``top``        a lid's back edge, on the top face        ``-x``  the front edge up (+y)
``top_left``   a lid's left (-x) edge, on the top face   ``+z``  the right edge up (+y)
``top_right``  a lid's right (+x) edge, on the top face  ``-z``  the left edge up (+y)
=============  ========================================  ======  ==================================

The three ``top*`` hinges are lids (:attr:`DoorFrame.is_lid`): their door coordinates lie on the top face.

The child frame has its origin on the hinge line and the base's axes at state 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ...geometry.transforms import SE3
from ...model.articulated import Joint
from . import _mesh as m
from .registry import REVOLUTE

if TYPE_CHECKING:  # (imported where a mesh is made: not at import, it takes a second)
    import trimesh

HINGES = ("left", "right", "bottom", "top", "top_left", "top_right")

_AXES = {
    "left": np.array([0.0, -1.0, 0.0]),
    "right": np.array([0.0, 1.0, 0.0]),
    "bottom": np.array([1.0, 0.0, 0.0]),
    "top": np.array([-1.0, 0.0, 0.0]),
    "top_left": np.array([0.0, 0.0, 1.0]),
    "top_right": np.array([0.0, 0.0, -1.0]),
}


@dataclass(frozen=True)
class DoorFrame:
    """Where a door sits on the body and how it hinges (metres, base frame).

    Attributes
    ----------
    x0, x1 : float
        The door's left and right edges.
    a0, a1 : float
        Its lower and upper edges along the face: ``y`` on the front face; for a lid (``top*``)
        ``z`` (back edge ``a0``, front edge ``a1``).
    face : float
        The face plane: ``z`` of the front face, or ``y`` of the top face for a lid.
    thickness : float
        Door thickness (metres).
    hinge : str
        One of :data:`HINGES`.
    inset : bool
        The door sits inside the opening, its outer face flush with the body's face
        (otherwise it stands on the face, outside the body).
    """

    x0: float
    x1: float
    a0: float
    a1: float
    face: float
    thickness: float
    hinge: str
    inset: bool = False

    def __post_init__(self):
        if self.hinge not in HINGES:
            raise ValueError(f"hinge: expected one of {HINGES}, got {self.hinge!r}")
        if not (self.x1 > self.x0 and self.a1 > self.a0 and self.thickness > 0):
            raise ValueError(f"door frame: expected x1 > x0, a1 > a0, thickness > 0, got {self}")

    @property
    def is_lid(self) -> bool:
        """The door lies on the top face (hinges ``top``, ``top_left``, ``top_right``)."""
        return self.hinge.startswith("top")

    @property
    def width(self) -> float:
        return self.x1 - self.x0

    @property
    def length(self) -> float:
        """Extent along the face's second axis (height of a front door, depth of a lid)."""
        return self.a1 - self.a0

    @property
    def pivot(self) -> np.ndarray:
        """(3,) a point on the hinge line, on the face plane (metres, base frame)."""
        xc, ac = (self.x0 + self.x1) / 2, (self.a0 + self.a1) / 2
        return {
            "left": np.array([self.x0, ac, self.face]),
            "right": np.array([self.x1, ac, self.face]),
            "bottom": np.array([xc, self.a0, self.face]),
            "top": np.array([xc, self.face, self.a0]),
            "top_left": np.array([self.x0, self.face, ac]),
            "top_right": np.array([self.x1, self.face, ac]),
        }[self.hinge]

    def to_child(self, lo, hi) -> tuple:
        """Corners (3,), (3,) of a box given in door coordinates, in the child frame.

        Door coordinates: ``u`` along the width from the left edge, ``v`` along the length from
        the lower (lid: back) edge, ``w`` outwards from the face (``w`` in ``[0, thickness]`` is
        the slab, outside the face, or inside it for an ``inset`` door shifted by -thickness).
        """
        lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        shift = -self.thickness if self.inset else 0.0
        corners = []
        for u, v, w in ((lo[0], lo[1], lo[2] + shift), (hi[0], hi[1], hi[2] + shift)):
            x, a = self.x0 + u, self.a0 + v
            p = np.array([x, self.face + w, a]) if self.is_lid else np.array([x, a, self.face + w])
            corners.append(p - self.pivot)
        c = np.array(corners)
        return c.min(axis=0), c.max(axis=0)

    def box(self, lo, hi) -> trimesh.Trimesh:
        """A box given in door coordinates (see :meth:`to_child`), in the child frame."""
        return m.box_between(*self.to_child(lo, hi))

    def place(self, mesh: trimesh.Trimesh, u: float, v: float, w: float) -> trimesh.Trimesh:
        """Move a piece built facing +z (front door) to door coordinates ``(u, v, w)``.

        For a lid the piece is turned so that its +z faces up (+y) (and its +y the back).
        """
        lo, _ = self.to_child([u, v, w], [u, v, w])
        if self.is_lid:
            mesh = m.rotated(mesh, [1.0, 0.0, 0.0], -np.pi / 2)
        return m.transformed(mesh, translation=lo)

    def joint(self, name: str, upper: float) -> Joint:
        """The revolute joint base -> door, closed at 0, opening to ``upper`` (rad)."""
        pivot = self.pivot
        return Joint(name, REVOLUTE, "base", "door", axis=_AXES[self.hinge], pivot=pivot, lower=0.0,
                     upper=float(upper), rest=0.0, origin=SE3(None, pivot))


def cavity_body(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float, opening, cavity_depth: float) -> list:
    """A box body ``[x0, x1] x [y0, y1] x [z0, z1]`` with a cavity open at the front face ``z1``.

    Parameters
    ----------
    opening : (float, float, float, float)
        The cavity's ``(x_lo, x_hi, y_lo, y_hi)`` on the front face, strictly inside it (metres).
    cavity_depth : float
        How deep the cavity goes behind the front face (metres), less than ``z1 - z0``.

    Returns
    -------
    list of trimesh.Trimesh
        Back block, left and right walls, floor and roof (closed boxes).
    """
    cx0, cx1, cy0, cy1 = opening
    if not (x0 < cx0 < cx1 < x1 and y0 < cy0 < cy1 < y1 and 0 < cavity_depth < z1 - z0):
        raise ValueError(f"opening: {opening} (depth {cavity_depth}) must lie inside the body's front face and depth")
    zc = z1 - cavity_depth
    return [
        m.box_between([x0, y0, z0], [x1, y1, zc]),  # back block
        m.box_between([x0, y0, zc], [cx0, y1, z1]),  # left wall
        m.box_between([cx1, y0, zc], [x1, y1, z1]),  # right wall
        m.box_between([cx0, y0, zc], [cx1, cy0, z1]),  # floor
        m.box_between([cx0, cy1, zc], [cx1, y1, z1]),  # roof
    ]


def vertical_bar(length: float, radius: float, standoff: float) -> list:
    """A vertical bar handle on two posts, standing on the plane z = 0 towards +z, centred at the origin."""
    return [m.rotated(p, [0.0, 0.0, 1.0], np.pi / 2) for p in m.bar_handle(length, radius, standoff)]


def knob(radius: float, length: float) -> trimesh.Trimesh:
    """A round knob (or dial) on the plane z = 0, protruding ``length`` towards +z."""
    return m.along(m.cylinder(radius, length, 20), "z", (0.0, 0.0, length / 2))


def spoke_wheel(radius: float, rng: np.random.Generator) -> list:
    """A safe's handle: a hub with 3-5 spokes, on the plane z = 0 towards +z."""
    hub_t = radius * rng.uniform(0.25, 0.45)
    pieces = [knob(radius * 0.3, hub_t)]
    n = int(rng.integers(3, 6))
    spoke_r = radius * rng.uniform(0.06, 0.1)
    for k in range(n):
        spoke = m.along(m.cylinder(spoke_r, radius, 10), "x", (radius / 2, 0.0, hub_t * 0.6))
        pieces.append(m.rotated(spoke, [0.0, 0.0, 1.0], 2 * np.pi * k / n + np.pi / 2))
    return pieces
