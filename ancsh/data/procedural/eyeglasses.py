"""Eyeglasses: front frame (base) with rims, lenses and bridge; left and right temples on
revolute hinges with vertical axes.

Frame: centre of the lens line at the origin, +y up, the front frame in the xy-plane facing
+z, +x right; the temples extend towards -z at rest. "Left" and "right" follow the canonical
frame as seen from the front (+z): the left temple is at -x (the wearer's right).
Hinge axes are vertical: -y for the left temple, +y for the right one, so that for both a
positive state folds the temple inwards (the PartNet-Mobility eyeglasses use the same
convention). Joint state: 0 = temple at right angles to the frame (rest), up to about
pi/2 folded, slightly negative = splayed outwards.
"""

from __future__ import annotations

import numpy as np

from ...geometry.transforms import SE3
from ...model.articulated import ArticulatedModel, Joint, Part
from ..conventions import convention
from . import _mesh as m
from .registry import REVOLUTE

INFO = convention("eyeglasses")  # the category's one definition (ancsh.data.conventions)

_N = 48
_UP = np.array([0.0, 1.0, 0.0])


def _temple(rng, length, width_y, thick_x, bend_frac, bend_angle, tip_style) -> list:
    """Temple pieces in the hinge frame: starts at the origin, extends towards -z."""
    straight = length * (1 - bend_frac)
    pieces = [m.box_between([-thick_x / 2, -width_y / 2, -straight], [thick_x / 2, width_y / 2, 0.0])]
    # the hinge knuckle
    knuckle_r = max(thick_x, 0.0015) * 0.9
    pieces.append(m.along(m.cylinder(knuckle_r, width_y * 0.9, 12), "y", (0.0, 0.0, -knuckle_r)))
    tip_len = length * bend_frac
    tip_w = width_y * (0.7 if tip_style == "thin" else 1.0)
    tip = m.box_between([-thick_x / 2, -tip_w / 2, -tip_len - 0.001], [thick_x / 2, tip_w / 2, 0.001])
    # bend the ear piece downwards (rotate about x so -z goes towards -y)
    tip = m.rotated(tip, [1.0, 0.0, 0.0], -bend_angle)
    pieces.append(m.transformed(tip, translation=(0.0, 0.0, -straight)))
    return pieces


def build(rng: np.random.Generator, name: str) -> ArticulatedModel:
    a = rng.uniform(0.021, 0.028)  # lens half width
    b = a * rng.uniform(0.55, 0.95)  # lens half height
    exponent = rng.uniform(2.0, 4.5)
    taper = rng.uniform(-0.12, 0.25)
    rim = rng.uniform(0.0015, 0.005)
    depth = rng.uniform(0.002, 0.006)  # frame thickness along z
    bridge = rng.uniform(0.014, 0.022)
    wrap = np.deg2rad(rng.uniform(0.0, 8.0))
    end_out = rng.uniform(0.003, 0.008)
    end_back = rng.uniform(0.006, 0.016)
    hinge_y = b * rng.uniform(0.1, 0.6)

    lens_outline = m.taper(m.outline_superellipse(a, b, exponent, _N), taper)
    rim_outline = m.taper(m.outline_superellipse(a + rim, b + rim, exponent, _N), taper)
    xc = bridge / 2 + rim + a
    pieces = []
    for side in (-1, 1):
        group = [
            m.ring_prism(rim_outline, lens_outline, depth),
            m.prism(lens_outline, min(0.0018, depth * 0.8)),
        ]
        rot = side * wrap  # outer edges bend backwards
        for g in group:
            g = m.rotated(g, _UP, rot)
            pieces.append(m.transformed(g, translation=(side * xc, 0.0, 0.0)))
    # bridge: one or two bars across the nose, and nose pads behind
    bar_h = rng.uniform(0.002, 0.005)
    bridge_ys = [b * rng.uniform(0.2, 0.6)]
    if rng.random() < 0.3:
        bridge_ys.append(b * rng.uniform(0.8, 1.0) + rim / 2)
    inner_x = xc - a * (1 + taper * np.array(bridge_ys) / b) - rim
    for y, ix in zip(bridge_ys, inner_x):
        pieces.append(m.box([2 * ix + 2 * rim, bar_h, depth], [0.0, y, 0.0]))
    for side in (-1, 1):
        pieces.append(m.box([0.003, 0.008, 0.006], [side * (bridge / 2 + 0.002), -b * 0.3, -depth / 2 - 0.004]))
    # end pieces: out from the rim's outer edge, then back to the hinge
    outer_x = xc + a * (1 + taper * hinge_y / b) * np.cos(wrap) + rim
    hinge_x = outer_x + end_out
    z_rim = -np.sin(wrap) * a  # the rim's outer edge sits back by the wrap
    z_back = z_rim - depth / 2 - end_back
    blk_h = rng.uniform(0.004, 0.009)
    for side in (-1, 1):
        xs = np.sort([side * (outer_x - rim - 0.002), side * (hinge_x + 0.0015)])
        pieces.append(m.box_between([xs[0], hinge_y - blk_h / 2, z_rim - depth / 2], [xs[1], hinge_y + blk_h / 2, z_rim + depth / 2]))
        xs = np.sort([side * (hinge_x - 0.0025), side * (hinge_x + 0.0015)])
        pieces.append(m.box_between([xs[0], hinge_y - blk_h / 2, z_back], [xs[1], hinge_y + blk_h / 2, z_rim - depth / 2]))
    base = Part("base", m.concat(pieces))

    # --- temples (child frames: origin on the hinge axis, axes as the frame at q = 0) ------
    length = rng.uniform(0.125, 0.150)
    width_y = rng.uniform(0.002, 0.008)
    thick_x = rng.uniform(0.0015, 0.0035)
    bend_frac = rng.uniform(0.15, 0.3)
    bend_angle = np.deg2rad(rng.uniform(15.0, 35.0))
    tip_style = str(rng.choice(["thin", "straight"]))
    fold = rng.uniform(1.45, 1.62)
    parts, joints = [base], []
    for side, part_name, joint_name in ((-1, "left_temple", "left_hinge"), (1, "right_temple", "right_hinge")):
        splay = rng.uniform(0.05, 0.25)
        temple = m.concat(_temple(rng, length, width_y, thick_x, bend_frac, bend_angle, tip_style))
        parts.append(Part(part_name, temple))
        pivot = np.array([side * hinge_x, hinge_y, z_back])
        # a positive rotation about side * y swings the temple's -z direction towards -side * x
        joints.append(Joint(joint_name, REVOLUTE, "base", part_name, axis=side * _UP, pivot=pivot,
                            lower=-splay, upper=fold, rest=0.0, origin=SE3(None, pivot)))
    return ArticulatedModel(tuple(parts), tuple(joints), name=name, category="eyeglasses")
