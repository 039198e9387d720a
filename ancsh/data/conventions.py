"""Category conventions: one definition per category, obeyed by procedural and imported objects.

A :class:`CategoryConvention` says what an instance of a category is in ANCSH terms:

- the canonical (NAOCS) axes, shared by every category: +y up, +z towards the object's front
  (the side a user faces), +x to the right as seen from the front;
- the part roles in label order (base first) and the joint tree (one joint per moving part,
  its type, parent and child role);
- for each joint, what state 0 *means* geometrically (``zero``), which way the state grows
  (``positive``), the rest state that defines NAOCS (``rest``, in that parameterisation) and the
  side of the base the moving part sits on at rest (``side``);
- how moving parts of the same kind are ordered (eyeglasses: left temple first, by NAOCS x;
  drawers: lowest first, by NAOCS y);
- the size range (rest-state box diagonal, metres) and the PartNet-Mobility names that map to
  the category and its moving parts.

Each category is written in a spec file (:mod:`ancsh.data.category_spec`, ``docs/category_spec.md``):
the built-in ones in ``ancsh/data/specs/``, others given as a file or a built category folder
(``--category DIR``, :func:`register_category`) or found on the search path ``ANCSH_CATEGORIES``.
:data:`CONVENTIONS` holds them all.

The procedural generators (:mod:`ancsh.data.procedural`) are written to these definitions and
the URDF importer (:mod:`ancsh.data.importer`) maps any object onto them. Both are checked by
:func:`convention_violations`, which measures the rules on the geometry (it does not trust
names): the state-0 rule, the positive direction, the side, the part order, the orientation and
the size range.

Geometric rules (``JointConvention.zero``)
-----------------------------------------
``"closed"``
    State 0 is where the moving part is shut against the base: a door or drawer flush with the
    front, a laptop display lying on the keyboard. Measured as the state, within the limits,
    that minimises the volume of the canonical axis-aligned box around the base and the part,
    among the states where a revolute part is aligned with the canonical axes
    (:data:`CLOSED_ALIGNMENT_FACTOR`: a door swung into the body, which some files' limits
    allow, makes a smaller box but is not closed).
``"perpendicular"``
    State 0 is where the part's long axis is perpendicular to the base's front face (an
    eyeglasses temple opened at right angles), on the convention's ``side``.

``JointConvention.positive``: ``"opens"`` (the box around base and part grows as the state
increases from 0: doors, drawers, displays) or ``"folds"`` (the part's far end comes closer to
the base's centre line as the state increases: temples folding inwards).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..model.articulated import ArticulatedModel, JointType
from . import category_spec
from .category_types import ORDER_AXES, CategoryConvention, JointConvention

__all__ = [
    "CONVENTIONS",
    "UP",
    "FRONT",
    "RIGHT",
    "CategoryConvention",
    "JointConvention",
    "box_volume",
    "category_folder",
    "convention",
    "convention_violations",
    "is_category_path",
    "part_vertices_canonical",
    "register_category",
    "resolve_category",
    "rest_diagonal",
]

#: Canonical axes shared by every category (NAOCS orientation).
RIGHT = np.array([1.0, 0.0, 0.0])
UP = np.array([0.0, 1.0, 0.0])
FRONT = np.array([0.0, 0.0, 1.0])

REVOLUTE, PRISMATIC = JointType.REVOLUTE, JointType.PRISMATIC


class _Registry(Mapping):
    """``name -> CategoryConvention``: the built-in categories (their spec files in ``ancsh/data/specs/``), then the
    categories on the search path (:data:`ancsh.data.category_spec.SEARCH_PATH_VARIABLE`, read again when it changes;
    :func:`register_category` adds to it, so worker processes started later know the same categories)."""

    def __init__(self):
        self._builtin = {}
        for path in category_spec.builtin_spec_paths():
            conv = category_spec.load_spec(path)
            self._builtin[conv.name] = dataclasses.replace(conv, spec_path=None)
        self._searched = (None, {})

    def _search(self) -> dict:
        value = os.environ.get(category_spec.SEARCH_PATH_VARIABLE, "")
        if self._searched[0] != value:
            found = {}
            for path in category_spec.search_path_specs(value):
                conv = category_spec.load_spec(path)
                _check_new(conv, {**self._builtin, **found})
                found[conv.name] = conv
            self._searched = (value, found)
        return self._searched[1]

    def __getitem__(self, name):
        if name in self._builtin:
            return self._builtin[name]
        return self._search()[name]

    def __contains__(self, name):
        return name in self._builtin or name in self._search()

    def __iter__(self):
        return iter([*self._builtin, *(n for n in self._search() if n not in self._builtin)])

    def __len__(self):
        return len(self._builtin) + len(set(self._search()) - set(self._builtin))

    @property
    def builtin(self) -> tuple:
        """Names of the built-in categories, in their listed order."""
        return tuple(self._builtin)


def _same_definition(a: CategoryConvention, b: CategoryConvention) -> bool:
    """Whether two conventions define the same category (a spec file and the folder built from it)."""
    return dataclasses.replace(a, spec_path=None, folder=None) == dataclasses.replace(b, spec_path=None, folder=None)


def _check_new(conv: CategoryConvention, known: dict) -> None:
    """Refuse a category whose name another definition holds (the same definition from another file -- a spec and
    the category folder built from it -- is the same category: the later one is used)."""
    old = known.get(conv.name)
    builtin = old is not None and old.spec_path is None
    if old is not None and old.spec_path != conv.spec_path and (builtin or not _same_definition(old, conv)):
        where = "a built-in category" if old.spec_path is None else f"the category of {old.spec_path}"
        raise category_spec.SpecError(f"{conv.spec_path}: name: {conv.name!r} is already {where}; give it another name")


#: ``CONVENTIONS[name]`` -> :class:`CategoryConvention`: every category with a convention (the built-in ones, read
#: from their spec files, then the search path's and the registered ones).
CONVENTIONS = _Registry()


def category_folder(category: str) -> Path | None:
    """The folder of a built category (its spec, weights, calibrations, template, catalog); ``None`` for a
    built-in category or an unknown name."""
    conv = CONVENTIONS.get(category) if isinstance(category, str) else None
    return None if conv is None or conv.folder is None else Path(conv.folder)


def register_category(path) -> CategoryConvention:
    """Read a category spec file or a built category folder and make its category known in this process and the
    processes it starts (it joins the search path, :data:`~ancsh.data.category_spec.SEARCH_PATH_VARIABLE`).

    Parameters
    ----------
    path : str or Path
        A spec file (``.toml``) or a category folder holding ``category.toml``.

    Returns
    -------
    CategoryConvention
        With ``folder`` set for a category folder.

    Raises
    ------
    ancsh.data.category_spec.SpecError
        The spec is wrong (naming the file and the key), or its name is another category's.
    """
    conv = category_spec.load_spec(path)
    known = CONVENTIONS._search()
    _check_new(conv, {**CONVENTIONS._builtin, **known})
    if conv.name not in known or known[conv.name].spec_path != conv.spec_path:
        entry = str(Path(conv.folder if conv.folder is not None else conv.spec_path).resolve())
        value = os.environ.get(category_spec.SEARCH_PATH_VARIABLE, "")
        os.environ[category_spec.SEARCH_PATH_VARIABLE] = os.pathsep.join(filter(None, [value, entry]))
    return CONVENTIONS[conv.name]


def is_category_path(category: str) -> bool:
    """Whether a ``--category`` value names a spec file or a category folder rather than a category."""
    text = str(category)
    return text.endswith(".toml") or os.sep in text or (os.altsep is not None and os.altsep in text) or \
        Path(text).is_dir()


def resolve_category(category) -> str:
    """The category name of a ``--category`` value: a known name as it is, a spec file or category folder
    registered (:func:`register_category`) and its name returned.

    Raises
    ------
    ValueError
        An unknown name (listing the known ones) or a wrong spec (:class:`~ancsh.data.category_spec.SpecError`).
    """
    if isinstance(category, CategoryConvention):
        return category.name
    if not isinstance(category, (str, os.PathLike)):
        raise ValueError(f"category: expected a category name, a spec file or a category folder, got {category!r}")
    if isinstance(category, str) and category in CONVENTIONS:
        return category
    if is_category_path(category):
        return register_category(category).name
    return convention(str(category)).name


def convention(category: str) -> CategoryConvention:
    """The convention of ``category``; ``ValueError`` naming the known ones otherwise."""
    if category not in CONVENTIONS:
        raise ValueError(f"category: no convention for {category!r}; known: {', '.join(CONVENTIONS)} (or give a "
                         f"category spec file or folder; the search path {category_spec.SEARCH_PATH_VARIABLE})")
    return CONVENTIONS[category]


# --- geometric measurements ------------------------------------------------------------------
def part_vertices_canonical(model: ArticulatedModel, q) -> list:
    """Each part's vertices at joint states ``q`` in the canonically rotated base frame.

    Returns
    -------
    list of (V_i, 3) float64
        Base frame rotated by ``model.R_canon_base`` (+y up, +z front); the model's units.
    """
    poses = model.forward_kinematics(q)
    R = model.R_canon_base
    return [poses[i].apply(_hull_vertices(p)) @ R.T for i, p in enumerate(model.parts)]


def _hull_vertices(part) -> np.ndarray:
    """The part's convex-hull vertices (the same axis-aligned boxes under any rotation, fewer points)."""
    cache = getattr(part, "_hull_cache", None)
    if cache is None:
        v = part.vertices
        try:
            cache = np.asarray(part.mesh.convex_hull.vertices, dtype=np.float64) if len(v) > 64 else v
        except Exception:  # noqa: BLE001 - qhull fails on flat parts: keep every vertex
            cache = v
        object.__setattr__(part, "_hull_cache", cache)
    return cache


def box_volume(*vertex_sets) -> float:
    """Volume of the axis-aligned box around all given ``(V, 3)`` vertex sets."""
    v = np.concatenate(vertex_sets)
    return float(np.prod(v.max(axis=0) - v.min(axis=0)))


def rest_diagonal(model: ArticulatedModel) -> float:
    """Diagonal of the axis-aligned box of all parts at the rest state (model units)."""
    v = np.concatenate(part_vertices_canonical(model, model.rest_states))
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))


def _with_state(model, k, value):
    q = model.rest_states.copy()
    q[k] = value
    return q


def _joint_pair(model, k, q):
    verts = part_vertices_canonical(model, q)
    parent, child = model.joint_parts(k)
    return verts[model.base_index], verts[child]


def _long_axis(v: np.ndarray) -> np.ndarray:
    c = v - v.mean(axis=0)
    return np.linalg.svd(c, full_matrices=False)[2][0]


def _horizontal_angle_to_front_deg(v: np.ndarray) -> float:
    """Angle (degrees) between the horizontal part of ``v``'s long axis and the front axis
    (temples may bend down at the ear: only their course in the horizontal plane counts)."""
    a = _long_axis(v)
    h = np.hypot(a[0], a[2])
    return 90.0 if h < 1e-12 else float(np.degrees(np.arccos(min(1.0, abs(a[2]) / h))))


def _side_ok(base_v, child_v, sides) -> bool:
    b_lo, b_hi = base_v.min(axis=0), base_v.max(axis=0)
    offset = child_v.mean(axis=0) - (b_lo + b_hi) / 2
    half = np.maximum((b_hi - b_lo) / 2, 1e-9)
    rel = offset / half
    checks = {"front": rel[2] > 0.0, "back": rel[2] < 0.0, "top": rel[1] > 0.5}
    return any(checks[s] for s in sides)


def convention_violations(model: ArticulatedModel, conv: CategoryConvention, *, units_metres: bool = True,
                          rel_tol: float = 0.02, angle_tol_deg: float = 12.0) -> list[str]:
    """Every way ``model`` breaks ``conv``, measured on its geometry; empty when it obeys.

    Parameters
    ----------
    model : ArticulatedModel
    conv : CategoryConvention
    units_metres : bool
        Check the rest diagonal against :attr:`CategoryConvention.diagonal_range`.
    rel_tol : float
        Relative tolerance of the ``closed`` rule: no state within the limits may shrink the
        box around base and part by more than this fraction below state 0.
    angle_tol_deg : float
        Tolerance of the ``perpendicular`` rule (degrees).

    Returns
    -------
    list of str
        One sentence per violation.
    """
    out = []
    if tuple(model.part_names) != conv.part_names:
        out.append(f"parts {tuple(model.part_names)} are not {conv.part_names}")
        return out
    if tuple(j.name for j in model.joints) != conv.joint_names:
        out.append(f"joints {tuple(j.name for j in model.joints)} are not {conv.joint_names}")
        return out
    if model.base_index != 0:
        out.append(f"the base is part {model.base_index}, not part 0")
        return out
    for k, (joint, jc) in enumerate(zip(model.joints, conv.joints)):
        if joint.type != jc.type:
            out.append(f"joint {joint.name!r} is {joint.type.value}, expected {jc.type.value}")
            continue
        if (joint.parent, joint.child) != (jc.parent, jc.child):
            out.append(f"joint {joint.name!r} connects {joint.parent}->{joint.child}, expected {jc.parent}->{jc.child}")
            continue
        if abs(joint.rest - jc.rest) > 1e-9:
            out.append(f"joint {joint.name!r} rest {joint.rest:.4g}, expected {jc.rest:.4g}")
        if not joint.lower <= 0.0 <= joint.upper:
            out.append(f"joint {joint.name!r}: state 0 ({jc.zero}) is outside the limits [{joint.lower:.4g}, {joint.upper:.4g}]")
            continue
        out.extend(_joint_rule_violations(model, k, jc, rel_tol, angle_tol_deg))
    if conv.order_by is not None and model.num_parts > 2:
        axis = ORDER_AXES[conv.order_by]
        verts = part_vertices_canonical(model, model.rest_states)
        centres = [verts[i].mean(axis=0)[axis] for i in range(1, model.num_parts)]
        if any(b <= a for a, b in zip(centres, centres[1:])):
            out.append(f"moving parts are not ordered by ascending NAOCS {conv.order_by}: centres {np.round(centres, 4).tolist()}")
    if units_metres:
        lo, hi = conv.diagonal_range
        d = rest_diagonal(model)
        if not lo * (1 - 1e-6) <= d <= hi * (1 + 1e-6):
            out.append(f"rest diagonal {d:.3f} m is outside the category's range [{lo}, {hi}] m")
    return out


#: A revolute part counts as closed only where it is *aligned* with the canonical axes: its own
#: axis-aligned box at most this factor above the smallest it takes over a full turn about the
#: joint (a door in the front face's plane, a display on the keyboard). This keeps a door swung
#: *into* the body (some files' limits allow it, and it makes a smaller box) from counting as
#: closed. A thin door 0.25 deg off alignment is ~9 % above its smallest box, a cube-like one 5 deg
#: off ~22 %; swung in by 0.5 rad any door is far above.
CLOSED_ALIGNMENT_FACTOR = 1.25
_TURN_SAMPLES = 721
_LIMIT_SAMPLES = 121


def _child_vertices_at(model, k, qs) -> np.ndarray:
    """Hull vertices of joint ``k``'s child at each state ``qs`` (other joints at rest), in the
    canonically rotated base frame, all states at once; the limits do not apply (a geometry probe).

    Returns
    -------
    (Q, V, 3) float64
        Model units.
    """
    qs = np.asarray(qs, dtype=np.float64)
    poses = model.forward_kinematics(model.rest_states)
    parent, child = model.joint_parts(k)
    joint = model.joints[k]
    v = joint.origin.apply(_hull_vertices(model.parts[child]))  # parent frame at state 0
    if joint.is_revolute:  # Rodrigues for every state: rotation about the axis through the pivot
        a = joint.axis
        K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
        s, c = np.sin(qs)[:, None, None], np.cos(qs)[:, None, None]
        R = np.eye(3) + s * K + (1.0 - c) * (K @ K)
        moved = np.einsum("qij,vj->qvi", R, v - joint.pivot) + joint.pivot
    else:
        moved = v[None] + qs[:, None, None] * joint.axis
    T = poses[parent]
    return (T.scale * np.einsum("ij,qvj->qvi", T.rotation, moved) + T.translation) @ model.R_canon_base.T


def _box_volumes(v: np.ndarray) -> np.ndarray:
    """Axis-aligned box volume of each ``(V, 3)`` set of a ``(Q, V, 3)`` stack."""
    return np.prod(v.max(axis=1) - v.min(axis=1), axis=1)


def _aligned_child_volume(model, k) -> float:
    """The smallest axis-aligned box volume of joint ``k``'s child over a full turn about the
    joint (its limits do not apply: this probes the part's shape, not a reachable state)."""
    qs = np.linspace(-np.pi, np.pi, _TURN_SAMPLES)
    vols = _box_volumes(_child_vertices_at(model, k, qs))
    step = qs[1] - qs[0]  # then finer around the best, so the result does not depend on the grid's phase
    fine = qs[int(np.argmin(vols))] + np.linspace(-step, step, 41)
    return float(min(vols.min(), _box_volumes(_child_vertices_at(model, k, fine)).min()))


def closed_scores(model, k, qs) -> np.ndarray:
    """Box volume around base and part at each state ``qs`` of joint ``k``; infinite where a
    revolute part is not aligned with the canonical axes (:data:`CLOSED_ALIGNMENT_FACTOR`),
    unless the part never closes aligned (:func:`_closes_aligned`).

    Returns
    -------
    (len(qs),) float64
        Model units cubed.
    """
    out, aligned = _pair_volumes(model, k, qs)
    if model.joints[k].is_revolute and _closes_aligned(model, k):
        out[~aligned] = np.inf
    return out


def closing_scores(model, k, qs) -> np.ndarray:
    """:func:`closed_scores` weighted by how far a revolute part is from its aligned pose (its own
    box over its smallest over a full turn): the importer's choice of state 0. An arched lid's
    box around base and part shrinks a little as the lid tilts open; its own box grows faster.

    Returns
    -------
    (len(qs),) float64
    """
    out = closed_scores(model, k, qs)
    if model.joints[k].is_revolute:
        out = out * _box_volumes(_child_vertices_at(model, k, qs)) / _aligned_child_volume(model, k)
    return out


def _pair_volumes(model, k, qs) -> tuple[np.ndarray, np.ndarray]:
    """Box volume around base and part at each state ``qs`` of joint ``k``, and whether the part
    is aligned with the canonical axes there (:data:`CLOSED_ALIGNMENT_FACTOR`)."""
    child = _child_vertices_at(model, k, qs)
    base = part_vertices_canonical(model, model.rest_states)[model.base_index]
    lo = np.minimum(child.min(axis=1), base.min(axis=0))
    hi = np.maximum(child.max(axis=1), base.max(axis=0))
    aligned = _box_volumes(child) <= CLOSED_ALIGNMENT_FACTOR * _aligned_child_volume(model, k)
    return np.prod(hi - lo, axis=1), aligned


def _closes_aligned(model, k) -> bool:
    """Whether joint ``k``'s part closes aligned with the canonical axes: the smallest box among
    its aligned states within the limits is at most :data:`CLOSED_ALIGNMENT_FACTOR` above the
    smallest box of all its states there. A lid closing on a sloping top is aligned only when
    it stands open, far from closed; then closed is simply the smallest box."""
    joint = model.joints[k]
    lo = joint.lower if np.isfinite(joint.lower) else -np.pi
    hi = joint.upper if np.isfinite(joint.upper) else np.pi
    vols, aligned = _pair_volumes(model, k, np.linspace(lo, hi, _LIMIT_SAMPLES))
    return bool(aligned.any()) and vols[aligned].min() <= CLOSED_ALIGNMENT_FACTOR * vols.min()


#: States sampled along one side of a state by :func:`side_volumes`.
SIDE_SAMPLES = 12


def side_volumes(model, k, start: float, end: float, samples: int = SIDE_SAMPLES) -> np.ndarray:
    """Box volume around base and joint ``k``'s part at ``samples`` states evenly spaced from ``start``
    (excluded) to ``end`` (included), the other joints at rest; the whole of one side, not only its first step.

    Returns
    -------
    (samples,) float64
        Model units cubed.
    """
    qs = start + (end - start) * np.arange(1, samples + 1) / samples
    return np.array([box_volume(*_joint_pair(model, k, _with_state(model, k, q))) for q in qs])


def _joint_rule_violations(model, k, jc, rel_tol, angle_tol_deg) -> list[str]:
    joint = model.joints[k]
    out = []
    lo, hi = joint.lower, joint.upper
    if not np.isfinite(lo):
        lo = -np.pi
    if not np.isfinite(hi):
        hi = np.pi
    span = hi - lo
    base0, child0 = _joint_pair(model, k, _with_state(model, k, 0.0))
    if jc.zero == "closed":
        qs = np.linspace(lo, hi, 61)
        v0, *vols = closed_scores(model, k, np.concatenate([[0.0], qs]))
        i = int(np.argmin(vols))
        if not np.isfinite(v0):
            out.append(f"joint {joint.name!r}: state 0 is not closed (the part is not aligned with the base's faces)")
        elif vols[i] < v0 * (1 - rel_tol):
            out.append(f"joint {joint.name!r}: state 0 is not closed (state {qs[i]:.4g} is {100 * (1 - vols[i] / v0):.1f}% tighter)")
    else:  # perpendicular
        ang = _horizontal_angle_to_front_deg(child0)
        if ang > angle_tol_deg:
            out.append(f"joint {joint.name!r}: at state 0 the part's long axis is {ang:.1f} deg from the front axis, not perpendicular to the base")
    step = min(0.1 * span, 0.25 if joint.is_revolute else 0.1 * span)
    if hi <= 0.0:
        out.append(f"joint {joint.name!r}: the state cannot increase from 0 (upper limit {hi:.4g}), so it cannot {jc.positive.rstrip('s')}")
    elif step > 0:
        if jc.positive == "opens":  # somewhere over the whole positive range: the first step may
            # leave the box unchanged (a lid's front edge rising within the body's height)
            ok = bool(np.any(side_volumes(model, k, 0.0, hi) > box_volume(base0, child0) * (1 + 1e-9)))
        else:  # folds: the far end of the part comes closer to the base's centre line (x = centre)
            q1 = min(hi, step)
            b1, c1 = _joint_pair(model, k, _with_state(model, k, q1))
            cx = (base0.min(axis=0)[0] + base0.max(axis=0)[0]) / 2
            ok = abs(c1.mean(axis=0)[0] - cx) < abs(child0.mean(axis=0)[0] - cx)
        if not ok:
            out.append(f"joint {joint.name!r}: increasing the state does not {jc.positive.rstrip('s')}")
    b_rest, c_rest = _joint_pair(model, k, model.rest_states)
    if not _side_ok(b_rest, c_rest, jc.side):
        out.append(f"joint {joint.name!r}: at rest part {jc.child!r} is not on the {'/'.join(jc.side)} of the base")
    return out
