"""Measure the variation that matters in a category, on any instance: procedural or imported.

:func:`measure_instance` reads one articulated model in its canonical (NAOCS-oriented) frame at
the rest state and returns the quantities that tell the instances of a category apart (issue
#11): proportions, door size relative to the front face, hinge side, lid or front door,
door thickness, drawer count and layout, laptop thickness, temple length and drop.
:func:`summarize` turns many measurements into ranges (numbers) and shares (labels);
:func:`procedural_summary` does both for a procedural category; :func:`ranges_table` writes
summaries side by side (e.g. real objects beside the generator) as a Markdown table.

Everything is measured on the geometry (convex-hull vertices of each part), not on names, and
ratios are unitless, so objects in PartNet-Mobility's unit scale compare with metric ones; only
``width``, ``height``, ``depth`` and ``diagonal`` carry the model's units.

Keys of a measurement (all categories): ``width``, ``height``, ``depth``, ``diagonal`` (rest
box of every part; model units), ``height_over_width``, ``depth_over_width`` (the base's box).
Then, by the kind of moving part the convention names:

- a door (joint child ``door``): ``door_on`` (``"front"`` or ``"top"``), ``hinge``
  (``"left"``, ``"right"``, ``"bottom"``, ``"top"`` of a front door; ``"back"``, ``"front"``,
  ``"left"``, ``"right"`` of a lid; found from the door's least-moving points), ``door_width_frac``
  and ``door_length_frac`` (door box over the base's face: width, and height of a front door or
  depth of a lid), ``door_centre_height_frac`` (door centre above the base's bottom, over its
  height), ``door_thickness_frac`` (door box thickness, handles included, over the base's
  width), ``door_recess_frac`` (how far a front door reaches behind the base's front face, over the
  base's depth: 0 for a door on the face; the face is the plane holding most of the base's
  front-facing area around the door);
- drawers (prismatic joints): ``drawers`` (count), ``drawer_width_frac``,
  ``drawer_height_frac`` (mean drawer box over the base's width and height),
  ``drawer_column_x`` (mean drawer centre from the base's centre, over its width: 0 centred),
  ``drawers_bottom_frac``, ``drawers_top_frac`` (lowest and highest drawer edge over the base's
  height);
- a laptop display (child ``display``): ``base_thickness_frac`` (base height over width),
  ``display_thickness_frac`` (display thickness when closed over the base width),
  ``display_length_frac`` (closed display depth over the base depth);
- temples (``perpendicular`` joints): ``temple_length_ratio`` (temple extent along -z over the
  frame's width), ``temple_drop_ratio`` (temple height extent over the frame's width).
"""

from __future__ import annotations

from collections import Counter
from typing import Mapping, Sequence

import numpy as np

from ..model.articulated import ArticulatedModel
from .conventions import CategoryConvention, part_vertices_canonical

__all__ = ["measure_instance", "procedural_summary", "summarize"]

# Share of a door's points (least moving first) that locate its hinge line.
_HINGE_QUANTILE = 0.05
# A hinge line within this fraction of the door's box from one of its edges is on that edge.
_EDGE_FRACTION = 0.25
# Faces whose normal is within this cosine of +z face the front.
_FRONT_COS = 0.9
# Bin width of the front-plane search, as a fraction of the base's depth.
_PLANE_BIN = 0.01


def _box(v: np.ndarray) -> tuple:
    return v.min(axis=0), v.max(axis=0)


def measure_instance(model: ArticulatedModel, conv: CategoryConvention) -> dict:
    """The variation that matters in ``conv``'s category, measured on ``model`` (module docstring).

    Parameters
    ----------
    model : ArticulatedModel
        Any instance, procedural or imported, with ``R_canon_base`` giving its NAOCS orientation
        (+y up, +z front) and the rest state that ``conv`` defines; the base is part 0.
    conv : CategoryConvention
        The category's convention; it says which measurements apply (door, drawers, display,
        temples), not the model's structure: a model with another joint count is measured too.

    Returns
    -------
    dict
        ``str -> float`` (ratios unitless; sizes in the model's units) or ``str -> str`` (labels).
    """
    if not isinstance(model, ArticulatedModel):
        raise ValueError(f"model: expected an ArticulatedModel, got {type(model).__name__}")
    if not isinstance(conv, CategoryConvention):
        raise ValueError(f"conv: expected a CategoryConvention, got {type(conv).__name__}")
    rest = model.rest_states
    verts = part_vertices_canonical(model, rest)
    lo, hi = _box(np.concatenate(verts))
    b_lo, b_hi = _box(verts[model.base_index])
    base_ext = b_hi - b_lo
    out = {
        "width": float(hi[0] - lo[0]),
        "height": float(hi[1] - lo[1]),
        "depth": float(hi[2] - lo[2]),
        "diagonal": float(np.linalg.norm(hi - lo)),
        "height_over_width": float(base_ext[1] / base_ext[0]),
        "depth_over_width": float(base_ext[2] / base_ext[0]),
    }
    children = [model.joint_parts(k)[1] for k in range(model.num_joints)]
    kinds = {j.child for j in conv.joints}
    if "door" in kinds and model.num_joints:
        out.update(_door(model, verts, children[0], b_lo, b_hi))
    elif "display" in kinds and model.num_joints:
        out.update(_display(model, children[0], b_lo, b_hi))
    elif any(j.zero == "perpendicular" for j in conv.joints):
        out.update(_temples(verts, children, base_ext))
    elif any(not j.is_revolute for j in model.joints):
        drawers = [c for k, c in enumerate(children) if not model.joints[k].is_revolute]
        out.update(_drawers(verts, drawers, b_lo, b_hi))
    return out


def _front_plane(model, d_lo, d_hi) -> float:
    """``z`` of the base's front face around a front door at rest (canonical frame): the plane
    that holds the largest area of front-facing base triangles outside the door's outline
    ``d_lo``, ``d_hi`` (3,) (knobs and handles hold little area, the cavity hides behind the door)."""
    pose = model.forward_kinematics(model.rest_states)[model.base_index]
    mesh = model.parts[model.base_index].mesh
    R = model.R_canon_base
    normals = mesh.face_normals @ (R @ pose.rotation).T
    centres = pose.apply(mesh.triangles_center) @ R.T
    behind = np.all((centres[:, :2] > d_lo[:2]) & (centres[:, :2] < d_hi[:2]), axis=1)
    front = (normals[:, 2] > _FRONT_COS) & ~behind
    if not front.any():
        return float(centres[:, 2].max())
    z = centres[front, 2]
    step = _PLANE_BIN * max(float(np.ptp(centres[:, 2])), 1e-12)
    _, inverse = np.unique(np.round(z / step), return_inverse=True)
    area = np.bincount(inverse, weights=mesh.area_faces[front])
    return float(z[inverse == int(np.argmax(area))].max())


def _door(model, verts, child, b_lo, b_hi) -> dict:
    d_lo, d_hi = _box(verts[child])
    ext, base_ext = d_hi - d_lo, b_hi - b_lo
    on_top = int(np.argmin(ext)) == 1
    # the hinge line: the door's points that move least when it opens a little
    joint = model.joints[0]
    q = model.rest_states.copy()
    q[0] = min(joint.upper, q[0] + 0.2) if joint.upper > q[0] else max(joint.lower, q[0] - 0.2)
    moved = part_vertices_canonical(model, q)[child]
    still = verts[child][np.argsort(np.linalg.norm(moved - verts[child], axis=1))]
    hinge_at = (still[: max(2, int(_HINGE_QUANTILE * len(still)))].mean(axis=0) - d_lo) / np.maximum(ext, 1e-12)
    if on_top:
        labels = (("back", hinge_at[2] < _EDGE_FRACTION), ("front", hinge_at[2] > 1 - _EDGE_FRACTION),
                  ("left", hinge_at[0] < _EDGE_FRACTION), ("right", hinge_at[0] > 1 - _EDGE_FRACTION))
    else:
        labels = (("left", hinge_at[0] < _EDGE_FRACTION), ("right", hinge_at[0] > 1 - _EDGE_FRACTION),
                  ("bottom", hinge_at[1] < _EDGE_FRACTION), ("top", hinge_at[1] > 1 - _EDGE_FRACTION))
    hinge = next((name for name, hit in labels if hit), "inside")
    length_axis = 2 if on_top else 1
    thickness = ext[1] if on_top else ext[2]
    out = {
        "door_on": "top" if on_top else "front",
        "hinge": hinge,
        "door_width_frac": float(ext[0] / base_ext[0]),
        "door_length_frac": float(ext[length_axis] / base_ext[length_axis]),
        "door_centre_height_frac": float(((d_lo[1] + d_hi[1]) / 2 - b_lo[1]) / base_ext[1]),
        "door_thickness_frac": float(thickness / base_ext[0]),
    }
    if not on_top:
        z_face = _front_plane(model, d_lo, d_hi)
        out["door_recess_frac"] = float(max(z_face - d_lo[2], 0.0) / base_ext[2])
    return out


def _display(model, child, b_lo, b_hi) -> dict:
    base_ext = b_hi - b_lo
    q = np.clip(np.zeros(model.num_joints), model.lower_limits, model.upper_limits)
    closed = part_vertices_canonical(model, q)[child]
    c_lo, c_hi = _box(closed)
    return {
        "base_thickness_frac": float(base_ext[1] / base_ext[0]),
        "display_thickness_frac": float((c_hi - c_lo)[1] / base_ext[0]),
        "display_length_frac": float((c_hi - c_lo)[2] / base_ext[2]),
    }


def _temples(verts, children, base_ext) -> dict:
    ext = np.array([np.ptp(verts[c], axis=0) for c in children])
    return {
        "temple_length_ratio": float(ext[:, 2].mean() / base_ext[0]),
        "temple_drop_ratio": float(ext[:, 1].mean() / base_ext[0]),
    }


def _drawers(verts, drawers, b_lo, b_hi) -> dict:
    base_ext = b_hi - b_lo
    boxes = np.array([_box(verts[c]) for c in drawers])  # (n, 2, 3)
    ext = boxes[:, 1] - boxes[:, 0]
    centre_x = (boxes[:, 0, 0] + boxes[:, 1, 0]) / 2
    return {
        "drawers": float(len(drawers)),
        "drawer_width_frac": float(ext[:, 0].mean() / base_ext[0]),
        "drawer_height_frac": float(ext[:, 1].mean() / base_ext[1]),
        "drawer_column_x": float((centre_x.mean() - (b_lo[0] + b_hi[0]) / 2) / base_ext[0]),
        "drawers_bottom_frac": float((boxes[:, 0, 1].min() - b_lo[1]) / base_ext[1]),
        "drawers_top_frac": float((boxes[:, 1, 1].max() - b_lo[1]) / base_ext[1]),
    }


def summarize(measurements: Sequence[Mapping]) -> dict:
    """Ranges and shares over many :func:`measure_instance` results.

    Parameters
    ----------
    measurements : sequence of dict
        At least one; keys may differ between them (each key is summarised over the
        measurements that have it).

    Returns
    -------
    dict
        ``key -> {"n", "min", "median", "max"}`` for numbers, ``key -> {"n", "shares": {label:
        fraction}}`` for labels (shares sorted by label), keys in first-seen order.
    """
    measurements = list(measurements)
    if not measurements:
        raise ValueError("measurements: need at least one measurement to summarise")
    keys = list(dict.fromkeys(k for mm in measurements for k in mm))
    out = {}
    for key in keys:
        values = [mm[key] for mm in measurements if key in mm]
        if all(isinstance(v, str) for v in values):
            counts = Counter(values)
            out[key] = {"n": len(values), "shares": {k: counts[k] / len(values) for k in sorted(counts)}}
        else:
            v = np.asarray(values, dtype=np.float64)
            out[key] = {"n": len(values), "min": float(v.min()), "median": float(np.median(v)), "max": float(v.max())}
    return out


def procedural_summary(category: str, n: int, split: str = "train") -> dict:
    """:func:`summarize` of the first ``n`` instances of ``split`` of a procedural ``category``."""
    from .conventions import convention
    from .procedural import instance_seeds, make_object

    seeds = instance_seeds(category, split)
    if isinstance(n, bool) or not isinstance(n, int) or not 0 < n <= len(seeds):
        raise ValueError(f"n: expected an int in [1, {len(seeds)}] for split {split!r}, got {n!r}")
    conv = convention(category)
    return summarize([measure_instance(make_object(category, s), conv) for s in seeds[:n]])
