"""Category spec files: a category defined in TOML, read and checked into a :class:`CategoryConvention`.

A category spec is the whole definition of a category in one small file (schema version
:data:`SPEC_VERSION`, documented in ``docs/category_spec.md``): the parts, base first, with the
PartNet-Mobility part names (``semantics``) or the URDF link-name patterns (``links``) that say
which links are which moving part; each joint's type, the meaning of its state 0, the direction
in which its state grows, its rest state (NAOCS) and its range; the size range of real instances;
the links to keep frozen. The built-in categories are spec files in ``ancsh/data/specs/``; a
category built by ``ancsh category build`` is a folder holding its ``category.toml``.

Every mistake is a :class:`SpecError` that names the file and the key (``joints[0].range_deg``),
before any data is read or trained on.

Units: revolute states are given in degrees (``rest_deg``, ``range_deg``) or radians
(``rest_rad``, ``range_rad``), prismatic ones in metres (``rest_m``, ``range_m``); exactly one form
per key. Inside the library every state is radians or metres.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
from pathlib import Path

from .category_types import CategoryConvention, JointConvention, ViewpointRange

__all__ = [
    "BUILTIN_SPECS_DIR",
    "SEARCH_PATH_VARIABLE",
    "SPEC_FILE",
    "SPEC_VERSION",
    "SpecError",
    "builtin_spec_paths",
    "load_spec",
    "parse_spec",
    "search_path_specs",
    "spec_file",
    "spec_text",
]

#: The schema version this library reads (``spec_version`` in every file).
SPEC_VERSION = 1
#: Where the built-in categories' spec files are.
BUILTIN_SPECS_DIR = Path(__file__).resolve().parent / "specs"
#: The spec file of a category folder.
SPEC_FILE = "category.toml"
#: Environment variable: folders (``os.pathsep``-separated) holding built category folders or spec files.
SEARCH_PATH_VARIABLE = "ANCSH_CATEGORIES"

_TOP_KEYS = {"spec_version", "name", "description", "rest", "diagonal_m", "order_by", "source_categories",
             "in_paper", "track_template", "freeze", "parts", "joints", "viewpoint"}
#: ``[viewpoint]`` keys: (ViewpointRange field, kind); angles in degrees, lengths in box diagonals.
_VIEWPOINT_KEYS = {"distance_diagonals": ("distance", "pair"), "azimuth_deg": ("azimuth", "pair_deg"),
                   "elevation_deg": ("elevation", "pair_deg"), "roll_deg": ("roll", "deg"),
                   "target_jitter_diagonals": ("target_jitter", "number")}
_PART_KEYS = {"name", "semantics", "links"}
_JOINT_KEYS = {"name", "type", "parent", "child", "zero", "positive", "side", "rest_deg", "rest_rad", "rest_m",
               "range_deg", "range_rad", "range_m"}
_UNIT_KEYS = {"revolute": ("deg", "rad"), "prismatic": ("m",)}


class SpecError(ValueError):
    """A category spec that cannot be read: the message names the file and the key."""


def _fail(source, key: str, why: str):
    raise SpecError(f"{source}: {key}: {why}")


def _unknown(source, where: str, table: dict, known: set) -> None:
    extra = sorted(set(table) - known)
    if extra:
        prefix = f"{where}." if where else ""
        _fail(source, prefix + extra[0], f"unknown key (known{' here' if where else ''}: {', '.join(sorted(known))})")


def _string(source, key: str, value, *, required: bool = True):
    if value is None and not required:
        return None
    if not isinstance(value, str) or not value.strip():
        _fail(source, key, f"expected a non-empty string, got {value!r}")
    return value


def _strings(source, key: str, value) -> tuple:
    if value is None:
        return ()
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        _fail(source, key, f"expected a list of non-empty strings, got {value!r}")
    return tuple(value)


def _number(source, key: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        _fail(source, key, f"expected a finite number, got {value!r}")
    return float(value)


def _pair(source, key: str, value, *, strict: bool = True) -> tuple:
    if not isinstance(value, list) or len(value) != 2:
        _fail(source, key, f"expected [lower, upper], got {value!r}")
    lo, hi = (_number(source, f"{key}[{i}]", v) for i, v in enumerate(value))
    if not (lo < hi if strict else lo <= hi):
        _fail(source, key, f"expected lower {'<' if strict else '<='} upper, got {value!r}")
    return lo, hi


def _state(source, where: str, table: dict, what: str, jtype: str):
    """The joint's ``rest`` or ``range`` in radians / metres, from the one unit form given."""
    units = _UNIT_KEYS[jtype]
    given = [u for u in ("deg", "rad", "m") if f"{what}_{u}" in table]
    wrong = [u for u in given if u not in units]
    if wrong:
        allowed = " or ".join(f"{what}_{u}" for u in units)
        _fail(source, f"{where}.{what}_{wrong[0]}", f"a {jtype} joint's {what} is given as {allowed}")
    if len(given) != 1:
        forms = " or ".join(f"{what}_{u}" for u in units)
        _fail(source, f"{where}.{what}_{units[0]}", f"expected exactly one of {forms}, got {len(given)}")
    key = f"{where}.{what}_{given[0]}"
    value = table[f"{what}_{given[0]}"]
    to_si = math.radians if given[0] == "deg" else float
    if what == "rest":
        return to_si(_number(source, key, value))
    lo, hi = _pair(source, key, value)
    return to_si(lo), to_si(hi)


def parse_spec(data: dict, source="<spec>") -> CategoryConvention:
    """Check a spec's parsed TOML table and build its convention.

    Parameters
    ----------
    data : dict
        The file's table (``tomllib.loads``).
    source : str or Path
        Named in every error (the file).

    Returns
    -------
    CategoryConvention

    Raises
    ------
    SpecError
        Naming ``source`` and the key: an unknown key, a missing or malformed value, a joint that moves no
        declared part, a state outside its range.
    """
    if not isinstance(data, dict):
        raise SpecError(f"{source}: expected a TOML table")
    _unknown(source, "", data, _TOP_KEYS)
    version = data.get("spec_version")
    if version != SPEC_VERSION:
        _fail(source, "spec_version", f"expected {SPEC_VERSION} (the schema this ancsh reads), got {version!r}")
    name = _string(source, "name", data.get("name"))
    if not name.replace("_", "").isalnum() or not name[0].isalpha() or name != name.lower():
        _fail(source, "name", f"expected lower-case letters, digits and '_' starting with a letter, got {name!r}")
    parts = data.get("parts")
    if not isinstance(parts, list) or len(parts) < 2 or not all(isinstance(p, dict) for p in parts):
        _fail(source, "parts", "expected at least two [[parts]] tables: the base first, then each moving part")
    part_names, semantics, links = [], {}, {}
    for i, part in enumerate(parts):
        where = f"parts[{i}]"
        _unknown(source, where, part, _PART_KEYS)
        pname = _string(source, f"{where}.name", part.get("name"))
        if pname in part_names:
            _fail(source, f"{where}.name", f"part {pname!r} is declared twice")
        if i == 0 and ("semantics" in part or "links" in part):
            key = "semantics" if "semantics" in part else "links"
            _fail(source, f"{where}.{key}", "the base (the first part) is every link the moving parts are not; "
                                            "name links only for moving parts")
        part_names.append(pname)
        semantics[pname] = _strings(source, f"{where}.semantics", part.get("semantics"))
        links[pname] = _strings(source, f"{where}.links", part.get("links"))
    joints = data.get("joints")
    if not isinstance(joints, list) or not all(isinstance(j, dict) for j in joints):
        _fail(source, "joints", "expected [[joints]] tables, one per moving part")
    if len(joints) != len(part_names) - 1:
        _fail(source, "joints", f"{len(part_names)} parts need {len(part_names) - 1} joints (one per moving part), "
                                f"got {len(joints)}")
    out = []
    for k, joint in enumerate(joints):
        where = f"joints[{k}]"
        _unknown(source, where, joint, _JOINT_KEYS)
        jname = _string(source, f"{where}.name", joint.get("name"))
        jtype = joint.get("type")
        if jtype not in _UNIT_KEYS:
            _fail(source, f"{where}.type", f"expected 'revolute' or 'prismatic', got {jtype!r}")
        child = _string(source, f"{where}.child", joint.get("child"))
        if child != part_names[k + 1]:
            _fail(source, f"{where}.child", f"joint {k} moves part {k + 1} ({part_names[k + 1]!r}), got {child!r}")
        parent = _string(source, f"{where}.parent", joint.get("parent", part_names[0]))
        if parent not in part_names[: k + 1]:
            _fail(source, f"{where}.parent", f"expected the base or an earlier moving part "
                                             f"({', '.join(part_names[: k + 1])}), got {parent!r}")
        side = joint.get("side")
        side = _strings(source, f"{where}.side", [side] if isinstance(side, str) else side)
        rest = _state(source, where, joint, "rest", jtype)
        state_range = _state(source, where, joint, "range", jtype)
        try:
            out.append(JointConvention(jname, jtype, parent, child, joint.get("zero"), joint.get("positive"), rest,
                                       side, semantics[child], state_range, links=links[child]))
        except ValueError as exc:  # the convention's own checks: say which key
            key = next((key for key in ("zero", "positive", "side") if f" {key}:" in str(exc)), "range")
            _fail(source, f"{where}.{key}", str(exc))
    names = [j.name for j in out]
    if len(set(names)) != len(names):
        _fail(source, "joints", f"joint names must differ, got {names}")
    fields = dict(
        order_by=data.get("order_by"),
        source_categories=_strings(source, "source_categories", data.get("source_categories")),
        in_paper=_bool(source, "in_paper", data.get("in_paper", False)),
        track_template=_bool(source, "track_template", data.get("track_template", False)),
        description=_string(source, "description", data.get("description"), required=False) or "",
        freeze=_strings(source, "freeze", data.get("freeze")),
        viewpoint=_viewpoint(source, data.get("viewpoint", {})),
    )
    diagonal = _pair(source, "diagonal_m", data.get("diagonal_m"))
    rest_text = _string(source, "rest", data.get("rest"))
    try:
        return CategoryConvention(name, tuple(part_names), tuple(out), diagonal, rest_text, **fields)
    except ValueError as exc:
        key = "order_by" if "order_by" in str(exc) else "diagonal_m"
        _fail(source, key, str(exc))


def _viewpoint(source, table) -> tuple:
    """The ``[viewpoint]`` table as ``ViewpointRange`` keyword pairs (radians, diagonals)."""
    if not isinstance(table, dict):
        _fail(source, "viewpoint", "expected a [viewpoint] table")
    _unknown(source, "viewpoint", table, set(_VIEWPOINT_KEYS))
    out = []
    for key, value in table.items():
        field, kind = _VIEWPOINT_KEYS[key]
        where = f"viewpoint.{key}"
        if kind.startswith("pair"):
            lo, hi = _pair(source, where, value, strict=False)
            value = (math.radians(lo), math.radians(hi)) if kind == "pair_deg" else (lo, hi)
        else:
            value = _number(source, where, value)
            value = math.radians(value) if kind == "deg" else value
        out.append((field, value))
    try:
        ViewpointRange(**dict(out))
    except ValueError as exc:
        _fail(source, "viewpoint", str(exc))
    return tuple(out)


def _bool(source, key: str, value) -> bool:
    if not isinstance(value, bool):
        _fail(source, key, f"expected true or false, got {value!r}")
    return value


def spec_file(path) -> Path:
    """The spec file of ``path``: the file itself, or a category folder's :data:`SPEC_FILE`.

    Raises
    ------
    SpecError
        Neither a ``.toml`` file nor a folder holding one.
    """
    path = Path(path)
    if path.is_dir():
        path = path / SPEC_FILE
        if not path.is_file():
            raise SpecError(f"{path.parent}: not a category folder (it holds no {SPEC_FILE})")
    elif not path.is_file():
        raise SpecError(f"{path}: no such category spec file or category folder")
    return path


def load_spec(path) -> CategoryConvention:
    """Read a spec file (or a category folder's :data:`SPEC_FILE`) into its convention.

    The convention's ``folder`` is the file's folder when it is a category folder (its weights,
    calibrations and template live there), else ``None``.

    Raises
    ------
    SpecError
        Naming the file and the key (:func:`parse_spec`), or a file that is not TOML.
    """
    file = spec_file(path).resolve()
    try:
        data = tomllib.loads(file.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(f"{file}: cannot read it: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{file}: not valid TOML: {exc}") from None
    conv = parse_spec(data, file)
    folder = file.parent if file.name == SPEC_FILE else None
    return dataclasses.replace(conv, spec_path=str(file), folder=None if folder is None else str(folder))


def builtin_spec_paths() -> list[Path]:
    """The built-in categories' spec files, in their listed order (``specs/ORDER``)."""
    order = (BUILTIN_SPECS_DIR / "ORDER").read_text().split()
    return [BUILTIN_SPECS_DIR / f"{name}.toml" for name in order]


def search_path_specs(value: str | None = None) -> list[Path]:
    """Spec files found on the category search path (:data:`SEARCH_PATH_VARIABLE`).

    Each entry of the path is a category folder, a spec file, or a folder of those.
    """
    value = os.environ.get(SEARCH_PATH_VARIABLE, "") if value is None else value
    out = []
    for entry in filter(None, value.split(os.pathsep)):
        root = Path(entry)
        if root.is_file() or (root / SPEC_FILE).is_file():
            out.append(spec_file(root))
        elif root.is_dir():
            out.extend(sorted(p for p in root.glob("*.toml")))
            out.extend(sorted(p / SPEC_FILE for p in root.iterdir() if (p / SPEC_FILE).is_file()))
    return out


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(float(value)) if isinstance(value, float) else str(value)


def _exact_deg(rad: float) -> float | None:
    """``rad`` in degrees rounded to 6 decimals when that reads back as ``rad`` exactly, else ``None``."""
    short = round(math.degrees(rad), 6)
    return short if math.radians(short) == rad else None


def _round_deg(rad: float) -> float:
    """Degrees of ``rad``, rounded where the rounded value gives ``rad`` back exactly."""
    short = _exact_deg(rad)
    return math.degrees(rad) if short is None else short


def _state_entries(joint: JointConvention) -> list[tuple]:
    """The joint's rest and range keys: metres, else degrees where every value reads back exactly, else radians."""
    if joint.type.value == "prismatic":
        return [("rest_m", joint.rest), ("range_m", list(joint.state_range))]
    deg = [_exact_deg(v) for v in (joint.rest, *joint.state_range)]
    if None not in deg:
        return [("rest_deg", deg[0]), ("range_deg", deg[1:])]
    return [("rest_rad", joint.rest), ("range_rad", list(joint.state_range))]


def spec_text(conv: CategoryConvention) -> str:
    """A convention written as a spec file (``parse_spec(tomllib.loads(spec_text(c)))`` gives ``c`` back)."""
    lines = [f"spec_version = {SPEC_VERSION}", f"name = {_toml_value(conv.name)}"]
    if conv.description:
        lines.append(f"description = {_toml_value(conv.description)}")
    lines += [f"rest = {_toml_value(conv.rest_description)}", f"diagonal_m = {_toml_value(list(conv.diagonal_range))}"]
    if conv.order_by is not None:
        lines.append(f"order_by = {_toml_value(conv.order_by)}")
    lines += [f"source_categories = {_toml_value(list(conv.source_categories))}",
              f"in_paper = {_toml_value(conv.in_paper)}"]
    if conv.track_template:
        lines.append(f"track_template = {_toml_value(conv.track_template)}")
    if conv.freeze:
        lines.append(f"freeze = {_toml_value(list(conv.freeze))}")
    if conv.viewpoint:
        names = {field: key for key, (field, _) in _VIEWPOINT_KEYS.items()}
        kinds = dict(_VIEWPOINT_KEYS.values())
        lines += ["", "[viewpoint]"]
        for field, value in conv.viewpoint:
            kind = kinds[field]
            if kind == "pair_deg":
                value = [_round_deg(v) for v in value]
            elif kind == "deg":
                value = _round_deg(value)
            lines.append(f"{names[field]} = {_toml_value(list(value) if isinstance(value, tuple) else value)}")
    by_child = {j.child: j for j in conv.joints}
    for name in conv.part_names:
        lines += ["", "[[parts]]", f"name = {_toml_value(name)}"]
        if name in by_child:
            j = by_child[name]
            if j.semantics:
                lines.append(f"semantics = {_toml_value(list(j.semantics))}")
            if j.links:
                lines.append(f"links = {_toml_value(list(j.links))}")
    for j in conv.joints:
        lines += ["", "[[joints]]", f"name = {_toml_value(j.name)}", f"type = {_toml_value(j.type.value)}",
                  f"parent = {_toml_value(j.parent)}", f"child = {_toml_value(j.child)}",
                  f"zero = {_toml_value(j.zero)}", f"positive = {_toml_value(j.positive)}",
                  f"side = {_toml_value(list(j.side))}"]
        lines += [f"{key} = {_toml_value(value)}" for key, value in _state_entries(j)]
    return "\n".join(lines) + "\n"
