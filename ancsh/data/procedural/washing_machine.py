"""Washing machine: body (base) and a door, either a front loader's round door on a vertical
side hinge or a top loader's lid on a hinge along its back edge.

Frame: body floor centre at the origin, +y up, +z towards the front, +x right. Joint state =
door opening angle: 0 closed (rest).

Variants (the convention allows the door in front or on top):

- ``front`` loader (65 %): the front panel has a porthole opening (the drum recess) that the
  door covers; the hinge sits on the door's left (-x) side; the door's right edge swings towards
  +z, upper limit 90-180 degrees;
- ``top`` loader (35 %): the top deck has a round opening into the drum under a rectangular
  lid hinged along its back edge (axis -x, the front edge rises) or, for 30 % of them, along its
  left or right edge (axis +z or -z, the other side edge rises), upper limit 80-110 degrees;
  the controls are on a low backsplash behind the lid (55 %) or on a strip in front of it.

Adding the top loader (issue #11) changed every instance of a seed; the split is unchanged.
The side hinges (generator version 3 of this category) are drawn last: every other instance is the
shape its seed gave before.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...geometry.transforms import SE3
from ...model.articulated import ArticulatedModel, Joint, Part
from ..conventions import convention
from . import _door
from . import _mesh as m
from .registry import REVOLUTE

INFO = convention("washing_machine")  # the category's one definition (ancsh.data.conventions)

_N = 64  # outline samples
#: Loader variants and their probabilities.
_LOADERS = {"front": 0.65, "top": 0.35}
#: Share of the top loaders whose lid hinges along its left or right edge (half each), not its back edge.
_SIDE_HINGED = 0.3


def build(rng: np.random.Generator, name: str) -> ArticulatedModel:
    loader = str(rng.choice(list(_LOADERS), p=list(_LOADERS.values())))
    return _front_loader(rng, name) if loader == "front" else _top_loader(rng, name)


def _top_loader(rng: np.random.Generator, name: str) -> ArticulatedModel:
    width = rng.uniform(0.55, 0.65)
    deck_y = rng.uniform(0.78, 0.88)  # top of the deck the lid rests on
    depth = rng.uniform(0.52, 0.62)
    feet_h = float(rng.choice([0.0, rng.uniform(0.01, 0.03)]))
    deck_t = rng.uniform(0.03, 0.07)  # deck thickness = depth of the recess around the drum
    margin = rng.uniform(0.02, 0.04)  # deck visible around the lid
    z0, z1 = -depth / 2, depth / 2
    backsplash = rng.random() < 0.55
    bs_d = rng.uniform(0.08, 0.12) if backsplash else 0.0
    bs_h = rng.uniform(0.04, 0.08)  # low: the lid's front edge clears it as soon as it opens
    strip = 0.0 if backsplash else rng.uniform(0.06, 0.1)  # control strip in front of the lid
    lid = _door.DoorFrame(-width / 2 + margin, width / 2 - margin, z0 + bs_d + margin, z1 - margin - strip,
                          deck_y, rng.uniform(0.02, 0.045), "top")

    # --- body: cabinet, deck with a round opening over the drum, controls -------------------
    pieces = [m.box_between([-width / 2, feet_h, z0], [width / 2, deck_y - deck_t, z1])]
    hole_c = np.array([0.0, (lid.a0 + lid.a1) / 2])  # (x, z) centre of the opening
    hole_r = 0.42 * min(lid.width, lid.length)
    # the deck outline in (x, -z), sampled along rays from the opening's centre (see _mesh)
    outer = m.outline_rounded_rect(width, depth, rng.uniform(0.0, 0.03), _N, center=(-hole_c[0], hole_c[1]))
    ang = np.arctan2(outer[:, 1], outer[:, 0])
    hole = hole_r * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    deck = m.along(m.ring_prism(outer, hole, deck_t), "y", (hole_c[0], deck_y - deck_t / 2, hole_c[1]))
    pieces.append(deck)
    knob_r = rng.uniform(0.02, 0.035)
    if backsplash:
        pieces.append(m.box_between([-width / 2, deck_y, z0], [width / 2, deck_y + bs_h, z0 + bs_d]))
        for x in np.linspace(-width / 3, width / 3, int(rng.integers(1, 4))):
            pieces.append(m.along(m.cylinder(knob_r, 0.02, 20), "z", (x, deck_y + bs_h / 2, z0 + bs_d + 0.01)))
    else:
        for x in np.linspace(-width / 3, width / 3, int(rng.integers(1, 4))):
            pieces.append(m.along(m.cylinder(knob_r * 0.8, 0.02, 20), "y", (x, deck_y + 0.01, z1 - strip / 2)))
    if feet_h > 0:
        pieces += m.feet(0.02, feet_h, width / 2 - 0.05, depth / 2 - 0.05)
    base = Part("base", m.concat(pieces))

    # --- lid: a slab, a glass window (55 %), a grip along the edge opposite the hinge -------
    window = rng.random() < 0.55
    grip_share = rng.uniform(0.3, 0.7)
    grip_h = rng.uniform(0.008, 0.02)
    upper = np.deg2rad(rng.uniform(80.0, 110.0))
    # drawn last, so that a lid hinged along its back edge is the shape its seed gave before side hinges
    side = rng.random()
    hinge = "top" if side >= _SIDE_HINGED else ("top_left" if side < _SIDE_HINGED / 2 else "top_right")
    lid = replace(lid, hinge=hinge)
    lid_pieces = [lid.box([0.0, 0.0, 0.0], [lid.width, lid.length, lid.thickness])]
    if window:
        inset = 0.2 * min(lid.width, lid.length)
        lid_pieces.append(lid.box([inset, inset, lid.thickness], [lid.width - inset, lid.length - inset, lid.thickness + 0.004]))
    w_top = lid.thickness + grip_h
    if hinge == "top":  # the grip along the front edge
        grip_w = lid.width * grip_share
        lid_pieces.append(lid.box([(lid.width - grip_w) / 2, lid.length - 0.03, lid.thickness],
                                  [(lid.width + grip_w) / 2, lid.length, w_top]))
    else:  # along the free side edge
        grip_l = lid.length * grip_share
        u0 = lid.width - 0.03 if hinge == "top_left" else 0.0
        lid_pieces.append(lid.box([u0, (lid.length - grip_l) / 2, lid.thickness],
                                  [u0 + 0.03, (lid.length + grip_l) / 2, w_top]))
    door = Part("door", m.concat(lid_pieces))
    joint = lid.joint("door_hinge", upper)
    return ArticulatedModel((base, door), (joint,), name=name, category="washing_machine")


def _front_loader(rng: np.random.Generator, name: str) -> ArticulatedModel:
    width = rng.uniform(0.55, 0.66)
    height = rng.uniform(0.70, 0.92)
    depth = rng.uniform(0.42, 0.66)
    feet_h = float(rng.choice([0.0, rng.uniform(0.01, 0.03)]))
    panel_h = rng.uniform(0.08, 0.16)  # control strip at the top of the front
    kick_h = rng.uniform(0.0, 0.1)  # service flap strip at the bottom
    recess = rng.uniform(0.03, 0.08)  # drum recess behind the porthole
    corner = rng.uniform(0.0, 0.03)
    z_front = depth / 2

    face_y0, face_y1 = feet_h, height - panel_h  # the front face around the porthole
    door_r = min(rng.uniform(0.19, 0.27), width / 2 - 0.045, (face_y1 - face_y0 - kick_h) / 2 - 0.03)
    exponent = float(rng.choice([2.0, 2.0, rng.uniform(2.3, 3.5)]))  # round or squircle door
    hinge_off = rng.uniform(0.005, 0.03)  # hinge line beyond the door's left edge
    x_c = rng.uniform(-0.02, 0.02) + hinge_off / 2
    y_lo, y_hi = face_y0 + kick_h + door_r + 0.02, face_y1 - door_r - 0.02
    y_c = y_lo + rng.uniform(0.3, 0.8) * max(y_hi - y_lo, 0.0)
    open_r = door_r * rng.uniform(0.72, 0.85)

    # --- body -----------------------------------------------------------------------------
    pieces = [m.box_between([-width / 2, feet_h, -depth / 2], [width / 2, height, z_front - recess])]
    # front face with the porthole, ray-sampled from the porthole centre
    face_h = face_y1 - face_y0
    outer = m.outline_rounded_rect(width, face_h, corner, _N, center=(-x_c, (face_y0 + face_y1) / 2 - y_c))
    # a circular hole sampled along the same rays as the outer outline
    ang = np.arctan2(outer[:, 1], outer[:, 0])
    hole = open_r * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    front = m.ring_prism(outer, hole, recess)
    pieces.append(m.transformed(front, translation=(x_c, y_c, z_front - recess / 2)))
    # control strip: slightly proud panel with a program knob, display and buttons
    pieces.append(m.box_between([-width / 2, face_y1, z_front - recess], [width / 2, height, z_front]))
    knob_r = rng.uniform(0.025, 0.04)
    y_panel = (face_y1 + height) / 2
    knob_x = rng.uniform(0.0, width / 2 - knob_r - 0.03) * rng.choice([-1, 1])
    pieces.append(m.along(m.cylinder(knob_r, 0.025, 24), "z", (knob_x, y_panel, z_front + 0.0125)))
    pieces.append(m.box([0.07, min(0.035, panel_h * 0.5), 0.004], [-knob_x * 0.4, y_panel, z_front + 0.002]))
    if rng.random() < 0.6:  # detergent drawer front at the top left
        dw = rng.uniform(0.12, 0.2)
        pieces.append(m.box([dw, panel_h * 0.6, 0.01], [-width / 2 + 0.02 + dw / 2, y_panel, z_front + 0.005]))
    if kick_h > 0.03:  # service flap
        pieces.append(m.box([width * 0.5, kick_h * 0.6, 0.004], [0.0, face_y0 + kick_h / 2, z_front + 0.002]))
    if feet_h > 0:
        pieces += m.feet(0.02, feet_h, width / 2 - 0.05, depth / 2 - 0.05)
    base = Part("base", m.concat(pieces))

    # --- door (child frame: origin on the hinge line, axes as the body at q = 0) -----------
    door_t = rng.uniform(0.03, 0.07)
    dx = hinge_off + door_r  # door centre in the child frame
    window_r = door_r * rng.uniform(0.55, 0.72)
    ring = m.ring_prism(
        m.outline_superellipse(door_r, door_r, exponent, _N),
        m.outline_superellipse(window_r, window_r, exponent, _N),
        door_t,
    )
    bowl_depth = rng.uniform(0.3, 0.9) * recess
    bowl_r = min(window_r, open_r - 0.01)
    glass = m.cylinder(bowl_r, bowl_depth + door_t * 0.8, 32)
    door_pieces = [
        m.transformed(ring, translation=(dx, 0.0, door_t / 2)),
        m.transformed(glass, translation=(dx, 0.0, (door_t * 0.8 - bowl_depth) / 2)),
        m.box_between([0.0, -0.03, 0.0], [hinge_off + 0.02, 0.03, door_t * 0.6]),  # hinge arm
    ]
    handle = str(rng.choice(["grip", "bar", "none"]))
    if handle == "grip":
        door_pieces.append(m.box([0.025, door_r * 0.5, 0.025], [dx + door_r - 0.01, 0.0, door_t + 0.0125]))
    elif handle == "bar":
        door_pieces.append(m.along(m.cylinder(0.01, door_r * 0.6, 12), "y", (dx + door_r * 0.85, 0.0, door_t + 0.015)))
    door = Part("door", m.concat(door_pieces))

    pivot = np.array([x_c - dx, y_c, z_front])
    joint = Joint(
        "door_hinge",
        REVOLUTE,
        "base",
        "door",
        axis=np.array([0.0, -1.0, 0.0]),  # positive angle swings the door's right edge towards +z
        pivot=pivot,
        lower=0.0,
        upper=np.deg2rad(rng.uniform(90.0, 180.0)),
        rest=0.0,
        origin=SE3(None, pivot),
    )
    return ArticulatedModel((base, door), (joint,), name=name, category="washing_machine")
