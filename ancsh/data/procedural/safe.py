"""Safe: a thick-walled body (base) with a shelved compartment and a heavy door on a vertical side hinge.

Frame: body floor centre at the origin, +y up, +z towards the door, +x right. Joint state =
door opening angle: 0 closed (rest), the free edge swings towards +z, upper limit 100-175
degrees.

Variation (calibrated on the 15 PartNet-Mobility safes, all hinged on the right, height :
width 0.9-2.2, depth : width 0.6-1.6, door 0.78-0.92 of the front in both directions, door
thickness 2-25 % of the width):

- hinge side: right (75 %) or left (25 %);
- style: a cube-like home safe (60 %, height : width 0.9-1.45, rest diagonal 0.42-0.95 m) or a
  tall cabinet safe (40 %, height : width 1.55-2.2, diagonal 0.9-1.3 m);
- door inset in the frame, flush with the front (50 %), or standing on it; thickness 3-22 %
  of the width;
- door hardware: a spoke wheel (40 %), a lever (35 %) or a knob (25 %) beside a dial or a
  keypad; hinge barrels on the body beside the door (50 %); a plinth (30 %).
"""

from __future__ import annotations

import numpy as np

from ...model.articulated import ArticulatedModel, Part
from ..conventions import convention
from . import _door
from . import _mesh as m

INFO = convention("safe")  # the category's one definition (ancsh.data.conventions)

_STYLES = {  # height : width range, body diagonal range (metres)
    "cube": ((0.9, 1.45), (0.42, 0.95)),
    "tall": ((1.55, 2.2), (0.9, 1.3)),
}


def build(rng: np.random.Generator, name: str) -> ArticulatedModel:
    style = "cube" if rng.random() < 0.6 else "tall"
    h_over_w, diagonal = _STYLES[style]
    shape = np.array([1.0, rng.uniform(*h_over_w), rng.uniform(0.6, 1.2)])
    width, height, depth = shape * rng.uniform(*diagonal) / np.linalg.norm(shape)
    hinge = "right" if rng.random() < 0.75 else "left"
    sign = 1.0 if hinge == "right" else -1.0
    plinth_h = float(rng.uniform(0.02, 0.06)) if rng.random() < 0.3 else 0.0
    inset = bool(rng.random() < 0.5)
    z_front = depth / 2

    # --- door rectangle on the front, thick walls around it --------------------------------
    door_w = width * rng.uniform(0.78, 0.92)
    door_h = (height - plinth_h) * rng.uniform(0.78, 0.92)
    door_t = min(width * rng.uniform(0.03, 0.22), 0.4 * depth)
    x_c = -sign * (width - door_w) * rng.uniform(0.0, 0.15)  # centred or a little away from the hinge
    y0 = plinth_h + (height - plinth_h - door_h) / 2
    door = _door.DoorFrame(x_c - door_w / 2, x_c + door_w / 2, y0, y0 + door_h, z_front, door_t, hinge, inset)

    # --- body: thick walls and a compartment with shelves ----------------------------------
    gap = 0.003 if inset else -0.02 * width  # opening around (inset) or inside the door's outline
    ox0, ox1, oy0, oy1 = door.x0 - gap, door.x1 + gap, door.a0 - gap, door.a1 + gap
    compartment_d = (depth - 0.04 * width) * rng.uniform(0.8, 0.95)
    pieces = _door.cavity_body(-width / 2, width / 2, plinth_h, height, -depth / 2, z_front, (ox0, ox1, oy0, oy1), compartment_d)
    z_back = z_front - compartment_d
    z_shelf = z_front - (door_t if inset else 0.0) - 0.01
    n_shelves = int(rng.integers(0, 4))
    for y in oy0 + (oy1 - oy0) * np.arange(1, n_shelves + 1) / (n_shelves + 1):
        pieces.append(m.box_between([ox0, y, z_back], [ox1, y + 0.01, z_shelf]))
    if plinth_h > 0:
        pieces.append(m.box_between([-width / 2 + 0.01, 0.0, -depth / 2 + 0.01], [width / 2 - 0.01, plinth_h, z_front - 0.02]))
    if rng.random() < 0.5:  # hinge barrels on the body, just beside the door's hinge edge
        barrel_r = min(0.012, 0.3 * (width / 2 - abs(door.pivot[0])) + 0.004)
        x_b = door.pivot[0] + sign * barrel_r
        for y in (door.a0 + 0.15 * door_h, door.a1 - 0.15 * door_h):
            pieces.append(m.along(m.cylinder(barrel_r, 0.08 * door_h, 12), "y", (x_b, y, z_front + barrel_r)))
    base = Part("base", m.concat(pieces))

    # --- door: slab, lock (dial or keypad) and handle, both towards the free edge ------------
    free_u = 0.0 if hinge == "right" else door_w
    inward = 1.0 if hinge == "right" else -1.0
    u_hw = free_u + inward * door_w * rng.uniform(0.22, 0.32)  # hardware column
    door_pieces = [door.box([0.0, 0.0, 0.0], [door_w, door_h, door_t])]
    if rng.random() < 0.5:  # raised panel
        border = 0.08 * min(door_w, door_h)
        door_pieces.append(door.box([border, border, door_t], [door_w - border, door_h - border, door_t + 0.006]))
    size = min(door_w, door_h)
    if rng.random() < 0.5:
        dial = _door.knob(size * rng.uniform(0.06, 0.1), rng.uniform(0.015, 0.03))
        door_pieces.append(door.place(dial, u_hw, door_h * 0.65, door_t))
    else:
        keypad = m.box([size * 0.14, size * 0.18, 0.012], [0.0, 0.0, 0.006])
        door_pieces.append(door.place(keypad, u_hw, door_h * 0.65, door_t))
    handle = str(rng.choice(["wheel", "lever", "knob"], p=[0.4, 0.35, 0.25]))
    if handle == "wheel":
        door_pieces += [door.place(p, u_hw, door_h * 0.4, door_t) for p in _door.spoke_wheel(size * rng.uniform(0.1, 0.16), rng)]
    elif handle == "lever":
        bar = m.bar_handle(size * rng.uniform(0.15, 0.25), 0.01, rng.uniform(0.025, 0.04))
        door_pieces += [door.place(p, u_hw, door_h * 0.4, door_t) for p in bar]
    else:
        door_pieces.append(door.place(_door.knob(size * 0.05, 0.03), u_hw, door_h * 0.4, door_t))
    door_part = Part("door", m.concat(door_pieces))

    joint = door.joint("door_hinge", np.deg2rad(rng.uniform(100.0, 175.0)))
    return ArticulatedModel((base, door_part), (joint,), name=name, category="safe")
