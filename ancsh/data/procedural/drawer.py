"""Drawer: a cabinet (base) with three drawers (lowest, middle, top) on prismatic joints.

Frame: cabinet floor centre at the origin, +y up, +z towards the drawer fronts, +x right.
Joint state = how far the drawer is pulled out along +z (metres): 0 closed (rest; the
drawer box lies inside the cabinet, only its handle sticks out), upper limit 55-90 % of the
drawer box depth.

Layouts (the category keeps exactly three drawers, stacked in one column; the shared
PartNet-Mobility cabinets have width : height 0.7-2.0 and their drawers across the whole
width, in a column beside a knee space or a cupboard, or in the upper part above a shelf):

- ``stack`` (50 %): a chest of drawers, the drawers across the whole width and height;
- ``column`` (25 %): a desk, 0.9-1.2 m wide, with the drawer column (0.3-0.45 of the width) on
  the left or right and an open knee space beside it under the desk top;
- ``upper`` (25 %): the drawers fill the upper 45-70 % of the cabinet, above an open shelf.

Adding the layouts (issue #11) changed every instance of a seed; the split is unchanged.
"""

from __future__ import annotations

import numpy as np

from ...geometry.transforms import SE3
from ...model.articulated import ArticulatedModel, Joint, Part
from ..conventions import convention
from . import _mesh as m
from .registry import PRISMATIC

INFO = convention("drawer")  # the category's one definition (ancsh.data.conventions)

#: Largest distance a handle sticks out in front of the drawer front (metres).
MAX_HANDLE_PROTRUSION = 0.045
#: Layouts and their probabilities (module docstring).
LAYOUTS = {"stack": 0.5, "column": 0.25, "upper": 0.25}


def _handle(rng: np.random.Generator, style: str, front_w: float, front_h: float) -> list:
    """Handle pieces centred on the front face at the origin, protruding towards +z."""
    if style == "bar":
        length = min(front_w * rng.uniform(0.25, 0.6), 0.45)
        r = rng.uniform(0.005, 0.008)
        stand = rng.uniform(0.018, 0.028)
        return m.bar_handle(length, r, stand)
    if style == "knobs":
        r = rng.uniform(0.010, 0.018)
        stem = rng.uniform(0.015, 0.025)
        n = 1 if front_w < 0.55 else 2
        xs = [0.0] if n == 1 else [-front_w / 4, front_w / 4]
        out = []
        for x in xs:
            out.append(m.along(m.cylinder(r * 0.45, stem, 12), "z", (x, 0.0, stem / 2)))
            out.append(m.along(m.cylinder(r, r * 0.9, 20), "z", (x, 0.0, stem + r * 0.45)))
        return out
    # "ledge": a flat pull plate along the front
    length = front_w * rng.uniform(0.3, 0.8)
    depth = rng.uniform(0.018, 0.03)
    plate_t = rng.uniform(0.004, 0.008)
    lip_h = min(front_h * 0.3, rng.uniform(0.015, 0.03))
    return [
        m.box([length, plate_t, depth], [0.0, 0.0, depth / 2]),
        m.box([length, lip_h, plate_t], [0.0, -lip_h / 2 + plate_t / 2, depth - plate_t / 2]),
    ]


def build(rng: np.random.Generator, name: str) -> ArticulatedModel:
    layout = str(rng.choice(list(LAYOUTS), p=list(LAYOUTS.values())))
    if layout == "column":
        width, height, depth = rng.uniform(0.90, 1.20), rng.uniform(0.70, 0.78), rng.uniform(0.45, 0.60)
    else:
        width, height, depth = rng.uniform(0.40, 0.90), rng.uniform(0.50 if layout == "upper" else 0.45, 1.10), rng.uniform(0.35, 0.60)
    t = rng.uniform(0.012, 0.025)  # board thickness
    plinth_style = rng.choice(["plinth", "feet", "none"])
    plinth_h = 0.0 if plinth_style == "none" else rng.uniform(0.03, 0.10)
    top_over = rng.choice([0.0, rng.uniform(0.005, 0.025)])
    handle_style = str(rng.choice(["bar", "knobs", "ledge"]))
    recess = rng.uniform(0.0, 0.006)  # drawer fronts set back from the cabinet's front edge
    gap = rng.uniform(0.002, 0.005)
    front_t = rng.uniform(0.015, 0.025)
    graded = rng.random() < 0.5

    # --- cabinet: outer sides, top, and the drawer column [cx0, cx1] x [ya0, y_top] --------
    x0, x1 = -width / 2, width / 2
    z0, z1 = -depth / 2, depth / 2
    y_bottom = plinth_h
    y_top = height - t
    cx0, cx1 = x0 + t, x1 - t  # inner edges of the column's side boards
    if layout == "column":
        column_w = width * rng.uniform(0.30, 0.45)
        if rng.random() < 0.5:
            cx1 = x0 + column_w - t  # column on the left
        else:
            cx0 = x1 - column_w + t  # column on the right
    ya0 = y_bottom + t  # the lowest drawer's opening starts here
    pieces = [
        m.box_between([x0, y_bottom, z0], [x0 + t, y_top, z1]),  # left side
        m.box_between([x1 - t, y_bottom, z0], [x1, y_top, z1]),  # right side
        m.box_between([cx0, y_bottom, z0], [cx1, y_bottom + t, z1]),  # bottom board of the column
        m.box_between([cx0, y_bottom + t, z0], [cx1, y_top, z0 + t]),  # back of the column
        m.box_between([x0 - top_over, y_top, z0], [x1 + top_over, height, z1 + top_over]),  # top
    ]
    if layout == "column":  # the column's inner side board; a modesty panel at the back of the knee space
        xs = (cx1, cx1 + t) if cx0 == x0 + t else (cx0 - t, cx0)
        pieces.append(m.box_between([xs[0], y_bottom, z0], [xs[1], y_top, z1]))
        kx = (xs[1], x1 - t) if cx0 == x0 + t else (x0 + t, xs[0])
        pieces.append(m.box_between([kx[0], y_top - 0.25 * height, z0], [kx[1], y_top, z0 + t]))
    elif layout == "upper":  # an open shelf below the drawers
        ya0 = y_bottom + t + (y_top - y_bottom) * rng.uniform(0.30, 0.55)
        pieces.append(m.box_between([cx0, ya0 - t, z0 + t], [cx1, ya0, z1]))
        if rng.random() < 0.5:
            y_shelf = (y_bottom + ya0) / 2
            pieces.append(m.box_between([cx0, y_shelf, z0 + t], [cx1, y_shelf + t, z1 - 0.02]))
    if plinth_style == "plinth":
        setback = rng.uniform(0.0, 0.04)
        pieces.append(m.box_between([x0 + 0.01, 0.0, z0 + 0.01], [x1 - 0.01, plinth_h, z1 - setback]))
    elif plinth_style == "feet":
        r = rng.uniform(0.012, 0.025)
        pieces += m.feet(r, plinth_h, width / 2 - 2 * r, depth / 2 - 2 * r, 16)
    # openings, bottom to top, separated by dividers of thickness t
    inner_h = y_top - ya0 - 2 * t
    weights = np.array([1.3, 1.0, 0.8]) * rng.uniform(0.9, 1.1, 3) if graded else np.ones(3)
    heights = inner_h * weights / weights.sum()
    y = ya0
    openings = []
    for k, h in enumerate(heights):
        openings.append((y, y + h))
        y += h
        if k < 2:
            pieces.append(m.box_between([cx0, y, z0 + t], [cx1, y + t, z1]))
            y += t
    base = Part("base", m.concat(pieces))

    # --- drawers (child frame: front-face centre at q = 0, axes as the cabinet) ------------
    parts, joints = [base], []
    open_w = cx1 - cx0
    x_column = (cx0 + cx1) / 2
    wall = rng.uniform(0.008, 0.014)
    box_depth = depth - t - front_t - recess - rng.uniform(0.01, 0.03)
    travel_frac = rng.uniform(0.55, 0.9)
    for name_k, joint_name, (ya, yb) in zip(INFO.part_names[1:], INFO.joint_names, openings):
        fw, fh = open_w - 2 * gap, (yb - ya) - 2 * gap
        bw = fw - 2 * rng.uniform(0.008, 0.015)  # slides
        bh = fh * rng.uniform(0.6, 0.85)
        y_box = -fh / 2 + rng.uniform(0.0, 0.1) * (fh - bh)  # box bottom relative to front centre
        zf = -front_t  # back face of the front
        zb = zf - box_depth
        dp = [
            m.box([fw, fh, front_t], [0.0, 0.0, -front_t / 2]),
            m.box_between([-bw / 2, y_box, zb], [bw / 2, y_box + wall, zf]),  # floor
            m.box_between([-bw / 2, y_box + wall, zb], [-bw / 2 + wall, y_box + bh, zf]),
            m.box_between([bw / 2 - wall, y_box + wall, zb], [bw / 2, y_box + bh, zf]),
            m.box_between([-bw / 2 + wall, y_box + wall, zb], [bw / 2 - wall, y_box + bh, zb + wall]),
        ]
        hy = fh * (0.3 if handle_style == "ledge" else rng.uniform(0.0, 0.2))
        dp += [m.transformed(p, translation=(0.0, hy, 0.0)) for p in _handle(rng, handle_style, fw, fh)]
        parts.append(Part(name_k, m.concat(dp)))
        front_centre = np.array([x_column, (ya + yb) / 2, z1 - recess])
        joints.append(
            Joint(
                joint_name,
                PRISMATIC,
                "base",
                name_k,
                axis=np.array([0.0, 0.0, 1.0]),
                pivot=front_centre,
                lower=0.0,
                upper=travel_frac * box_depth,
                rest=0.0,
                origin=SE3(None, front_centre),
            )
        )
    return ArticulatedModel(tuple(parts), tuple(joints), name=name, category="drawer")
