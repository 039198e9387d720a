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

from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from ..model.articulated import ArticulatedModel, JointType

__all__ = [
    "CONVENTIONS",
    "UP",
    "FRONT",
    "RIGHT",
    "CategoryConvention",
    "JointConvention",
    "box_volume",
    "convention",
    "convention_violations",
    "part_vertices_canonical",
    "rest_diagonal",
]

#: Canonical axes shared by every category (NAOCS orientation).
RIGHT = np.array([1.0, 0.0, 0.0])
UP = np.array([0.0, 1.0, 0.0])
FRONT = np.array([0.0, 0.0, 1.0])

REVOLUTE, PRISMATIC = JointType.REVOLUTE, JointType.PRISMATIC
_ZERO_RULES = ("closed", "perpendicular")
_POSITIVE_RULES = ("opens", "folds")
_SIDES = ("front", "back", "top")
_ORDER_AXES = {"x": 0, "y": 1}


@dataclass(frozen=True)
class JointConvention:
    """What one joint of a category means.

    Attributes
    ----------
    name : str
        Joint name (``display_hinge``).
    type : JointType
    parent, child : str
        Part roles; the child is the moving part.
    zero : str
        Geometric meaning of state 0: ``"closed"`` or ``"perpendicular"`` (module docstring).
    positive : str
        Direction of increasing state: ``"opens"`` or ``"folds"``.
    rest : float
        Rest state defining NAOCS (radians or metres, in this parameterisation).
    side : str or tuple of str
        Side(s) of the base the child sits on at rest: ``"front"`` (+z), ``"back"`` (-z) or
        ``"top"`` (+y) of the base's box centre. A tuple allows any of them (a washing
        machine's door is in front or on top).
    semantics : tuple of str
        PartNet-Mobility part names (``mobility_v2.json`` ``name``) of the child.
    state_range : (float, float)
        The states every object of the category can take (radians or metres, this parameterisation):
        ``zero="closed"`` joints start at 0 (a lid cannot go through its base, a drawer into its
        cabinet) and reach the widest opening of the category's real and procedural instances. The
        fits take it as bounds on the state (:attr:`CategoryConvention.joint_limits`). Default: no
        bound.
    """

    name: str
    type: JointType
    parent: str
    child: str
    zero: str
    positive: str
    rest: float
    side: tuple
    semantics: tuple
    state_range: tuple = (-np.inf, np.inf)

    def __post_init__(self):
        object.__setattr__(self, "type", JointType(self.type))
        if self.zero not in _ZERO_RULES:
            raise ValueError(f"joint {self.name!r} zero: expected one of {_ZERO_RULES}, got {self.zero!r}")
        if self.positive not in _POSITIVE_RULES:
            raise ValueError(f"joint {self.name!r} positive: expected one of {_POSITIVE_RULES}, got {self.positive!r}")
        side = (self.side,) if isinstance(self.side, str) else tuple(self.side)
        if not side or any(s not in _SIDES for s in side):
            raise ValueError(f"joint {self.name!r} side: expected one or more of {_SIDES}, got {self.side!r}")
        object.__setattr__(self, "side", side)
        object.__setattr__(self, "semantics", tuple(self.semantics))
        object.__setattr__(self, "rest", float(self.rest))
        lo, hi = (float(v) for v in self.state_range)
        if not (lo < hi and not np.isnan(lo) and not np.isnan(hi)):
            raise ValueError(f"joint {self.name!r} state_range: expected lower < upper, got {self.state_range!r}")
        if not lo <= self.rest <= hi:
            raise ValueError(f"joint {self.name!r} state_range: the rest state {self.rest:.4g} lies outside [{lo:.4g}, {hi:.4g}]")
        object.__setattr__(self, "state_range", (lo, hi))


@dataclass(frozen=True)
class CategoryConvention:
    """One category's definition (see the module docstring).

    Attributes
    ----------
    name : str
    part_names : tuple of str
        Part roles in label order ``0..M-1``, base first.
    joints : tuple of JointConvention
        Joint ``k`` moves part ``k + 1``.
    diagonal_range : (float, float)
        Range of the rest-state box diagonal (metres) of real instances; imported objects are
        scaled into it, procedural ones are generated in it.
    rest_description : str
        The rest state that defines NAOCS, in words (paper Sec. 4.1).
    order_by : str or None
        Canonical axis (``"x"`` or ``"y"``) ordering the moving parts at rest, ascending
        (eyeglasses: left temple at -x first; drawers: lowest first); ``None`` for one moving part.
    source_categories : tuple of str
        PartNet-Mobility ``meta.json`` ``model_cat`` values that map to this category.
    in_paper : bool
        One of the ANCSH paper's five categories.
    """

    name: str
    part_names: tuple
    joints: tuple
    diagonal_range: tuple
    rest_description: str
    order_by: str | None = None
    source_categories: tuple = ()
    in_paper: bool = True

    def __post_init__(self):
        parts, joints = tuple(self.part_names), tuple(self.joints)
        if len(joints) != len(parts) - 1:
            raise ValueError(f"category {self.name!r}: {len(parts)} parts need {len(parts) - 1} joints, got {len(joints)}")
        for k, j in enumerate(joints):
            if not isinstance(j, JointConvention):
                raise ValueError(f"category {self.name!r} joints: expected JointConvention, got {type(j).__name__}")
            if j.child != parts[k + 1] or j.parent not in parts[: k + 1]:
                raise ValueError(f"category {self.name!r}: joint {j.name!r} must move part {parts[k + 1]!r} from an earlier part")
        lo, hi = (float(v) for v in self.diagonal_range)
        if not 0 < lo < hi:
            raise ValueError(f"category {self.name!r} diagonal_range: expected 0 < lo < hi, got {self.diagonal_range}")
        if self.order_by is not None and self.order_by not in _ORDER_AXES:
            raise ValueError(f"category {self.name!r} order_by: expected 'x', 'y' or None, got {self.order_by!r}")
        object.__setattr__(self, "part_names", parts)
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "diagonal_range", (lo, hi))
        object.__setattr__(self, "source_categories", tuple(self.source_categories))

    @property
    def joint_names(self) -> tuple:
        return tuple(j.name for j in self.joints)

    @property
    def joint_types(self) -> tuple:
        return tuple(j.type for j in self.joints)

    @property
    def rest_states(self) -> np.ndarray:
        """(K,) rest states in the convention's parameterisation."""
        return np.array([j.rest for j in self.joints], dtype=np.float64)

    @property
    def joint_limits(self) -> np.ndarray:
        """(K, 2) the joints' :attr:`JointConvention.state_range` relative to the rest states (the fits' states)."""
        return np.array([j.state_range for j in self.joints], dtype=np.float64).reshape(-1, 2) - self.rest_states[:, None]

    @property
    def typical_size(self) -> float:
        """Typical rest-state box diagonal (metres): the middle of :attr:`diagonal_range`."""
        return 0.5 * (self.diagonal_range[0] + self.diagonal_range[1])

    @property
    def num_parts(self) -> int:
        return len(self.part_names)

    @property
    def num_joints(self) -> int:
        return len(self.joints)


#: Joint ranges (:attr:`JointConvention.state_range`), from closed to the widest opening of the category's procedural
#: generators and of its PartNet-Mobility objects' limits (boxes open 116-265 deg; laptops lie flat at 180 deg;
#: drawers travel at most 90 % of a cabinet's depth, 1.6 m across at most). Eyeglasses temples splay outwards up to
#: 0.25 rad and fold up to 1.62 rad in the generator: 0.1 rad more both ways.
_DOOR_RANGE = (0.0, np.pi)
_LID_RANGE = (0.0, np.deg2rad(270.0))
_TEMPLE_RANGE = (-0.35, 1.72)
_DRAWER_RANGE = (0.0, 1.0)


def _door(name="door_hinge", side=("front",), semantics=("door",)):
    return JointConvention(name, REVOLUTE, "base", "door", "closed", "opens", 0.0, side, semantics, _DOOR_RANGE)


_DRAWER_SEMANTICS = ("drawer", "drawer_box", "handle")
_CONVENTIONS = (
    CategoryConvention(
        "eyeglasses",
        ("base", "left_temple", "right_temple"),
        tuple(
            JointConvention(f"{s}_hinge", REVOLUTE, "base", f"{s}_temple", "perpendicular", "folds", 0.0, "back", ("leg",),
                            _TEMPLE_RANGE)
            for s in ("left", "right")
        ),
        (0.17, 0.27),
        "temples at right angles to the front frame (0)",
        order_by="x",
        source_categories=("Eyeglasses",),
    ),
    CategoryConvention(
        "oven",
        ("base", "door"),
        (_door(),),
        (0.50, 1.55),
        "door closed (0)",
        source_categories=("Oven",),
    ),
    CategoryConvention(
        "washing_machine",
        ("base", "door"),
        (_door(side=("front", "top")),),
        (0.95, 1.35),
        "door closed (0)",
        source_categories=("WashingMachine",),
    ),
    CategoryConvention(
        "laptop",
        ("base", "display"),
        (
            JointConvention(
                "display_hinge", REVOLUTE, "base", "display", "closed", "opens", np.pi / 2, "back",
                ("shaft", "screen", "screen_side", "other_leaf"), _DOOR_RANGE,
            ),
        ),
        (0.35, 0.62),
        "display at right angles to the base (pi/2 from closed)",
        source_categories=("Laptop",),
    ),
    CategoryConvention(
        "drawer",
        ("base", "lowest", "middle", "top"),
        tuple(
            JointConvention(f"{n}_slide", PRISMATIC, "base", n, "closed", "opens", 0.0, "front", _DRAWER_SEMANTICS,
                            _DRAWER_RANGE)
            for n in ("lowest", "middle", "top")
        ),
        (0.75, 1.60),
        "all drawers closed (0)",
        order_by="y",
        source_categories=("Table", "StorageFurniture"),
    ),
    CategoryConvention(
        "microwave",
        ("base", "door"),
        (_door(),),
        (0.45, 0.85),
        "door closed (0)",
        source_categories=("Microwave",),
        in_paper=False,
    ),
    CategoryConvention(
        "safe",
        ("base", "door"),
        (_door(),),
        (0.35, 1.40),
        "door closed (0)",
        source_categories=("Safe",),
        in_paper=False,
    ),
    CategoryConvention(
        "box",
        ("base", "lid"),
        (JointConvention("lid_hinge", REVOLUTE, "base", "lid", "closed", "opens", 0.0, "top", ("rotation_lid", "lid"),
                             _LID_RANGE),),
        (0.12, 1.15),
        "lid closed (0)",
        source_categories=("Box",),
        in_paper=False,
    ),
)

#: ``CONVENTIONS[name]`` -> :class:`CategoryConvention`, every category with a convention.
CONVENTIONS = MappingProxyType({c.name: c for c in _CONVENTIONS})


def convention(category: str) -> CategoryConvention:
    """The convention of ``category``; ``ValueError`` naming the known ones otherwise."""
    if category not in CONVENTIONS:
        raise ValueError(f"category: no convention for {category!r}; known: {', '.join(CONVENTIONS)}")
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
        axis = _ORDER_AXES[conv.order_by]
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
