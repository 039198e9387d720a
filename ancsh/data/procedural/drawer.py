"""Drawer: a cabinet (base) with three drawers (lowest, middle, top) on prismatic joints.

Frame: cabinet floor centre at the origin, +y up, +z towards the drawer fronts, +x right.
Joint state = how far the drawer is pulled out along +z (metres): 0 closed (rest; the
drawer box lies inside the cabinet, only its handle sticks out), upper limit 55-90 % of the
drawer box depth.
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
    width = rng.uniform(0.40, 0.90)
    height = rng.uniform(0.45, 1.10)
    depth = rng.uniform(0.35, 0.60)
    t = rng.uniform(0.012, 0.025)  # board thickness
    plinth_style = rng.choice(["plinth", "feet", "none"])
    plinth_h = 0.0 if plinth_style == "none" else rng.uniform(0.03, 0.10)
    top_over = rng.choice([0.0, rng.uniform(0.005, 0.025)])
    handle_style = str(rng.choice(["bar", "knobs", "ledge"]))
    recess = rng.uniform(0.0, 0.006)  # drawer fronts set back from the cabinet's front edge
    gap = rng.uniform(0.002, 0.005)
    front_t = rng.uniform(0.015, 0.025)
    graded = rng.random() < 0.5

    # --- cabinet ------------------------------------------------------------------------
    x0, x1 = -width / 2, width / 2
    z0, z1 = -depth / 2, depth / 2
    y_bottom = plinth_h
    y_top = height - t
    pieces = [
        m.box_between([x0, y_bottom, z0], [x0 + t, y_top, z1]),  # left side
        m.box_between([x1 - t, y_bottom, z0], [x1, y_top, z1]),  # right side
        m.box_between([x0 + t, y_bottom, z0], [x1 - t, y_bottom + t, z1]),  # bottom board
        m.box_between([x0 + t, y_bottom + t, z0], [x1 - t, y_top, z0 + t]),  # back
        m.box_between([x0 - top_over, y_top, z0], [x1 + top_over, height, z1 + top_over]),  # top
    ]
    if plinth_style == "plinth":
        setback = rng.uniform(0.0, 0.04)
        pieces.append(m.box_between([x0 + 0.01, 0.0, z0 + 0.01], [x1 - 0.01, plinth_h, z1 - setback]))
    elif plinth_style == "feet":
        r = rng.uniform(0.012, 0.025)
        pieces += m.feet(r, plinth_h, width / 2 - 2 * r, depth / 2 - 2 * r, 16)
    # openings, bottom to top, separated by dividers of thickness t
    inner_h = y_top - (y_bottom + t) - 2 * t
    weights = np.array([1.3, 1.0, 0.8]) * rng.uniform(0.9, 1.1, 3) if graded else np.ones(3)
    heights = inner_h * weights / weights.sum()
    y = y_bottom + t
    openings = []
    for k, h in enumerate(heights):
        openings.append((y, y + h))
        y += h
        if k < 2:
            pieces.append(m.box_between([x0 + t, y, z0 + t], [x1 - t, y + t, z1]))
            y += t
    base = Part("base", m.concat(pieces))

    # --- drawers (child frame: front-face centre at q = 0, axes as the cabinet) ------------
    parts, joints = [base], []
    open_w = width - 2 * t
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
        front_centre = np.array([0.0, (ya + yb) / 2, z1 - recess])
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
