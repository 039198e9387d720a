"""Microwave: body (base) with a cooking cavity and a door on a vertical side hinge.

Frame: body floor centre at the origin, +y up, +z towards the door, +x right. The door covers
most of the front; a control panel (buttons, display, sometimes dials and a door-release
button) fills the rest of the front on the side opposite the hinge. Joint state = door
opening angle: 0 closed (rest), the free edge swings towards +z, upper limit 85-120 degrees.

Variation (calibrated on the 7 PartNet-Mobility microwaves, all hinged on the left, body
width : height 1.35-2.0, depth : width 0.5-1.0, door 0.7-0.85 of the width):

- hinge side: left (80 %) or right (20 %);
- proportions drawn as ratios, then the body scaled to a rest diagonal of 0.50-0.76 m;
- door width 0.66-0.84 of the body, height 0.72-0.98 of it (or the full height, 25 %);
  standing on the front face (70 %) or inset flush with it (30 %); thickness 2.5-5.5 cm;
- door handle: vertical bar (40 %), edge grip (30 %) or none, opened by a button on the
  panel (30 %); 0-2 dials on the panel; glass window on the door.
"""

from __future__ import annotations

import numpy as np

from ...model.articulated import ArticulatedModel, Part
from ..conventions import convention
from . import _door
from . import _mesh as m

INFO = convention("microwave")  # the category's one definition (ancsh.data.conventions)

#: Range of the body's box diagonal (metres), inside the convention's range (handles add a few cm).
BODY_DIAGONAL = (0.50, 0.76)


def _proportions(rng: np.random.Generator, diagonal_range) -> tuple:
    """``(width, height, depth)`` from a width : height and depth : width ratio, scaled to a drawn diagonal."""
    w_over_h = rng.uniform(1.35, 1.95)
    d_over_w = rng.uniform(0.5, 0.9)
    shape = np.array([w_over_h, 1.0, w_over_h * d_over_w])
    return tuple(shape * rng.uniform(*diagonal_range) / np.linalg.norm(shape))


def build(rng: np.random.Generator, name: str) -> ArticulatedModel:
    width, height, depth = _proportions(rng, BODY_DIAGONAL)
    hinge = "left" if rng.random() < 0.8 else "right"
    sign = -1.0 if hinge == "left" else 1.0  # the hinge side's x direction
    feet_h = float(rng.choice([0.0, rng.uniform(0.008, 0.02)]))
    shell = rng.uniform(0.012, 0.03)
    inset = bool(rng.random() < 0.3)
    door_t = rng.uniform(0.025, 0.055)
    z_front = depth / 2

    # --- front layout: door on the hinge side, control panel on the other ------------------
    door_w = width * rng.uniform(0.66, 0.84)
    full_height = rng.random() < 0.25
    door_h = (height - feet_h) * (1.0 if full_height else rng.uniform(0.72, 0.98)) - (0.004 if inset else 0.0)
    margin = 0.002 if inset or full_height else 0.0
    y0 = feet_h + (height - feet_h - door_h) / 2
    x_hinge = sign * (width / 2 - margin)
    xs = sorted([x_hinge, x_hinge - sign * door_w])
    door = _door.DoorFrame(xs[0], xs[1], y0, y0 + door_h, z_front, door_t, hinge, inset)
    panel_x0, panel_x1 = sorted([x_hinge - sign * door_w, -x_hinge])
    panel_xc = (panel_x0 + panel_x1) / 2
    panel_w = panel_x1 - panel_x0

    # --- body with the cooking cavity ------------------------------------------------------
    gap = 0.003 if inset else -shell  # opening beyond (inset) or inside the door's outline
    cx0 = max(door.x0 - gap, -width / 2 + shell)
    cx1 = min(door.x1 + gap, width / 2 - shell)
    cy0 = max(door.a0 - gap, feet_h + shell)
    cy1 = min(door.a1 + gap, height - shell)
    cavity_d = (depth - shell) * rng.uniform(0.7, 0.88)
    pieces = _door.cavity_body(-width / 2, width / 2, feet_h, height, -depth / 2, z_front, (cx0, cx1, cy0, cy1), cavity_d)
    turntable_r = min(cx1 - cx0, cavity_d) * rng.uniform(0.3, 0.45)
    pieces.append(m.along(m.cylinder(turntable_r, 0.006, 32), "y", ((cx0 + cx1) / 2, cy0 + 0.003, z_front - cavity_d / 2)))
    if feet_h > 0:
        pieces += m.feet(0.012, feet_h, width / 2 - 0.04, depth / 2 - 0.04)
    # control panel: display, a grid of buttons, dials, a door-release button
    y_display = height - (height - feet_h) * rng.uniform(0.15, 0.25)
    pieces.append(m.box([panel_w * 0.7, 0.025, 0.004], [panel_xc, y_display, z_front + 0.002]))
    handle = str(rng.choice(["bar", "grip", "button"], p=[0.4, 0.3, 0.3]))
    n_dials = int(rng.integers(0, 3))
    rows = int(rng.integers(2, 5)) if n_dials < 2 else 0
    items = ["buttons"] * rows + ["dial"] * n_dials + (["release"] if handle == "button" else [])
    ys = np.linspace(y_display - 0.03, feet_h + 0.03, len(items) + 1)[:-1] if items else []
    pitch = (y_display - feet_h - 0.06) / max(len(items), 1)  # vertical room per item
    button = min(panel_w / 5, 0.5 * pitch, 0.02)
    dial_r = min(panel_w * 0.3, 0.4 * pitch, 0.025)
    for item, y in zip(items, ys):
        y = y - pitch / 2
        if item == "buttons":
            for c in (-1, 0, 1):
                pieces.append(m.box([button, button * 0.7, 0.004], [panel_xc + c * 1.4 * button, y, z_front + 0.002]))
        elif item == "dial":
            pieces.append(m.transformed(_door.knob(dial_r, 0.015), translation=(panel_xc, y, z_front)))
        else:  # the door-release button
            pieces.append(m.box([panel_w * 0.6, min(0.02, 0.6 * pitch), 0.008], [panel_xc, y, z_front + 0.004]))
    base = Part("base", m.concat(pieces))

    # --- door: frame with a glass window; handle on the free edge --------------------------
    free_u = door_w if hinge == "left" else 0.0  # the free edge in door coordinates
    frame = rng.uniform(0.03, 0.06)
    door_pieces = [
        door.box([0.0, 0.0, 0.0], [door_w, door_h, door_t]),
        door.box([frame, frame, door_t], [door_w - frame, door_h - frame, door_t + 0.002]),  # window
    ]
    inward = -1.0 if hinge == "left" else 1.0  # from the free edge into the door
    if handle == "bar":
        length = door_h * rng.uniform(0.5, 0.8)
        pieces_h = _door.vertical_bar(length, rng.uniform(0.007, 0.012), rng.uniform(0.025, 0.04))
        door_pieces += [door.place(p, free_u + inward * 0.03, door_h / 2, door_t) for p in pieces_h]
    elif handle == "grip":
        grip_w = rng.uniform(0.015, 0.03)
        u0 = free_u + inward * grip_w
        door_pieces.append(door.box([min(u0, free_u), 0.1 * door_h, door_t], [max(u0, free_u), 0.9 * door_h, door_t + 0.02]))
    door_part = Part("door", m.concat(door_pieces))

    joint = door.joint("door_hinge", np.deg2rad(rng.uniform(85.0, 120.0)))
    return ArticulatedModel((base, door_part), (joint,), name=name, category="microwave")
