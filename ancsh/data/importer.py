"""Import real articulated objects (URDF) into a category's convention.

:func:`import_object` turns one URDF object into an :class:`ImportedObject`: a small, JSON-able
record of *how* the file maps onto the category (:mod:`ancsh.data.conventions`) — which of the
file's joints move, which file state is the category's state 0 and in which direction the state
grows, whether the front is turned round, the metric scale and the instance split. Its
:meth:`ImportedObject.model` rebuilds the category-convention :class:`ArticulatedModel` from the
file each time; no mesh is copied. An object whose structure the category cannot hold is
rejected with :class:`ImportRejected` and the reason; it is never mis-evaluated.

Rules (each measured on the geometry, see :mod:`ancsh.data.conventions`)
-------------------------------------------------------------------------
1. Category: given, or PartNet-Mobility's ``meta.json`` ``model_cat`` matched against each
   convention's ``source_categories``, or the category a URDF written by ancsh names (``predict --urdf``:
   its ``<ancsh category=...>``, :mod:`ancsh.model.urdf_export`), or the folder name's prefix.
2. Moving parts: with ``semantics.txt`` (PartNet-Mobility), the links whose original joint
   has the convention's type (``hinge`` = revolute, ``slider`` = prismatic) and whose part name
   is one of the convention's ``semantics``; those joints are restored when the file froze them
   (GenSim2's copies keep one movable joint), every other movable joint is frozen (knobs,
   buttons, trays). Without it, the file's movable joints whose child link matches one of the
   joints' ``links`` patterns (all movable joints when no pattern is given). Links matching the
   category's ``freeze`` patterns (by link name or part name) never move. More candidates than the
   category's moving parts: each choice is tried and the largest parts that meet the convention
   kept; fewer: rejected.
3. State 0: ``closed`` — the state within the limits minimising the box around base and part
   among the states where the part is aligned with the base (not swung into it);
   ``perpendicular`` — the state with the part's long axis along the front axis, on the
   convention's side. Direction: the sign under which the state ``opens`` / ``folds``.
4. Orientation: the loader's up/front (:mod:`ancsh.data.urdf`); turned 180 degrees about up when
   the moving parts sit on the wrong side for the convention at rest.
5. Part order by role (``order_by``), names from the convention.
6. Scale: the rest-state diagonal drawn uniformly from the category's range, seeded by the
   object's name (or given by an override).
7. The result must pass :func:`~ancsh.data.conventions.convention_violations`; otherwise the
   object is rejected with the violations as the reason.

Overrides (``--override FILE``, JSON): ``{"<object name>": {"zero": {"<joint>": value},
"sign": {"<joint>": 1|-1}, "flip_front": bool, "diagonal_m": float, "moving_links": [...],
"reject": "reason"}}`` where ``<joint>`` is a convention joint name and ``zero`` is in the
file's units. Unknown objects, keys or joint names are errors naming the object.

Split: a category with at most :data:`MIN_REAL_FOR_TRAINING` real objects keeps them all for
testing; otherwise an object is a test object when ``crc32(name) % 4 == 0`` — fixed per object,
independent of which other objects are imported.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import json
import re
import zlib
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from ..geometry._checks import check_bool
from ..geometry.rotations import axis_angle_matrix
from ..model.articulated import ArticulatedModel
from ..model.edit import reparameterized, restructured, scaled, with_limits, with_orientation
from ..model.urdf_export import OBJECT_ELEMENT
from .conventions import (
    CONVENTIONS,
    UP,
    CategoryConvention,
    _side_ok,
    convention,
    convention_violations,
    part_vertices_canonical,
    rest_diagonal,
)
from .import_rules import ImportRejected, find_sign, find_zero, free_range, unbounded

__all__ = [
    "ImportRejected",
    "ImportedObject",
    "MIN_REAL_FOR_TRAINING",
    "assign_splits",
    "import_object",
    "load_overrides",
]

#: Categories with at most this many real objects keep them all for testing.
MIN_REAL_FOR_TRAINING = 2
_KIND = {"hinge": "revolute", "slider": "prismatic"}
_OVERRIDE_KEYS = {"zero", "sign", "flip_front", "diagonal_m", "moving_links", "reject"}


@dataclass(frozen=True)
class ImportedObject:
    """How one URDF file maps onto its category's convention (JSON-able).

    Attributes
    ----------
    name : str
        Object name (the URDF's folder, e.g. ``laptop_10101``).
    category : str
    urdf : str
        Path of the URDF: relative to the shared data folder when inside it (``shared:`` prefix),
        else absolute.
    joint_types : dict
        ``{urdf joint: type}`` overrides (restored and frozen joints) passed to the loader.
    moving_links : tuple of str
        URDF child link of each convention joint, in convention order.
    zero : tuple of float
        File state that is the convention's state 0, per convention joint (file units).
    sign : tuple of int
        ``+1``/``-1`` per convention joint: ``q_convention = sign * (q_file - zero)``.
    flip_front : bool
        The loader's front turned round (180 degrees about up).
    scale : float
        File units -> metres.
    split : str
        ``"train"`` or ``"test"``.
    notes : tuple of str
        Overrides applied, clipped values, anything a person checking the catalog should know.
    limits : dict
        ``{convention joint: [lower, upper]}`` (convention units) replacing a revolute joint's limits where
        the file gives none or more than a full turn (``continuous``, ``+-1e9``): the states from state 0
        where the part does not pass through the base (:func:`free_range`). Empty for most objects.
    """

    name: str
    category: str
    urdf: str
    joint_types: dict
    moving_links: tuple
    zero: tuple
    sign: tuple
    flip_front: bool
    scale: float
    split: str = "test"
    notes: tuple = field(default_factory=tuple)
    limits: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        d = {
            "name": self.name, "category": self.category, "urdf": self.urdf,
            "joint_types": dict(self.joint_types), "moving_links": list(self.moving_links),
            "zero": [float(z) for z in self.zero], "sign": [int(s) for s in self.sign],
            "flip_front": bool(self.flip_front), "scale": float(self.scale), "split": self.split,
            "notes": list(self.notes),
        }
        if self.limits:
            d["limits"] = {k: [float(a), float(b)] for k, (a, b) in self.limits.items()}
        return d

    @classmethod
    def from_dict(cls, d: dict, where: str = "catalog") -> "ImportedObject":
        name = d.get("name", "?") if isinstance(d, dict) else d
        if isinstance(d, dict) and "scale" in d:
            sc = d["scale"]
            if isinstance(sc, bool) or not isinstance(sc, (int, float)) or not np.isfinite(sc) or sc <= 0:
                raise ValueError(f"{where}: object {name!r}: scale: expected a positive number (file units -> metres), "
                                 f"got {sc!r}")
        try:
            return cls(
                name=str(d["name"]), category=str(d["category"]), urdf=str(d["urdf"]),
                joint_types={str(k): str(v) for k, v in dict(d["joint_types"]).items()},
                moving_links=tuple(str(x) for x in d["moving_links"]),
                zero=tuple(float(z) for z in d["zero"]), sign=tuple(int(s) for s in d["sign"]),
                flip_front=check_bool(d["flip_front"], "flip_front"), scale=float(d["scale"]), split=str(d["split"]),
                notes=tuple(str(n) for n in d.get("notes", ())),
                limits={str(k): (float(v[0]), float(v[1])) for k, v in dict(d.get("limits", {})).items()},
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: malformed object entry {name!r}: {exc}") from None

    @property
    def urdf_path(self) -> Path:
        """The URDF file (``shared:`` paths resolved against the shared data folder)."""
        from .paths import shared_data_dir

        if self.urdf.startswith("shared:"):
            root = shared_data_dir().resolve()
            file = (root / self.urdf[len("shared:"):]).resolve()
            if not file.is_relative_to(root):
                raise ValueError(f"{self.name}: catalog urdf {self.urdf!r} leaves the shared data folder {root}")
            return file
        return Path(self.urdf)

    @cached_property
    def _model(self) -> ArticulatedModel:
        from .urdf import load_urdf

        conv = convention(self.category)
        path = self.urdf_path
        if not path.is_file():
            raise FileNotFoundError(f"{self.name}: URDF {path} not found (is ../shared/data beside the repository?)")
        raw = load_urdf(path, category=self.category, joint_types=self.joint_types)
        return _to_convention(raw, conv, self.moving_links, self.zero, self.sign, self.flip_front, self.scale, self.name,
                              self.limits)

    def model(self) -> ArticulatedModel:
        """The object in its category's convention (metres, canonical orientation, rest, roles)."""
        return self._model


def _relative_urdf(path: Path) -> str:
    from .paths import shared_data_dir

    path = path.resolve()
    try:
        return "shared:" + path.relative_to(shared_data_dir()).as_posix()
    except ValueError:
        return str(path)


def _object_name(path: Path) -> str:
    """The folder's name for generic file names (``mobility.urdf``, ``model.urdf``), else the file's stem."""
    return path.parent.name if path.stem in ("mobility", "model") else path.stem


def _guess_category(path: Path) -> str | None:
    meta = path.parent / "meta.json"
    cat = None
    if meta.is_file():
        try:
            cat = json.loads(meta.read_text()).get("model_cat")
        except (ValueError, OSError):
            cat = None
    for conv in CONVENTIONS.values():
        if cat in conv.source_categories:
            return conv.name
    written = _urdf_root(path, _object_name(path)).find(OBJECT_ELEMENT)
    if written is not None and written.get("category") in CONVENTIONS:
        return written.get("category")
    prefix = re.sub(r"_\d+$", "", path.parent.name)
    return prefix if prefix in CONVENTIONS else None


def _mobility_joints(path: Path) -> dict | None:
    """``{link name: (joint kind, part name)}`` of a PartNet-Mobility object, or ``None``.

    From ``semantics.txt`` (``link_name joint_kind part_name`` per line), which names the URDF's
    links; ``mobility_v2.json`` ids do not always match the link names of re-hosted copies.
    """
    file = path.parent / "semantics.txt"
    if not file.is_file():
        return None
    out = {}
    for n, line in enumerate(file.read_text().splitlines(), 1):
        fields = line.split()
        if not fields:
            continue
        if len(fields) != 3:
            raise ValueError(f"{path.parent.name}: semantics.txt line {n} is not 'link kind name': {line!r}")
        out[fields[0]] = (fields[1], fields[2])
    return out


def _urdf_root(path: Path, name: str):
    """The file's ``<robot>`` element (entities and DTDs not loaded), or :class:`ImportRejected` saying what the
    file is instead: not XML at all, or XML with another root element."""
    from lxml import etree

    parser = etree.XMLParser(resolve_entities=False, load_dtd=False, no_network=True)
    try:
        root = etree.parse(str(path), parser).getroot()
    except Exception as exc:  # noqa: BLE001 - any parser failure: not a URDF
        raise ImportRejected(name, f"{path.name} is not a URDF file (not readable as XML: "
                                   f"{str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__})") from None
    if root is None or root.tag != "robot":
        raise ImportRejected(name, f"{path.name} is not a URDF file (its root element is "
                                   f"<{getattr(root, 'tag', '?')}>, not <robot>)")
    return root


def _urdf_joints(path: Path) -> dict:
    """``{child link: (joint name, type)}`` of the file (no geometry loaded)."""
    root = _urdf_root(path, _object_name(path))
    out = {}
    for j in root.findall("joint"):
        child = j.find("child")
        if child is not None and child.get("link") is not None:
            out[child.get("link")] = (j.get("name"), j.get("type"))
    return out


class _TooManyMoving(ImportRejected):
    """More moving parts of the category's kind than its joints: :func:`import_object` tries each choice."""

    def __init__(self, name: str, links: list):
        super().__init__(name, f"{len(links)} candidate moving parts {links}")
        self.links = list(links)


def _replaced_types_note(path: Path, joint_types: dict) -> str:
    """One note listing the joints whose file type the import replaces (frozen, restored, continuous kept)."""
    if not joint_types:
        return ""
    file_types = {jname: jtype for jname, jtype in _urdf_joints(path).values()}
    changes = [f"{j} {file_types.get(j, '?')} -> {t}" for j, t in sorted(joint_types.items())]
    return "joint types replaced: " + ", ".join(changes)


def _frozen(conv: CategoryConvention, link: str, part_name: str | None) -> bool:
    """Whether the category freezes ``link`` (its ``freeze`` patterns match the link's name or its part name)."""
    return any(fnmatch.fnmatchcase(link, p) or (part_name is not None and fnmatch.fnmatchcase(part_name, p))
               for p in conv.freeze)


def _select_moving(path: Path, conv: CategoryConvention, name: str, forced_links=None) -> tuple[dict, list]:
    """Joint-type overrides and the moving child links (file order)."""
    joints = _urdf_joints(path)
    movable = {link for link, (_, t) in joints.items() if t in ("revolute", "prismatic", "continuous")}
    wanted_type = {j.type.value for j in conv.joints}
    semantics = {s for j in conv.joints for s in j.semantics}
    mobility = _mobility_joints(path)
    if forced_links is not None:
        if isinstance(forced_links, str) or not all(isinstance(x, str) for x in forced_links):
            raise ValueError(f"{name}: override moving_links: expected a list of link names, got {forced_links!r}")
        moving = list(forced_links)
        unknown = [x for x in moving if x not in joints]
        if unknown:
            links = {link.get("name") for link in _urdf_root(path, name).findall("link")}
            base = [x for x in unknown if x in links]
            if base:
                raise ValueError(f"{name}: override moving_links: link(s) {base} are not the child of any joint (the "
                                 "base of the file's tree): the base cannot move; name the links of the moving parts")
            raise ValueError(f"{name}: override moving_links names unknown link(s) {unknown}")
    elif mobility is None:
        patterns = [p for j in conv.joints for p in j.links]
        moving = [link for link in joints if link in movable and not _frozen(conv, link, None)
                  and (not patterns or any(fnmatch.fnmatchcase(link, p) for p in patterns))]
    else:
        moving = [link for link in joints if link in mobility and _KIND.get(mobility[link][0]) in wanted_type
                  and mobility[link][1] in semantics and not _frozen(conv, link, mobility[link][1])]
    mobility = mobility or {}
    if len(moving) > conv.num_joints and forced_links is None:
        raise _TooManyMoving(name, moving)
    if len(moving) != conv.num_joints:
        kinds = [f"{mobility[link][1]} ({mobility[link][0]})" for link in joints if link in mobility and mobility[link][0] in _KIND]
        kinds = kinds or [f"{link} ({joints[link][1]})" for link in joints if link in movable]
        raise ImportRejected(name, f"has {len(moving)} moving part(s) of the kind the {conv.name} category needs "
                                   f"({'/'.join(sorted(semantics))}; {'/'.join(sorted(wanted_type))}), it needs "
                                   f"{conv.num_joints}; the file's movable parts: {', '.join(kinds) or 'none'}")
    overrides = {}
    for link, (jname, jtype) in joints.items():
        if link in moving:
            kind = _KIND.get(mobility.get(link, ("",))[0], jtype)
            if kind == "revolute" and jtype == "continuous":
                kind = "continuous"
            if kind != jtype:
                overrides[jname] = kind
        elif jtype in ("revolute", "prismatic", "continuous"):
            overrides[jname] = "fixed"
    return overrides, moving


def _to_convention(raw: ArticulatedModel, conv: CategoryConvention, moving_links, zero, sign, flip_front, scale,
                   name, limits=None) -> ArticulatedModel:
    """Apply an import record to the loaded model (see :class:`ImportedObject`)."""
    model = raw
    if flip_front:
        model = with_orientation(model, axis_angle_matrix(UP, np.pi) @ model.R_canon_base)
    index = {j.child: k for k, j in enumerate(model.joints)}
    ks = [index[link] for link in moving_links]
    for jc, k, z, s in zip(conv.joints, ks, zero, sign):
        model = reparameterized(model, k, zero=z, sign=s, rest=jc.rest)
    if limits:
        lower = np.array([j.lower for j in model.joints])
        upper = np.array([j.upper for j in model.joints])
        for jc, k in zip(conv.joints, ks):
            if jc.name in limits:
                lower[k], upper[k] = limits[jc.name]
        model = with_limits(model, lower, upper)
    order = [0] + [model.part_index(link) for link in moving_links]
    model = restructured(model, order, conv.part_names, conv.joint_names)
    model = scaled(model, scale)
    return ArticulatedModel(model.parts, model.joints, name=name, category=conv.name, R_canon_base=model.R_canon_base)


def load_overrides(path) -> dict:
    """Read and check an override file (JSON; see the module docstring)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"override: cannot read {path}: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"override: {path} must hold an object {{name: {{...}}}}")
    for name, entry in data.items():
        if not isinstance(entry, dict):
            raise ValueError(f"override: {path}: entry {name!r} must be an object of settings such as "
                             f"{{\"moving_links\": [\"link_1\"]}}, got {entry!r}")
        unknown = set(entry) - _OVERRIDE_KEYS
        if unknown:
            raise ValueError(f"override: {path}: entry {name!r} has unknown key(s) {sorted(unknown)}; known: {sorted(_OVERRIDE_KEYS)}")
        if "flip_front" in entry:
            check_bool(entry["flip_front"], f"override: {path}: entry {name!r}: flip_front")
        for key, what in (("zero", "a number (file units)"), ("sign", "1 or -1")):
            value = entry.get(key, {})
            if not isinstance(value, dict) or not all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in value.values()):
                raise ValueError(f"override: {path}: entry {name!r}: {key}: expected an object {{joint name: {what}}} "
                                 f"naming the category's joints, got {value!r}")
        if "diagonal_m" in entry:
            d = entry["diagonal_m"]
            if isinstance(d, bool) or not isinstance(d, (int, float)) or not np.isfinite(d) or d <= 0:
                raise ValueError(f"override: {path}: entry {name!r}: diagonal_m: expected a positive number of metres, "
                                 f"got {d!r}")
        if "reject" in entry and not isinstance(entry["reject"], str):
            raise ValueError(f"override: {path}: entry {name!r}: reject: expected the reason (a string), "
                             f"got {entry['reject']!r}")
        links = entry.get("moving_links", [])
        if not isinstance(links, list) or not all(isinstance(link, str) for link in links):
            raise ValueError(f"override: {path}: entry {name!r}: moving_links: expected a list of link names "
                             f"(e.g. [\"link_1\"]), got {links!r}")
    return data


def import_object(urdf, category: str | None = None, *, override: dict | None = None) -> ImportedObject:
    """Map one URDF object onto a category's convention (see the module docstring).

    Parameters
    ----------
    urdf : str or Path
        The object's URDF file.
    category : str, optional
        A category with a convention; default: from the object's ``meta.json``.
    override : dict, optional
        This object's override entry (module docstring).

    Returns
    -------
    ImportedObject
        With ``split`` provisionally ``"test"``; :func:`assign_splits` sets the split of a catalog.

    Raises
    ------
    ImportRejected
        The object's structure or geometry cannot be an instance of the category (with the reason).
    ValueError
        A malformed file, missing meshes, or a bad override, naming the object.
    """
    from .urdf import load_urdf

    path = Path(urdf)
    if path.is_dir() and (path / "mobility.urdf").is_file():
        path = path / "mobility.urdf"
    name = _object_name(path)
    if not path.exists():
        raise ValueError(f"{name}: URDF file {path} does not exist")
    if not path.is_file():
        raise ValueError(f"{name}: {path} exists but is neither a URDF file nor a folder holding mobility.urdf")
    override = dict(override or {})
    if "reject" in override:
        raise ImportRejected(name, f"rejected by override: {override['reject']}")
    _urdf_root(path, name)  # a file that is no URDF says so, before any guess about its category
    if category is None:
        category = _guess_category(path)
        if category is None:
            meta = path.parent / "meta.json"
            why = ("its meta.json names no category with a convention" if meta.is_file() else
                   f"there is no meta.json beside it and its folder name {path.parent.name!r} names no category")
            raise ImportRejected(name, f"{why}; give the category (--category; known: {', '.join(CONVENTIONS)})")
    conv = convention(category)
    try:
        joint_types, moving = _select_moving(path, conv, name, override.get("moving_links"))
    except _TooManyMoving as many:
        return _choose_moving(path, conv, name, override, many.links)
    try:
        raw = load_urdf(path, category=category, joint_types=joint_types)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None
    empty = [p.name for p in raw.parts if p.mesh is None]
    if empty:
        raise ImportRejected(name, f"part(s) {empty} carry no geometry")
    index = {j.child: k for k, j in enumerate(raw.joints)}
    for link in moving:
        if link not in index:  # an override naming the base, or a link merged into another part by fixed joints
            raise ValueError(f"{name}: override moving_links: link {link!r} does not move in the file (it is the base or "
                             "is fixed to another link; its joint is fixed or it has none): name the links of the "
                             "moving parts")
        if raw.joint_parts(index[link])[0] != raw.base_index:
            raise ImportRejected(name, f"moving link {link!r} hangs from another moving part, not from the base")
    notes = []
    if "moving_links" in override:
        notes.append(f"moving links {list(moving)} from override")
    replaced = _replaced_types_note(path, joint_types)
    if replaced:
        notes.append(replaced)
    for key in set(override.get("zero", {})) | set(override.get("sign", {})):
        if key not in conv.joint_names:
            raise ValueError(f"{name}: override names unknown joint {key!r}; joints of {conv.name}: {conv.joint_names}")

    # provisional role order by file order; joint conventions are alike within a category
    zeros, signs = [], []
    for link, jc in zip(moving, conv.joints):
        k = index[link]
        if jc.name in override.get("zero", {}):
            z = float(override["zero"][jc.name])
            notes.append(f"{jc.name} zero {z:.4g} from override")
        else:
            z = find_zero(raw, k, jc)
        if jc.name in override.get("sign", {}):
            s = int(override["sign"][jc.name])
            if s not in (1, -1):
                raise ValueError(f"{name}: override sign of {jc.name!r} must be 1 or -1, got {s}")
        else:
            s = find_sign(raw, k, jc, z)
        zeros.append(z)
        signs.append(s)
    link_limits = {}  # by moving link: the role order below may still change
    for link, jc, z, s in zip(moving, conv.joints, zeros, signs):
        joint = raw.joints[index[link]]
        if unbounded(joint):
            lo, hi = free_range(raw, index[link], z, s, closed=jc.zero == "closed")
            if not lo < hi:
                raise ImportRejected(name, f"joint {joint.name!r} is unlimited in the file and its part cannot turn "
                                           "from state 0 without passing through the base")
            link_limits[link] = (lo, hi)
            kind = "continuous" if not (np.isfinite(joint.lower) and np.isfinite(joint.upper)) else \
                f"limited to [{joint.lower:.3g}, {joint.upper:.3g}] (more than a full turn)"
            notes.append(f"joint {joint.name!r} ({link}) is {kind} in the file; limited to [{np.degrees(lo):.0f}, "
                         f"{np.degrees(hi):.0f}] deg, the states where the part does not pass through the base")

    def by_role(order_links) -> dict:
        return {jc.name: link_limits[link] for link, jc in zip(order_links, conv.joints) if link in link_limits}

    def build(order_links, zs, ss, flip, scale):
        return _to_convention(raw, conv, order_links, zs, ss, flip, scale, name, by_role(order_links))

    # NAOCS front: flip when the moving parts sit on the wrong side at rest
    probe = _try_build(build, moving, zeros, signs, False, 1.0, conv, name)
    verts = part_vertices_canonical(probe, probe.rest_states)
    wrong = sum(not _side_ok(verts[0], verts[k + 1], jc.side) for k, jc in enumerate(conv.joints))
    flip = (check_bool(override["flip_front"], f"{name}: override flip_front") if "flip_front" in override
            else bool(wrong > conv.num_joints / 2))
    if "flip_front" in override:
        notes.append(f"flip_front={flip} from override")
    # role order: sort moving parts by the ordering axis at rest
    if conv.order_by is not None:
        probe = _try_build(build, moving, zeros, signs, flip, 1.0, conv, name)
        verts = part_vertices_canonical(probe, probe.rest_states)
        axis = {"x": 0, "y": 1}[conv.order_by]
        perm = sorted(range(len(moving)), key=lambda i: verts[i + 1].mean(axis=0)[axis])
        moving, zeros, signs = [moving[i] for i in perm], [zeros[i] for i in perm], [signs[i] for i in perm]
    probe = _try_build(build, moving, zeros, signs, flip, 1.0, conv, name)
    d0 = rest_diagonal(probe)
    if "diagonal_m" in override:
        target = float(override["diagonal_m"])
        notes.append(f"diagonal {target:.3f} m from override")
    else:
        lo, hi = conv.diagonal_range
        target = float(np.random.default_rng(zlib.crc32(name.encode())).uniform(lo, hi))
    scale = target / d0
    model = build(moving, zeros, signs, flip, scale)
    problems = convention_violations(model, conv)
    if problems:
        raise ImportRejected(name, "does not meet the category's convention after import: " + "; ".join(problems))
    obj = ImportedObject(name=name, category=conv.name, urdf=_relative_urdf(path), joint_types=joint_types,
                         moving_links=tuple(moving), zero=tuple(zeros), sign=tuple(signs), flip_front=flip,
                         scale=float(scale), split="test", notes=tuple(notes), limits=by_role(moving))
    return _carry_model(model, obj)


MAX_CHOICES = 12
"""Most choices of moving parts :func:`import_object` tries when a file has more than its category's joints."""


def _choose_moving(path: Path, conv: CategoryConvention, name: str, override: dict, links: list) -> ImportedObject:
    """Import with each choice of ``conv.num_joints`` of the candidate moving ``links`` (the others frozen) and keep
    the one that meets the convention with the largest moving parts (an oven's door, not a grill's hatch), recording
    the choice in the notes."""
    import itertools

    choices = list(itertools.combinations(links, conv.num_joints))[:MAX_CHOICES]
    found, reasons = [], []
    for choice in choices:
        try:
            obj = import_object(path, conv.name, override={**override, "moving_links": list(choice)})
        except ImportRejected as exc:
            reasons.append(f"{list(choice)}: {exc.reason}")
            continue
        model = obj.model()
        size = sum(float(model.parts[model.joint_parts(k)[1]].mesh.area) for k in range(model.num_joints))
        found.append((size, choice, obj))
    if not found:
        raise ImportRejected(name, f"has {len(links)} moving parts of the kind the {conv.name} category needs ({links}), "
                                   f"it needs {conv.num_joints}, and no choice meets the convention: " + "; ".join(reasons))
    size, choice, obj = max(found, key=lambda f: f[0])
    frozen = [link for link in links if link not in choice]
    note = (f"the file has {len(links)} moving parts of the category's kind {links}: {list(choice)} chosen by the "
            f"convention (of {len(found)} choice(s) meeting it, the largest moving surface), {frozen} frozen")
    notes = tuple(n for n in obj.notes if not n.startswith("moving links "))  # the choice was ours, not an override
    return _carry_model(obj.model(), dataclasses.replace(obj, notes=(note, *notes)))


def _carry_model(model: ArticulatedModel, obj: ImportedObject) -> ImportedObject:
    """``obj`` with ``model`` as its already built :meth:`ImportedObject.model` (the same record
    rebuilds the same model from the file; this saves loading the meshes a second time)."""
    obj.__dict__["_model"] = model
    return obj


def _try_build(build, moving, zeros, signs, flip, scale, conv, name):
    try:
        return build(moving, zeros, signs, flip, scale)
    except ValueError as exc:  # e.g. the rest state outside the mapped limits
        raise ImportRejected(name, f"cannot take the {conv.name} convention: {exc}") from None


def assign_splits(objects) -> list:
    """The fixed instance split of imported objects (module docstring), as new records."""
    from dataclasses import replace

    objects = list(objects)
    counts = {}
    for o in objects:
        counts[o.category] = counts.get(o.category, 0) + 1
    out = []
    for o in objects:
        test = counts[o.category] <= MIN_REAL_FOR_TRAINING or zlib.crc32(o.name.encode()) % 4 == 0
        new = replace(o, split="test" if test else "train")
        out.append(_carry_model(o.__dict__["_model"], new) if "_model" in o.__dict__ else new)
    return out
