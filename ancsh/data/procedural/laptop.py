"""Laptop: base (keyboard half) and display, one revolute hinge along the back edge.

Frame: base bottom centre at the origin, +y up, +z towards the user (the open side),
+x right. Joint state = opening angle: 0 closed, rest pi/2 (display upright, screen facing
+z), upper limit 110-175 degrees.

Proportions (calibrated on the 34 PartNet-Mobility laptops: base depth : width 0.47-0.87,
median 0.71; base thickness : width 0.02-0.14, median 0.06): width 0.28-0.38 m, depth :
width 0.55-0.82, base thickness : width 0.03-0.06 (thin, 60 %) or 0.06-0.11 (thick, 40 %),
display thickness 4-14 mm. Widening these ranges (issue #11) changed every instance of a
seed; the split is unchanged.
"""

from __future__ import annotations

import numpy as np

from ...geometry.transforms import SE3
from ...model.articulated import ArticulatedModel, Joint, Part
from ..conventions import convention
from . import _mesh as m
from .registry import REVOLUTE

INFO = convention("laptop")  # the category's one definition (ancsh.data.conventions)


def build(rng: np.random.Generator, name: str) -> ArticulatedModel:
    width = rng.uniform(0.28, 0.38)
    depth = width * rng.uniform(0.55, 0.82)
    t_base = width * (rng.uniform(0.03, 0.06) if rng.random() < 0.6 else rng.uniform(0.06, 0.11))
    t_lid = rng.uniform(0.004, 0.014)
    corner = rng.uniform(0.002, 0.016)
    foot_h = rng.choice([0.0, rng.uniform(0.002, 0.005)])
    hinge_in = rng.uniform(0.0, 0.008)  # hinge line ahead of the base's back edge
    bezel_side = rng.uniform(0.004, 0.020)
    bezel_top = bezel_side + rng.uniform(0.0, 0.012)
    bezel_bottom = bezel_side + rng.uniform(0.0, 0.025)
    upper = np.deg2rad(rng.uniform(110.0, 175.0))
    taper = rng.uniform(0.0, 0.4)  # wedge: base thinner at the front

    # --- base -----------------------------------------------------------------------------
    outline = m.outline_rounded_rect(width, depth, corner)
    y0 = foot_h
    pieces = [m.along(m.prism(outline, t_base), "y", (0.0, y0 + t_base / 2, 0.0))]
    if taper > 0.05:  # wedge look: thinner at the front, full height over the back half
        front_t = t_base * (1 - taper)
        back = m.outline_rounded_rect(width, depth / 2, corner)
        pieces = [
            m.along(m.prism(outline, front_t), "y", (0.0, y0 + front_t / 2, 0.0)),
            m.along(m.prism(back, t_base - front_t), "y", (0.0, y0 + (t_base + front_t) / 2, -depth / 4)),
        ]
        top_front = y0 + front_t
    else:
        top_front = y0 + t_base
    y_top = y0 + t_base
    kb_w, kb_d = width * rng.uniform(0.75, 0.9), depth * rng.uniform(0.3, 0.4)
    pieces.append(m.box([kb_w, 0.0012, kb_d], [0.0, y_top + 0.0006, -depth / 2 + 0.015 + kb_d / 2]))
    pad_w, pad_d = width * rng.uniform(0.25, 0.4), depth * rng.uniform(0.2, 0.3)
    pieces.append(m.box([pad_w, 0.0008, pad_d], [0.0, top_front + 0.0004, depth / 2 - 0.012 - pad_d / 2]))
    if foot_h > 0:
        pieces += m.feet(0.006, foot_h, width / 2 - 0.03, depth / 2 - 0.025)
    # hinge barrel on the base's back edge
    barrel_r = min(t_base / 2, 0.007)
    z_hinge = -depth / 2 + hinge_in
    pieces.append(m.along(m.cylinder(barrel_r, width * rng.uniform(0.5, 0.9)), "x", (0.0, y_top, z_hinge)))
    base = Part("base", m.concat(pieces))

    # --- display (child frame: origin on the hinge line, axes as the base at q = 0) ----------
    lid_d = depth - hinge_in - rng.uniform(0.0, 0.004)
    lid_outline = m.outline_rounded_rect(width, lid_d, corner)
    lid = m.along(m.prism(lid_outline, t_lid), "y", (0.0, barrel_r + t_lid / 2, lid_d / 2))
    scr_w = width - 2 * bezel_side
    scr_d = lid_d - bezel_top - bezel_bottom
    # screen on the underside at q = 0 (faces the user when open); bezel_bottom is near the hinge
    screen = m.box([scr_w, 0.0008, scr_d], [0.0, barrel_r - 0.0004, bezel_bottom + scr_d / 2])
    display = Part("display", m.concat([lid, screen]))

    pivot = np.array([0.0, y_top, z_hinge])
    joint = Joint(
        "display_hinge",
        REVOLUTE,
        "base",
        "display",
        axis=np.array([-1.0, 0.0, 0.0]),  # positive angle lifts the lid's front edge
        pivot=pivot,
        lower=0.0,
        upper=upper,
        rest=np.pi / 2,
        origin=SE3(None, pivot),
    )
    return ArticulatedModel((base, display), (joint,), name=name, category="laptop")
