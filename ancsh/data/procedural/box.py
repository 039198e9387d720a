"""Box: an open-topped body (base) and a lid on a revolute hinge along the body's top back edge.

Frame: body floor centre at the origin, +y up, +z towards the front (the side away from the
hinge), +x right. Joint state = the lid's opening angle: 0 closed (rest), 90 degrees upright,
180 degrees lying flat behind the box; the front edge rises as the state grows (axis ``-x``).

Styles (calibrated on the 13 PartNet-Mobility boxes, whose limits open 116-265 degrees, and on
the two real boxes of ``../shared/data/real_frames``):

==============  =====  =============  ============  =================  ===================  =============
style           share  width (m)      depth:width   height:width       lid                  opens (deg)
==============  =====  =============  ============  =================  ===================  =============
``tin``         25 %   0.10-0.30      0.45-0.90     0.12-0.40          cap with a rim       150-270
``pencil_case`` 20 %   0.17-0.30      0.25-0.50     0.10-0.25          shell, 30-50 % high  150-200
``shoe_box``    15 %   0.26-0.42      0.45-0.70     0.30-0.45          cap with a rim       110-200
``jewellery``   20 %   0.10-0.28      0.55-1.00     0.30-0.70          shell, 20-45 % high  95-180
``chest``       20 %   0.35-0.75      0.45-0.70     0.45-0.75          arched or flat       100-135
==============  =====  =============  ============  =================  ===================  =============

- A *cap* lid is a thin top sheet with a rim hanging over the body's walls (overhang 1-5 mm);
  its hinge is at the rim's lower back edge. A *shell* lid is an inverted tray of the body's
  footprint; its hinge is on the body's top back edge. Both hinges sit 0-6 mm behind the back
  face (barrels outside, 50 %).
- The body is hollow (floor and four walls, 1-25 mm thick by style) so an open lid shows the
  inside; jewellery boxes and chests may stand on feet; chests carry side handles and a front
  clasp, jewellery boxes and pencil cases a clasp (50 %).
"""

from __future__ import annotations

import numpy as np

from ...geometry.rotations import axis_angle_matrix
from ...geometry.transforms import SE3
from ...model.articulated import ArticulatedModel, Joint, Part
from ..conventions import convention
from . import _mesh as m
from .registry import REVOLUTE

INFO = convention("box")  # the category's one definition (ancsh.data.conventions)

#: style -> (probability, width range m, depth:width, height:width, lid kind, opening range deg)
STYLES = {
    "tin": (0.25, (0.10, 0.30), (0.45, 0.90), (0.12, 0.40), "cap", (150.0, 270.0)),
    "pencil_case": (0.20, (0.17, 0.30), (0.25, 0.50), (0.10, 0.25), "shell", (150.0, 200.0)),
    "shoe_box": (0.15, (0.26, 0.42), (0.45, 0.70), (0.30, 0.45), "cap", (110.0, 200.0)),
    "jewellery": (0.20, (0.10, 0.28), (0.55, 1.00), (0.30, 0.70), "shell", (95.0, 180.0)),
    "chest": (0.20, (0.35, 0.75), (0.45, 0.70), (0.45, 0.75), "shell", (100.0, 135.0)),
}
_WALL = {"tin": (0.001, 0.002), "pencil_case": (0.002, 0.005), "shoe_box": (0.002, 0.004),
         "jewellery": (0.005, 0.012), "chest": (0.012, 0.025)}


def _tray(x0, x1, y0, y1, z0, z1, wall, floor, *, open_up: bool) -> list:
    """A box with one open face (up: the floor at ``y0``; down: the top at ``y1``), walls ``wall`` thick."""
    yf0, yf1 = (y0, y0 + floor) if open_up else (y1 - floor, y1)
    return [
        m.box_between([x0, yf0, z0], [x1, yf1, z1]),
        m.box_between([x0, y0, z1 - wall], [x1, y1, z1]),  # front wall
        m.box_between([x0, y0, z0], [x1, y1, z0 + wall]),  # back wall
        m.box_between([x0, y0, z0 + wall], [x0 + wall, y1, z1 - wall]),  # left wall
        m.box_between([x1 - wall, y0, z0 + wall], [x1, y1, z1 - wall]),  # right wall
    ]


def _arch_outline(width: float, rise: float, n: int = 24) -> np.ndarray:
    """Half-ellipse arch of base ``width`` and height ``rise`` on the line v = 0, (N, 2) ccw,
    shifted so that the origin is inside (the star centre :func:`_mesh.prism` fans from)."""
    t = np.linspace(0.0, np.pi, n)
    arc = np.stack([width / 2 * np.cos(t), rise * np.sin(t)], axis=1)  # right foot -> top -> left foot
    loop = np.concatenate([arc, [[-width / 4, 0.0], [0.0, 0.0], [width / 4, 0.0]]])
    return loop - np.array([0.0, rise / 3])


def _pick_style(rng: np.random.Generator) -> str:
    names = list(STYLES)
    return str(rng.choice(names, p=[STYLES[s][0] for s in names]))


def build(rng: np.random.Generator, name: str) -> ArticulatedModel:
    style = _pick_style(rng)
    _, width_range, d_over_w, h_over_w, lid_kind, opens = STYLES[style]
    width = rng.uniform(*width_range)
    depth = width * rng.uniform(*d_over_w)
    height = width * rng.uniform(*h_over_w)  # closed, without feet
    wall = rng.uniform(*_WALL[style])
    foot_h = float(rng.uniform(0.008, 0.03)) * width if style in ("jewellery", "chest") and rng.random() < 0.4 else 0.0
    hinge_out = rng.uniform(0.0, 0.006) if rng.random() < 0.5 else 0.0
    x0, x1, z0, z1 = -width / 2, width / 2, -depth / 2, depth / 2

    # --- lid at state 0 (closed), in the base frame --------------------------------------------
    if lid_kind == "cap":
        sheet = rng.uniform(0.001, 0.004)
        rim = height * rng.uniform(0.08, 0.30)
        over = max(wall + 0.0005, rng.uniform(0.001, 0.005))
        y_body = foot_h + height - sheet  # the body's walls reach the sheet's underside
        lx0, lx1, lz0, lz1 = x0 - over, x1 + over, z0 - over, z1 + over
        lid_pieces = _tray(lx0, lx1, y_body - rim + sheet, y_body + sheet, lz0, lz1, wall, sheet, open_up=False)
        y_hinge = y_body - rim + sheet
    else:
        share = rng.uniform(0.30, 0.50) if style == "pencil_case" else rng.uniform(0.15, 0.45)
        lid_h = height * share
        y_body = foot_h + height - lid_h
        over = rng.uniform(0.0, 0.003)
        lx0, lx1, lz0, lz1 = x0 - over, x1 + over, z0 - over, z1 + over
        if style == "chest" and rng.random() < 0.5:  # arched top over a short straight band
            band = lid_h * rng.uniform(0.2, 0.5)
            lid_pieces = _tray(lx0, lx1, y_body, y_body + band, lz0, lz1, wall, wall, open_up=False)
            arch = m.along(m.prism(_arch_outline(lz1 - lz0, lid_h - band), lx1 - lx0), "x")
            lid_pieces.append(m.transformed(arch, translation=(0.0, y_body + band + (lid_h - band) / 3, (lz0 + lz1) / 2)))
        else:
            lid_pieces = _tray(lx0, lx1, y_body, y_body + lid_h, lz0, lz1, wall, wall, open_up=False)
        y_hinge = y_body

    # --- body: hollow tray, feet, handles and clasp -----------------------------------------------
    pieces = _tray(x0, x1, foot_h, y_body, z0, z1, wall, wall, open_up=True)
    if foot_h > 0:
        pieces += m.feet(0.04 * width, foot_h, width / 2 - 0.06 * width, depth / 2 - 0.06 * width)
    if style == "chest":  # side handles
        bar = m.bar_handle(0.25 * depth, 0.008, 0.02)
        for sign in (-1.0, 1.0):
            R = axis_angle_matrix(np.array([0.0, 1.0, 0.0]), sign * np.pi / 2)
            pieces += [m.transformed(p, rotation=R, translation=(sign * width / 2, foot_h + 0.6 * (y_body - foot_h), 0.0)) for p in bar]
    if style in ("chest", "jewellery", "pencil_case") and (style == "chest" or rng.random() < 0.5):
        clasp_w = width * rng.uniform(0.06, 0.12)
        pieces.append(m.box_between([-clasp_w / 2, y_body - 0.15 * (y_body - foot_h), z1], [clasp_w / 2, y_body, z1 + 0.004]))
    if hinge_out > 0:  # hinge barrels outside the back face
        r = max(hinge_out, 0.002)
        for sx in (-0.3, 0.3):
            pieces.append(m.along(m.cylinder(r, 0.12 * width, 12), "x", (sx * width, y_hinge, z0 - r)))
    base = Part("base", m.concat(pieces))

    # --- lid in its own frame (origin on the hinge line) and the hinge ------------------------
    pivot = np.array([0.0, y_hinge, lz0 - hinge_out])
    lid = Part("lid", m.transformed(m.concat(lid_pieces), translation=-pivot))
    joint = Joint(
        "lid_hinge",
        REVOLUTE,
        "base",
        "lid",
        axis=np.array([-1.0, 0.0, 0.0]),  # a positive angle lifts the lid's front edge
        pivot=pivot,
        lower=0.0,
        upper=np.deg2rad(rng.uniform(*opens)),
        rest=0.0,
        origin=SE3(None, pivot),
    )
    return ArticulatedModel((base, lid), (joint,), name=name, category="box")
