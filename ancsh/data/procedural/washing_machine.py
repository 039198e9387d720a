"""Washing machine (front loader): body (base) and a round-ish door on a vertical side hinge.

Frame: body floor centre at the origin, +y up, +z towards the door, +x right. The front
panel has a porthole opening (the drum recess) that the door covers; the hinge sits on the
door's left (-x) side. Joint state = door opening angle: 0 closed (rest), the door's right
edge swings towards +z, upper limit 90-180 degrees.
"""

from __future__ import annotations

import numpy as np

from ...geometry.transforms import SE3
from ...model.articulated import ArticulatedModel, Joint, Part
from ..conventions import convention
from . import _mesh as m
from .registry import REVOLUTE

INFO = convention("washing_machine")  # the category's one definition (ancsh.data.conventions)

_N = 64  # outline samples


def build(rng: np.random.Generator, name: str) -> ArticulatedModel:
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
