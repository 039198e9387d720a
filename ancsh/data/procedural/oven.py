"""Oven: body (base) and a door on a revolute hinge along its bottom edge or one side.

Frame: body floor centre at the origin, +y up, +z towards the door, +x right. Three styles:
a freestanding range (cooktop, knobs above the door), a built-in wall oven and a countertop
oven (control column beside the door). The body is hollow behind the door (a cavity with a
rack). Joint state = door opening angle: 0 closed (rest), the door's free edge swings forward
(a bottom-hinged door's top edge forward and down), upper limit 80-95 degrees (side doors
85-120).

Door variants (the issue #11 failures: small upper doors, side-hinged doors; the shared
PartNet-Mobility oven has a bottom-hinged door over 0.65 of the front's height):

- ``full`` (60 %): bottom-hinged, filling the front below the controls;
- ``upper`` (20 %, range and wall styles): a small bottom-hinged door, 0.28-0.45 of the height,
  in the upper part of the front above a fixed lower panel (a storage drawer front);
- ``side`` (20 %, wall and countertop styles): hinged on the left or right side (even odds).

Changing the variants (issue #11) changed every instance of a seed; the split is unchanged.
"""

from __future__ import annotations

import numpy as np

from ...model.articulated import ArticulatedModel, Part
from ..conventions import convention
from . import _door
from . import _mesh as m

INFO = convention("oven")  # the category's one definition (ancsh.data.conventions)

_STYLES = {  # width, height, depth ranges (metres)
    "range": ((0.50, 0.76), (0.85, 0.95), (0.55, 0.66)),
    "wall": ((0.55, 0.76), (0.45, 0.72), (0.50, 0.60)),
    "countertop": ((0.40, 0.56), (0.25, 0.38), (0.30, 0.45)),
}
#: Door variants, their probabilities and the styles they apply to.
_DOORS = {"full": 0.6, "upper": 0.2, "side": 0.2}
_DOOR_STYLES = {"full": tuple(_STYLES), "upper": ("range", "wall"), "side": ("wall", "countertop")}


def _knobs(rng, n, xs_range, y, z_face, radius) -> list:
    xs = np.linspace(*xs_range, n) if n > 1 else [np.mean(xs_range)]
    length = rng.uniform(0.015, 0.03)
    return [m.along(m.cylinder(radius, length, 16), "z", (x, y, z_face + length / 2)) for x in xs]


def build(rng: np.random.Generator, name: str) -> ArticulatedModel:
    variant = str(rng.choice(list(_DOORS), p=list(_DOORS.values())))
    style = str(rng.choice(_DOOR_STYLES[variant]))
    (w0, w1), (h0, h1), (d0, d1) = _STYLES[style]
    width, height, depth = rng.uniform(w0, w1), rng.uniform(h0, h1), rng.uniform(d0, d1)
    scale = height / 0.9 if style != "range" else 1.0
    wall = rng.uniform(0.02, 0.045) * min(1.0, 0.5 + width)
    feet_h = rng.choice([0.0, rng.uniform(0.01, 0.03) * (0.5 if style == "countertop" else 1.5)])
    z_front = depth / 2

    # --- layout of the front: door rectangle and control area --------------------------
    x_door0, x_door1 = -width / 2 + 0.005, width / 2 - 0.005
    if style == "countertop":
        panel_w = width * rng.uniform(0.2, 0.3)
        x_door1 = width / 2 - panel_w
        door_y0 = feet_h + rng.uniform(0.01, 0.03)
        door_y1 = height - rng.uniform(0.01, 0.03)
    else:
        panel_h = rng.uniform(0.08, 0.16) * (1.0 if style == "range" else 0.8)
        door_y0 = feet_h + (rng.uniform(0.08, 0.18) if style == "range" else rng.uniform(0.02, 0.06))
        door_y1 = height - panel_h
    lower_panel = None
    if variant == "upper":  # a small door high up; a fixed drawer front below it
        door_y0_full = door_y0
        door_y0 = door_y1 - (height - feet_h) * rng.uniform(0.28, 0.45)
        lower_panel = (door_y0_full, door_y0 - rng.uniform(0.01, 0.02))
    door_w, door_h = x_door1 - x_door0, door_y1 - door_y0
    door_t = rng.uniform(0.03, 0.06) * (0.6 if style == "countertop" else 1.0)
    hinge = "bottom" if variant != "side" else str(rng.choice(["left", "right"]))
    door = _door.DoorFrame(x_door0, x_door1, door_y0, door_y1, z_front, door_t, hinge)

    # --- body with a cavity behind the door --------------------------------------------
    cav_x0, cav_x1 = x_door0 + wall, x_door1 - wall
    cav_y0, cav_y1 = door_y0 + wall, door_y1 - wall
    cav_d = (depth - 2 * wall) * rng.uniform(0.75, 0.92)
    zc = z_front - cav_d  # cavity back
    y_body0 = feet_h
    pieces = _door.cavity_body(-width / 2, width / 2, y_body0, height, -depth / 2, z_front, (cav_x0, cav_x1, cav_y0, cav_y1), cav_d)
    if lower_panel is not None:
        y_a, y_b = lower_panel
        pieces.append(m.box_between([x_door0, y_a, z_front], [x_door1, y_b, z_front + 0.01]))
        pieces += [m.transformed(p, translation=(0.0, (y_a + y_b) / 2, z_front + 0.01)) for p in m.bar_handle(0.5 * door_w, 0.008, 0.025)]
    rack_y = cav_y0 + (cav_y1 - cav_y0) * rng.uniform(0.3, 0.6)
    pieces.append(m.box_between([cav_x0, rack_y, zc], [cav_x1, rack_y + 0.006, z_front - 0.04]))
    if feet_h > 0:
        r = rng.uniform(0.01, 0.02)
        pieces += m.feet(r, feet_h, width / 2 - 0.04, depth / 2 - 0.04)
    knob_r = rng.uniform(0.012, 0.025) * (0.7 if style == "countertop" else 1.0)
    if style == "countertop":
        n = int(rng.integers(2, 4))
        x_mid = (x_door1 + width / 2) / 2
        for k in range(n):
            y = door_y1 - (k + 0.7) * (door_h / (n + 0.4))
            pieces += _knobs(rng, 1, (x_mid, x_mid), y, z_front, knob_r)
    else:
        n = int(rng.integers(2, 7))
        y = (door_y1 + height) / 2
        pieces += _knobs(rng, n, (-width / 2 + 0.08, width / 2 - 0.08), y, z_front, knob_r)
        if rng.random() < 0.5:  # display
            pieces.append(m.box([0.08, 0.03, 0.006], [0.0, y, z_front + 0.003]))
    if style == "range":
        if rng.random() < 0.5:  # coil/gas burners
            for sx in (-1, 1):
                for sz in (-1, 1):
                    r = rng.uniform(0.06, 0.1)
                    c = (sx * width / 4, height + 0.006, sz * depth / 4)
                    pieces.append(m.along(m.cylinder(r, 0.012, 24), "y", c))
        else:  # glass top
            pieces.append(m.box_between([-width / 2, height, -depth / 2], [width / 2, height + 0.006, depth / 2]))
        if rng.random() < 0.5:  # backguard
            bg_h = rng.uniform(0.05, 0.15)
            pieces.append(m.box_between([-width / 2, height, -depth / 2], [width / 2, height + bg_h, -depth / 2 + 0.03]))
    base = Part("base", m.concat(pieces))

    # --- door (child frame: origin on the hinge line, axes as the body at q = 0) --------
    # pieces built centred on x = 0, y in [0, door_h], z in [0, door_t], then placed on the door
    corner = rng.uniform(0.002, 0.03)
    handle = str(rng.choice(["bar", "lip", "none"] if style == "countertop" else ["bar", "bar", "lip"]))
    if rng.random() < 0.75:  # window
        win_w = door_w * rng.uniform(0.5, 0.8)
        top_space = 0.12 if handle == "bar" and hinge == "bottom" else 0.06
        win_h = min(door_h * rng.uniform(0.4, 0.7), door_h - top_space - 0.04)
        win_yc = (door_h - top_space) / 2 + rng.uniform(-0.01, 0.01) * scale
        outer = m.outline_rounded_rect(door_w, door_h, corner, 64, center=(0.0, door_h / 2 - win_yc))
        inner = m.outline_rounded_rect(win_w, win_h, corner * 0.5, 64)
        frame = m.transformed(m.ring_prism(outer, inner, door_t), translation=(0.0, win_yc, door_t / 2))
        glass_t = door_t * rng.uniform(0.2, 0.5)
        glass = m.box([win_w, win_h, glass_t], [0.0, win_yc, glass_t / 2])
        door_pieces = [frame, glass]
    else:
        outline = m.outline_rounded_rect(door_w, door_h, corner, 64)
        door_pieces = [m.transformed(m.prism(outline, door_t), translation=(0.0, door_h / 2, door_t / 2))]
    door_pieces = [door.place(p, door_w / 2, 0.0, 0.0) for p in door_pieces]
    if hinge == "bottom":  # handle along the top edge
        if handle == "bar":
            length = door_w * rng.uniform(0.6, 0.9)
            bar = m.bar_handle(length, rng.uniform(0.008, 0.014), rng.uniform(0.03, 0.05))
            door_pieces += [door.place(p, door_w / 2, door_h - rng.uniform(0.03, 0.06), door_t) for p in bar]
        elif handle == "lip":
            lip_h = rng.uniform(0.015, 0.03)
            lip_w = door_w * rng.uniform(0.5, 0.95)
            door_pieces.append(door.box([(door_w - lip_w) / 2, door_h - lip_h, door_t], [(door_w + lip_w) / 2, door_h, door_t + 0.025]))
    elif handle != "none":  # side door: a vertical handle along the free edge
        free_u = door_w - 0.035 if hinge == "left" else 0.035
        bar = _door.vertical_bar(door_h * rng.uniform(0.4, 0.7), rng.uniform(0.008, 0.014), rng.uniform(0.025, 0.04))
        door_pieces += [door.place(p, free_u, door_h / 2, door_t) for p in bar]
    door_part = Part("door", m.concat(door_pieces))

    upper = rng.uniform(80.0, 95.0) if hinge == "bottom" else rng.uniform(85.0, 120.0)
    joint = door.joint("door_hinge", np.deg2rad(upper))
    return ArticulatedModel((base, door_part), (joint,), name=name, category="oven")
