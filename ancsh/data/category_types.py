"""The types of a category's definition: :class:`JointConvention` and :class:`CategoryConvention`.

What they mean, and the geometric rules that check an object against them, are in
:mod:`ancsh.data.conventions`; how they are written in files, in :mod:`ancsh.data.category_spec`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry._checks import as_array
from ..model.articulated import JointType

__all__ = ["ORDER_AXES", "CategoryConvention", "JointConvention", "ViewpointRange"]

REVOLUTE, PRISMATIC = JointType.REVOLUTE, JointType.PRISMATIC
_ZERO_RULES = ("closed", "perpendicular")
_POSITIVE_RULES = ("opens", "folds")
_SIDES = ("front", "back", "top")
#: Canonical axis index of each `order_by` value.
ORDER_AXES = {"x": 0, "y": 1}


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
    links : tuple of str
        URDF link-name patterns (``fnmatch``, e.g. ``"door*"``) of the child, for files without
        PartNet-Mobility semantics: the importer's moving-part candidates are the movable links that
        match. Empty: every movable link is a candidate.
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
    links: tuple = ()

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
        object.__setattr__(self, "links", tuple(self.links))
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
    description : str
        What the category holds, in words (a spec's ``description``).
    freeze : tuple of str
        Link-name or PartNet-Mobility part-name patterns (``fnmatch``) the importer always freezes
        (locks, knobs, buttons): never a moving part.
    spec_path : str or None
        The spec file the convention was read from (:mod:`ancsh.data.category_spec`).
    viewpoint : tuple of (str, value) pairs
        How cameras see the category's objects in rendered frames: keyword arguments of
        :class:`ancsh.data.render.ViewpointRange` (radians; distances in box diagonals). Empty: the
        default range.
    folder : str or None
        The category folder (a built category: its spec, weights, calibrations, template); ``None``
        for the built-in categories, whose files ship in the package.
    track_template : bool
        Tracks of the category carry the category template refined at every (re-)initialisation
        (:class:`ancsh.tracking.CategoryTracker`, ``TrackerConfig.template_categories`` left at its default);
        a spec's ``track_template``, ``false`` unless measured to help (``docs/category_spec.md``).
    """

    name: str
    part_names: tuple
    joints: tuple
    diagonal_range: tuple
    rest_description: str
    order_by: str | None = None
    source_categories: tuple = ()
    in_paper: bool = True
    description: str = ""
    freeze: tuple = ()
    spec_path: str | None = None
    folder: str | None = None
    viewpoint: tuple = ()
    track_template: bool = False

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
        if self.order_by is not None and self.order_by not in ORDER_AXES:
            raise ValueError(f"category {self.name!r} order_by: expected 'x', 'y' or None, got {self.order_by!r}")
        object.__setattr__(self, "part_names", parts)
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "diagonal_range", (lo, hi))
        object.__setattr__(self, "source_categories", tuple(self.source_categories))
        object.__setattr__(self, "freeze", tuple(self.freeze))
        view = dict(self.viewpoint)
        object.__setattr__(self, "viewpoint", tuple((k, tuple(v) if isinstance(v, (list, tuple)) else float(v))
                                                    for k, v in view.items()))

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


@dataclass(frozen=True)
class ViewpointRange:
    """Random camera placement around an object, in its canonical (NAOCS) orientation.

    The camera sits at ``target + d * (cos(el) sin(az), sin(el), cos(el) cos(az))`` in
    canonical axes (``+y`` up, ``+z`` the object's front; ``az = el = 0`` looks at the front
    head-on), looks at the target (the centre of the object's box at the sampled joint
    state, jittered) with canonical ``+y`` up, then rolls about its optical axis.

    Attributes
    ----------
    distance : (float, float)
        Range of ``d`` in multiples of the object's box diagonal at the sampled state.
    azimuth, elevation : (float, float)
        Ranges in radians (uniform).
    roll : float
        Maximal absolute roll, radians (uniform in ``[-roll, roll]``).
    target_jitter : float
        Standard deviation of the look-at point jitter, in multiples of the diagonal.
    """

    distance: tuple = (1.5, 2.6)
    azimuth: tuple = (np.radians(-90.0), np.radians(90.0))
    elevation: tuple = (np.radians(0.0), np.radians(60.0))
    roll: float = np.radians(5.0)
    target_jitter: float = 0.05

    def __post_init__(self):
        for name in ("distance", "azimuth", "elevation"):
            lo, hi = (float(x) for x in as_array(getattr(self, name), name, (2,)))
            if lo > hi:
                raise ValueError(f"{name}: lower bound {lo} exceeds upper bound {hi}")
            object.__setattr__(self, name, (lo, hi))
        if self.distance[0] <= 0:
            raise ValueError(f"distance: must be positive, got {self.distance}")
        if not -np.pi / 2 < self.elevation[0] <= self.elevation[1] < np.pi / 2:
            raise ValueError(f"elevation: must lie strictly within (-pi/2, pi/2), got {self.elevation}")
        for name in ("roll", "target_jitter"):
            value = float(getattr(self, name))
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"{name}: expected a non-negative number, got {getattr(self, name)}")
            object.__setattr__(self, name, value)
