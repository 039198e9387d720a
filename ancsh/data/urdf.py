"""Load articulated objects from URDF (PartNet-Mobility, ReplicaCAD) into an ArticulatedModel.

What the loader does
--------------------
- Parses the file with yourdfpy (meshes are *not* resolved by yourdfpy; this module finds
  them relative to the URDF, stripping ``package://<name>/`` and ``file://`` prefixes; a mesh outside the
  URDF's folder is refused).
- Every link's ``<visual>`` geometry (meshes, boxes, cylinders, spheres), with its
  ``<origin>`` and mesh ``scale``, is put into the link frame; a link may carry many
  meshes. OBJ files load without materials; glTF/GLB files (ReplicaCAD) load as scenes and
  are flattened with their scene-graph transforms.
- ``fixed`` joints are merged: the child link's geometry joins its parent's part, in the
  parent part's frame. Each remaining movable joint starts a new part whose frame is its
  child link's frame. Parts are ordered root first, then breadth-first in file order;
  joint ``k`` moves part ``k + 1``.
- Joints keep the URDF motion ``T_parent_child(q) = T_origin @ Motion(axis, q)``: in the
  parent *part* frame ``origin = T_part_link @ T_origin``, ``axis = R(origin) @ axis_urdf``
  and ``pivot`` = the child frame origin (a point on a revolute axis).
- ``continuous`` joints become unlimited revolute joints; ``floating``/``planar`` joints
  are rejected. A URDF without movable joints loads as a single part with 0 joints.
- Rest state = 0 when it lies within the limits, otherwise the limit nearest to 0 (a URDF written by ancsh: its
  own, below).
- A part whose links carry no geometry (e.g. the empty world link a ReplicaCAD door swings
  from) keeps ``mesh=None``.
- A URDF written by ancsh (:mod:`ancsh.model.urdf_export`: ``predict --urdf``, ``fit-cad --urdf-out``) names its
  base link, canonical orientation and category in an ``<ancsh>`` element: the object starts at that link (the
  geometry-free root link and the fixed joints placing the base in the camera or the user's frame are dropped, so
  the base part is the base link, in its frame), and the element gives ``R_canon_base``, the rest states and the
  category.

Orientation (``R_canon_base``, base part frame -> canonical +y up, +z front, +x right)
-------------------------------------------------------------------------------------
- PartNet-Mobility (``mobility.urdf``): the root link is SAPIEN's z-up world; the object's
  Y-up mesh frame hangs below it through a fixed joint. Up is the root's +z and the front
  faces the root's -x (the mesh frame's +Z; checked on the shared ovens, microwave, washing
  machine and drawers, whose doors/drawers sit on that side, and on the laptops and
  eyeglasses, whose displays/temples sit on the other), so the canonical axes are
  (x, y, z)_canon = (-y, z, -x)_root.
- ReplicaCAD (glTF meshes) and other URDFs: up is the root's +y (habitat's y-up world;
  the fridge's mesh file itself is z-up under a fixed rotation) or +z (other URDFs, the ROS
  convention); the front is the horizontal axis of the base part's main link (the one with
  the most visuals), with sign, that the movable parts sit on and slide along
  (:func:`estimate_front`). Objects whose base has no geometry (doors hung from an empty
  world link) get the main link's first horizontal axis.
Units are the file's (PartNet-Mobility objects are roughly unit-sized, not metres).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from ..geometry.transforms import Sim3
from ..model.articulated import ArticulatedModel, Joint, JointType, Part
from ..model.urdf_export import OBJECT_ELEMENT, rpy_matrix

_MOVABLE = {"revolute": JointType.REVOLUTE, "continuous": JointType.REVOLUTE, "prismatic": JointType.PRISMATIC}
_SUPPORTED = set(_MOVABLE) | {"fixed"}


@dataclass(frozen=True)
class _ObjectRecord:
    """What the ``<ancsh>`` element of a written URDF says (:mod:`ancsh.model.urdf_export`)."""

    base_link: str
    R_canon_base: np.ndarray  # (3, 3) the base link's frame -> canonical axes
    category: str | None
    rest: tuple | None  # (K,) rest states in joint order, radians / file units


@dataclass
class _Link:
    name: str
    part: int  # index of the part it belongs to
    T_part_link: np.ndarray  # (4, 4)


def load_urdf(path, *, category: str | None = None, joint_types=None) -> ArticulatedModel:
    """Load a URDF file into an :class:`ArticulatedModel`.

    Parameters
    ----------
    path : str or Path
        The ``.urdf`` file; mesh paths are resolved relative to its folder.
    category : str, optional
        Category to record on the model. Default: the folder name's prefix when it names a
        procedural category (``laptop_10101`` -> ``laptop``), else PartNet-Mobility's
        ``meta.json`` ``model_cat`` in snake case, else ``None``.
    joint_types : mapping of str to str, optional
        ``{urdf joint name: type}`` replacing the file's joint types before loading:
        ``"fixed"`` freezes a movable joint (a knob the category does not model);
        ``"revolute"``/``"prismatic"``/``"continuous"`` restores a joint that the file froze
        (GenSim2's copies keep one movable joint; ``mobility_v2.json`` has the others),
        using the file's ``<axis>`` and ``<limit>``. Unknown joint names raise ``ValueError``.

    Returns
    -------
    ArticulatedModel
        Meshes in each part's frame (the file's units); see the module docstring for
        merging, joint conversion, rest states and ``R_canon_base``.

    Raises
    ------
    ValueError
        Naming the file and the element: unreadable or malformed XML, a missing mesh file,
        an unsupported joint type (floating, planar), a joint referring to an unknown link,
        a zero axis, or missing limits on a revolute/prismatic joint.
    """
    path = Path(path)
    if not path.exists():
        raise ValueError(f"path: URDF file {str(path)!r} does not exist")
    if not path.is_file():
        raise ValueError(f"path: {str(path)!r} exists but is not a URDF file (a folder, a device or a pipe)")
    robot, record = _parse(path, joint_types or {})
    links = {link.name: link for link in robot.links}
    if not links:
        raise ValueError(f"{path}: <robot> has no <link> elements")
    for j in robot.joints:
        for role in ("parent", "child"):
            if getattr(j, role) not in links:
                raise ValueError(f"{path}: <joint name={j.name!r}> {role} link {getattr(j, role)!r} is not defined")
    children = {}
    for j in robot.joints:
        children.setdefault(j.parent, []).append(j)
    child_links = [j.child for j in robot.joints]
    dup = sorted({c for c in child_links if child_links.count(c) > 1})
    if dup:
        raise ValueError(f"{path}: <link name={dup[0]!r}> is the child of more than one joint")
    roots = [name for name in links if name not in child_links]
    if len(roots) != 1:
        raise ValueError(f"{path}: expected one root <link>, found {roots}")

    # --- walk the tree: merge fixed joints, start a part at each movable joint ------------
    part_links: list[list[str]] = [[roots[0]]]
    part_names = [roots[0]]
    info = {roots[0]: _Link(roots[0], 0, np.eye(4))}
    joints: list[Joint] = []
    frontier = [roots[0]]
    while frontier:
        parent = frontier.pop(0)
        pl = info[parent]
        for j in children.get(parent, []):
            T_origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=np.float64)
            if not np.all(np.isfinite(T_origin)):
                raise ValueError(f"{path}: <joint name={j.name!r}> <origin> has non-finite xyz/rpy values")
            T_ppart_origin = pl.T_part_link @ T_origin
            if j.type == "fixed":
                info[j.child] = _Link(j.child, pl.part, T_ppart_origin)
                part_links[pl.part].append(j.child)
            else:
                part = len(part_names)
                part_names.append(j.child)
                part_links.append([j.child])
                info[j.child] = _Link(j.child, part, np.eye(4))
                joints.append(_make_joint(path, j, part_names[pl.part], T_ppart_origin))
            frontier.append(j.child)
    if len(info) != len(links):
        missing = sorted(set(links) - set(info))
        raise ValueError(f"{path}: <link name={missing[0]!r}> is not connected to the root link {roots[0]!r}")

    parts = []
    for k, names in enumerate(part_links):
        pieces = []
        for name in names:
            for mesh in _link_meshes(path, links[name]):
                mesh.apply_transform(info[name].T_part_link)
                pieces.append(mesh)
        mesh = trimesh.util.concatenate(pieces) if pieces else None
        parts.append(Part(part_names[k], mesh))

    if category is None:
        category = record.category if record is not None and record.category else _guess_category(path)
    model = ArticulatedModel(tuple(parts), tuple(joints), name=_model_name(path), category=category)
    R = record.R_canon_base if record is not None else _orientation(path, links, model, info)
    if record is not None and record.rest is not None:
        joints = _with_rest(path, joints, record.rest)
    return ArticulatedModel(model.parts, tuple(joints), name=model.name, category=category, R_canon_base=R)


def _with_rest(path: Path, joints: list, rest: tuple) -> list:
    """``joints`` at the rest states of the file's ``<ancsh rest=...>``; ``ValueError`` for a wrong count or a rest
    state outside its joint's limits."""
    import dataclasses

    if len(rest) != len(joints):
        raise ValueError(f"{path}: <ancsh rest=...> must hold {len(joints)} number(s), one per movable joint "
                         f"({[j.name for j in joints]}), got {len(rest)}")
    for j, r in zip(joints, rest):
        if not j.lower <= r <= j.upper:
            raise ValueError(f"{path}: <ancsh rest=...>: joint {j.name!r} rest {r:.6g} lies outside its limits "
                             f"[{j.lower:.6g}, {j.upper:.6g}]")
    return [dataclasses.replace(j, rest=float(r)) for j, r in zip(joints, rest)]


# --- parsing ----------------------------------------------------------------------------------
def _parse(path: Path, joint_types: dict):
    import yourdfpy

    try:
        from lxml import etree

        # no entity expansion, no DTD or network access: a URDF cannot pull in other files
        parser = etree.XMLParser(resolve_entities=False, load_dtd=False, no_network=True)
        tree = etree.parse(str(path), parser)
    except Exception as exc:  # noqa: BLE001 - any parser failure is a malformed file
        raise ValueError(f"{path}: malformed URDF XML: {exc}") from None
    root = tree.getroot()
    if root.tag != "robot":
        raise ValueError(f"{path}: root element is <{root.tag}>, expected <robot>")
    by_name = {j.get("name"): j for j in root.findall("joint")}
    for name, jtype in joint_types.items():
        if name not in by_name:
            raise ValueError(f"joint_types: {path} has no <joint name={name!r}> (joints: {sorted(n for n in by_name if n)})")
        if jtype not in _SUPPORTED:
            raise ValueError(f"joint_types: type {jtype!r} of joint {name!r} is not one of {sorted(_SUPPORTED)}")
        by_name[name].set("type", jtype)
    for j in root.findall("joint"):  # direct children (<transmission> also holds <joint>)
        name, jtype = j.get("name"), j.get("type")
        if name is None or jtype is None:
            raise ValueError(f"{path}: <joint> element without name/type attribute (line {j.sourceline})")
        if jtype not in _SUPPORTED:
            raise ValueError(f"{path}: <joint name={name!r}> has unsupported type {jtype!r} (supported: {sorted(_SUPPORTED)})")
        if jtype in ("revolute", "prismatic"):
            lim = j.find("limit")
            if lim is None or lim.get("lower") is None or lim.get("upper") is None:
                raise ValueError(f"{path}: <joint name={name!r}> of type {jtype!r} needs <limit lower=.. upper=..>")
    for el in root.iter():  # ReplicaCAD writes "x, y, z": accept commas as separators
        for attr in ("xyz", "rpy"):
            if el.get(attr) is not None and "," in el.get(attr):
                el.set(attr, el.get(attr).replace(",", " "))
    seen = set()
    for link in root.findall("link"):
        name = link.get("name")
        if name is None:
            raise ValueError(f"{path}: <link> element without name attribute (line {link.sourceline})")
        if name in seen:
            raise ValueError(f"{path}: <link name={name!r}> is defined twice (line {link.sourceline})")
        seen.add(name)
    record = _object_record(path, root)
    if record is not None:
        _drop_placement(path, root, record.base_link)
    try:
        return yourdfpy.URDF._parse_robot(xml_element=root), record
    except Exception as exc:  # noqa: BLE001
        raise ValueError(f"{path}: could not read the URDF structure: {exc}") from None


def _object_record(path: Path, root) -> _ObjectRecord | None:
    """The file's ``<ancsh>`` element (:data:`~ancsh.model.urdf_export.OBJECT_ELEMENT`), or ``None`` without one."""
    found = root.findall(OBJECT_ELEMENT)
    if not found:
        return None
    if len(found) > 1:
        raise ValueError(f"{path}: {len(found)} <{OBJECT_ELEMENT}> elements; a written object has one")
    el = found[0]
    where = f"{path}: <{OBJECT_ELEMENT}> (line {el.sourceline})"
    base = el.get("base_link")
    if not base:
        raise ValueError(f"{where} has no base_link attribute (the name of the object's base link)")
    try:
        rpy = [float(v) for v in el.get("canonical_rpy", "").split()]
    except ValueError:
        rpy = []
    if len(rpy) != 3 or not np.all(np.isfinite(rpy)):
        raise ValueError(f"{where}: canonical_rpy must be 3 finite numbers (roll pitch yaw, radians), "
                         f"got {el.get('canonical_rpy')!r}")
    rest = None
    if el.get("rest") is not None:
        try:
            rest = tuple(float(v) for v in el.get("rest").split())
        except ValueError:
            rest = (np.nan,)
        if not np.all(np.isfinite(rest)):
            raise ValueError(f"{where}: rest must be finite numbers (one rest state per movable joint), "
                             f"got {el.get('rest')!r}")
    return _ObjectRecord(base, rpy_matrix(*rpy), el.get("category") or None, rest)


def _drop_placement(path: Path, root, base: str) -> None:
    """Remove, in place, the links above ``base`` and the joints between them: where a written object was placed
    (a camera or world root), not part of it. They must be free of geometry, joined by fixed joints and carry
    nothing else; ``ValueError`` naming the element otherwise."""
    links = {link.get("name"): link for link in root.findall("link")}
    if base not in links:
        raise ValueError(f"{path}: <ancsh base_link={base!r}> names no <link> of the file")
    by_child, by_parent = {}, {}
    for j in root.findall("joint"):
        parent, child = j.find("parent"), j.find("child")
        if parent is not None and child is not None:
            by_child[child.get("link")] = j
            by_parent.setdefault(parent.get("link"), []).append(j)
    chain, above, link = [], [], base
    while link in by_child and len(chain) <= len(by_child):
        j = by_child[link]
        if j.get("type") != "fixed":
            raise ValueError(f"{path}: <ancsh base_link={base!r}>: the base hangs from the {j.get('type')} joint "
                             f"{j.get('name')!r}; the links above the base may only place it (fixed joints)")
        chain.append(j)
        link = j.find("parent").get("link")
        above.append(link)
    for name in above:
        el = links.get(name)
        if el is None:
            raise ValueError(f"{path}: <ancsh base_link={base!r}>: link {name!r} above the base is not defined")
        if el.find("visual") is not None or el.find("collision") is not None:
            raise ValueError(f"{path}: <ancsh base_link={base!r}>: link {name!r} above the base carries geometry; the "
                             "links above the base may only place it")
        others = [j.get("name") for j in by_parent.get(name, []) if j not in chain]
        if others:
            raise ValueError(f"{path}: <ancsh base_link={base!r}>: link {name!r} above the base also carries the "
                             f"joint(s) {others}; the links above the base may only place it")
    for el in chain + [links[name] for name in above]:
        root.remove(el)


def _make_joint(path: Path, j, parent_part: str, T_ppart_origin: np.ndarray) -> Joint:
    axis_urdf = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, dtype=np.float64)
    n = np.linalg.norm(axis_urdf)
    if not np.isfinite(n) or n < 1e-12:
        raise ValueError(f"{path}: <joint name={j.name!r}> <axis> is zero or not finite: {axis_urdf.tolist()}")
    R = T_ppart_origin[:3, :3]
    axis = R @ (axis_urdf / n)
    pivot = T_ppart_origin[:3, 3].copy()
    if j.type == "continuous":
        lower, upper = -np.inf, np.inf
    else:
        lower, upper = float(j.limit.lower), float(j.limit.upper)
        if not (np.isfinite(lower) and np.isfinite(upper)) or lower > upper:
            raise ValueError(f"{path}: <joint name={j.name!r}> <limit> lower={lower} upper={upper} is not a valid range")
    rest = min(max(0.0, lower), upper)
    origin = Sim3(_orthonormal(R), pivot)
    return Joint(j.name, _MOVABLE[j.type], parent_part, j.child, axis=axis / np.linalg.norm(axis), pivot=pivot,
                 lower=lower, upper=upper, rest=rest, origin=origin)


def _orthonormal(R: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(R)
    out = U @ Vt
    if np.linalg.det(out) < 0:
        U[:, -1] *= -1
        out = U @ Vt
    return out


# --- geometry ------------------------------------------------------------------------------
def _resolve(path: Path, filename: str, where: str = "mesh") -> Path:
    """The mesh file ``filename`` names, inside the URDF's folder; ``ValueError`` for one that lies elsewhere
    (an absolute path, ``..`` leaving the folder, ``file://``, ``package://x/../..`` or a link pointing out):
    a URDF must not open files outside its object's folder."""
    name = re.sub(r"^file://", "", filename)
    m = re.match(r"^package://[^/]+/(.*)$", name)
    if m:
        name = m.group(1)
    folder = path.parent.resolve()
    p = Path(name)
    file = (folder / p).resolve()
    if p.is_absolute() or not file.is_relative_to(folder):
        raise ValueError(f"{path}: {where} mesh file {filename!r} lies outside the object's folder {folder}; "
                         "meshes are read from inside it only")
    return file


def _link_meshes(path: Path, link) -> list:
    out = []
    for i, visual in enumerate(link.visuals):
        geom = visual.geometry
        where = f"<link name={link.name!r}> <visual> #{i}"
        if geom is None:
            raise ValueError(f"{path}: {where} has no <geometry>")
        if geom.mesh is not None:
            file = _resolve(path, geom.mesh.filename, where)
            if not file.is_file():
                raise ValueError(f"{path}: {where} mesh file {geom.mesh.filename!r} not found (looked for {file})")
            mesh = _load_mesh_file(path, where, file)
            scale = geom.mesh.scale
            if scale is not None:
                S = np.eye(4)
                S[:3, :3] = np.diag(np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,)))
                mesh.apply_transform(S)
        elif geom.box is not None:
            mesh = trimesh.creation.box(extents=np.asarray(geom.box.size, dtype=np.float64))
        elif geom.cylinder is not None:
            mesh = trimesh.creation.cylinder(radius=float(geom.cylinder.radius), height=float(geom.cylinder.length))
        elif geom.sphere is not None:
            mesh = trimesh.creation.icosphere(subdivisions=2, radius=float(geom.sphere.radius))
        else:
            raise ValueError(f"{path}: {where} has an unsupported <geometry> element")
        if visual.origin is not None:
            mesh.apply_transform(np.asarray(visual.origin, dtype=np.float64))
        if len(mesh.faces):
            out.append(mesh)
    return out


def _load_mesh_file(path: Path, where: str, file: Path) -> trimesh.Trimesh:
    try:
        kwargs = {"skip_materials": True} if file.suffix.lower() == ".obj" else {}
        loaded = trimesh.load(str(file), process=False, **kwargs)
    except Exception as exc:  # noqa: BLE001
        raise ValueError(f"{path}: {where} mesh file {file.name!r} could not be read: {exc}") from None
    if isinstance(loaded, trimesh.Scene):
        geoms = []
        for node in loaded.graph.nodes_geometry:
            T, gname = loaded.graph[node]
            g = loaded.geometry[gname]
            if isinstance(g, trimesh.Trimesh) and len(g.faces):
                g = trimesh.Trimesh(np.asarray(g.vertices), np.asarray(g.faces), process=False)
                g.apply_transform(T)
                geoms.append(g)
        if not geoms:
            raise ValueError(f"{path}: {where} mesh file {file.name!r} holds no triangles")
        return trimesh.util.concatenate(geoms)
    if not isinstance(loaded, trimesh.Trimesh):
        raise ValueError(f"{path}: {where} mesh file {file.name!r} holds no triangle mesh")
    return trimesh.Trimesh(np.asarray(loaded.vertices), np.asarray(loaded.faces), process=False)


# --- naming, category, orientation ----------------------------------------------------------
def _model_name(path: Path) -> str:
    return path.parent.name if path.name == "mobility.urdf" else path.stem


def _guess_category(path: Path) -> str | None:
    from .procedural import CATEGORIES

    prefix = re.sub(r"_\d+$", "", path.parent.name)
    if prefix in CATEGORIES:
        return prefix
    meta = path.parent / "meta.json"
    if meta.is_file():
        try:
            cat = json.loads(meta.read_text()).get("model_cat")
        except (ValueError, OSError):
            return None
        if isinstance(cat, str) and cat:
            return re.sub(r"(?<!^)(?=[A-Z])", "_", cat).lower()
    return None


def _is_partnet(path: Path) -> bool:
    return path.name == "mobility.urdf"


def _main_link_rotation(links: dict, model: ArticulatedModel, info: dict) -> np.ndarray:
    """Rotation from the frame of the base part's link with the most visual geometry to the
    base part frame (the frame the mesh files were authored in)."""
    best, best_count = None, -1
    for name, link in info.items():
        if link.part != model.base_index:
            continue
        count = sum(1 for v in links[name].visuals if v.geometry is not None)
        if count > best_count:
            best, best_count = name, count
    return info[best].T_part_link[:3, :3]


def _orientation(path: Path, links: dict, model: ArticulatedModel, info: dict) -> np.ndarray:
    if _is_partnet(path):
        # SAPIEN world: z up, the objects' fronts face -x (their mesh frame: Y up, front +Z).
        return canonical_rotation(model, up=[0.0, 0.0, 1.0], front=[-1.0, 0.0, 0.0])
    R_main = _main_link_rotation(links, model, info)
    uses_gltf = any(
        v.geometry is not None and v.geometry.mesh is not None and v.geometry.mesh.filename.lower().endswith((".glb", ".gltf"))
        for link in links.values()
        for v in link.visuals
    )
    # ReplicaCAD (glTF meshes): habitat's y-up world is the root frame (the mesh files
    # themselves are not consistently y-up); otherwise the ROS convention (z up)
    up = np.array([0.0, 1.0, 0.0]) if uses_gltf else np.array([0.0, 0.0, 1.0])
    axes = [R_main[:, i] for i in range(3) if abs(R_main[:, i] @ up) < 0.5]
    if not axes:  # a main link tilted so that no axis lies within 60 deg of horizontal: its two most nearly horizontal
        axes = [R_main[:, i] for i in np.argsort(np.abs(R_main.T @ up))[:2]]
    return canonical_rotation(model, up, front=estimate_front(model, up, axes))


def estimate_front(model: ArticulatedModel, up, axes=None) -> np.ndarray:
    """A horizontal base-frame direction facing the object's front, estimated from its
    movable parts: one of ``+-axes`` (default: the base-frame axes perpendicular to ``up``).

    Doors and drawers sit on the front face and open towards it: for each movable part the
    vector from the base's box centre to the part's box centre at rest, plus (prismatic)
    the axis signed towards that offset, votes for the best-aligned horizontal axis,
    weighted by the part's size. Objects without movable geometry face +x.
    """
    up = np.asarray(up, dtype=np.float64)
    if axes is None:
        axes = [c for c in np.eye(3) if abs(c @ up) < 0.5]
    candidates = [np.asarray(c, dtype=np.float64) for c in axes]
    candidates = candidates + [-c for c in candidates]
    base = model.parts[model.base_index]
    if base.mesh is None or not model.joints:
        return candidates[0]
    poses = model.forward_kinematics(model.rest_states)
    b_lo, b_hi = base.vertices.min(axis=0), base.vertices.max(axis=0)
    half = np.maximum((b_hi - b_lo) / 2, 1e-9)
    centre = (b_lo + b_hi) / 2
    score = np.zeros(len(candidates))
    for k, joint in enumerate(model.joints):
        child = model.joint_parts(k)[1]
        part = model.parts[child]
        if part.mesh is None:
            continue
        v = poses[child].apply(part.vertices)
        offset = ((v.min(axis=0) + v.max(axis=0)) / 2 - centre) / half
        weight = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
        for i, c in enumerate(candidates):
            score[i] += weight * (offset @ c)
            if not joint.is_revolute:
                axis = poses[model.joint_parts(k)[0]].apply_direction(joint.axis)
                score[i] += weight * abs(axis @ c) * np.sign(offset @ c)
    return candidates[int(np.argmax(score))]


def canonical_rotation(model: ArticulatedModel, up, front=None) -> np.ndarray:
    """Rotation ``R_canon_base`` taking ``up`` (3,) to +y and ``front`` (3,, perpendicular
    to ``up``; default: :func:`estimate_front`) to +z."""
    up = np.asarray(up, dtype=np.float64)
    up = up / np.linalg.norm(up)
    if front is None:
        front = estimate_front(model, up)
    front = np.asarray(front, dtype=np.float64)
    front = front - (front @ up) * up
    front = front / np.linalg.norm(front)
    right = np.cross(up, front)
    return np.stack([right, up, front])
