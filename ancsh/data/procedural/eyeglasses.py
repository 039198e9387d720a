"""Eyeglasses: front frame (base) with rims, lenses and bridge; left and right temples on
revolute hinges with vertical axes.

Frame: centre of the lens line at the origin, +y up, the front frame in the xy-plane facing
+z, +x right; the temples extend towards -z at rest. "Left" and "right" follow the canonical
frame as seen from the front (+z): the left temple is at -x (the wearer's right).
Hinge axes are vertical: -y for the left temple, +y for the right one, so that for both a
positive state folds the temple inwards (the PartNet-Mobility eyeglasses use the same
convention). Joint state: 0 = temple at right angles to the frame (rest), up to about
pi/2 folded, slightly negative = splayed outwards.

Temple shapes (the two PartNet-Mobility eyeglasses: one nearly straight temple, one with a
long ear hook dropping by a third of the frame width; temple length 0.7-0.76 of the frame
width, real eyeglasses about 1):

- ``bent`` (50 %): straight, then an ear piece bent down by 15-35 degrees over 15-30 % of it;
- ``straight`` (20 %): no ear bend (sports and reading glasses);
- ``hooked`` (30 %): an ear hook curling down by 40-65 degrees in three steps over 25-35 %.

Temple length is 0.8-1.15 of the frame width (at least 11 cm); the temple is a thin wire
(60 %) or a wider acetate bar tapering towards the end (40 %). Adding the shapes (issue #11)
changed every instance of a seed; the split is unchanged.
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


#: Temple shapes and their probabilities (module docstring).
TEMPLE_SHAPES = {"bent": 0.5, "straight": 0.2, "hooked": 0.3}


def _ear_piece(rng: np.random.Generator, shape: str) -> tuple:
    """``(tip_frac, angles)``: the ear piece's share of the temple length and its segments'
    downward angles (rad), for a temple ``shape`` of :data:`TEMPLE_SHAPES`."""
    if shape == "straight":
        return 0.0, []
    if shape == "bent":
        return rng.uniform(0.15, 0.3), [np.deg2rad(rng.uniform(15.0, 35.0))]
    tip_frac, total = rng.uniform(0.25, 0.35), np.deg2rad(rng.uniform(40.0, 65.0))
    return tip_frac, list(total * np.array([1.0, 2.0, 3.0]) / 3)


def _temple(length, width_y, thick_x, tip_frac, angles, taper) -> list:
    """Temple pieces in the hinge frame: starts at the origin, extends towards -z.

    A straight bar, then ear-piece segments (``tip_frac`` of the length, see
    :func:`_ear_piece`), each turned further down about x; ``taper`` narrows the far end's
    height (fraction).
    """
    straight = length * (1 - tip_frac)
    pieces = [m.box_between([-thick_x / 2, -width_y / 2, -straight], [thick_x / 2, width_y / 2, 0.0])]
    # the hinge knuckle
    knuckle_r = max(thick_x, 0.0015) * 0.9
    pieces.append(m.along(m.cylinder(knuckle_r, width_y * 0.9, 12), "y", (0.0, 0.0, -knuckle_r)))
    start = np.array([0.0, 0.0, -straight])
    seg_len = length * tip_frac / max(len(angles), 1)
    for k, angle in enumerate(angles):
        w = width_y * (1 - taper * (k + 1) / len(angles))
        seg = m.box_between([-thick_x / 2, -w / 2, -seg_len - 0.001], [thick_x / 2, w / 2, 0.001])
        # bend the segment downwards (rotate about x so -z goes towards -y)
        pieces.append(m.transformed(m.rotated(seg, [1.0, 0.0, 0.0], -angle), translation=start))
        start = start + seg_len * np.array([0.0, -np.sin(angle), -np.cos(angle)])
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
    frame_width = 2 * (hinge_x + 0.0015)
    length = max(frame_width * rng.uniform(0.8, 1.15), 0.11)
    acetate = rng.random() < 0.4
    width_y = rng.uniform(0.006, 0.012) if acetate else rng.uniform(0.002, 0.005)
    thick_x = rng.uniform(0.0015, 0.0035)
    taper = rng.uniform(0.3, 0.6) if acetate else 0.0
    shape = str(rng.choice(list(TEMPLE_SHAPES), p=list(TEMPLE_SHAPES.values())))
    tip_frac, angles = _ear_piece(rng, shape)
    fold = rng.uniform(1.45, 1.62)
    parts, joints = [base], []
    for side, part_name, joint_name in ((-1, "left_temple", "left_hinge"), (1, "right_temple", "right_hinge")):
        splay = rng.uniform(0.05, 0.25)
        temple = m.concat(_temple(length, width_y, thick_x, tip_frac, angles, taper))
        parts.append(Part(part_name, temple))
        pivot = np.array([side * hinge_x, hinge_y, z_back])
        # a positive rotation about side * y swings the temple's -z direction towards -side * x
        joints.append(Joint(joint_name, REVOLUTE, "base", part_name, axis=side * _UP, pivot=pivot,
                            lower=-splay, upper=fold, rest=0.0, origin=SE3(None, pivot)))
    return ArticulatedModel(tuple(parts), tuple(joints), name=name, category="eyeglasses")
