"""Writing an :class:`~ancsh.model.articulated.ArticulatedModel` as a URDF folder (simulators, planners, yourdfpy).

The model's joints move a child by ``M(q) @ origin`` (``M`` about the axis through the pivot, both in the
parent's part frame); URDF rotates a child's *link frame* about the joint frame's origin. Each URDF joint
frame therefore sits on the pivot with the parent part's axes, and each part's frame is its link frame
times a fixed offset ``D = Trans(-pivot) @ origin`` (the identity for the base), which the visuals and the
children's joints carry. At the same joint values the URDF's part frames equal the model's.

The folder holds ``<name>.urdf``, ``meshes/<index>_<part>.obj`` (the part meshes in their part frames, metres) and
``joint_states.json`` (the states to load the model at: URDF has no initial position). A root link (no
geometry) carries the base through a fixed joint placed at ``T_root_base``: the camera frame of a fit, or a
frame the user gives.

The root frame says nothing about which way is up (a camera's +z is its viewing direction), so the file also holds
one ``<ancsh>`` element (:data:`OBJECT_ELEMENT`; URDF readers ignore elements they do not know) naming the base link,
the model's canonical orientation there and its category::

    <ancsh base_link="base" canonical_rpy="r p y" rest="1.5707963267948966" category="laptop"/>

``canonical_rpy`` is ``R_canon_base`` (the base link's frame -> the canonical +x right, +y up, +z front) as URDF
roll, pitch, yaw; ``rest`` the model's rest states in joint order (the states that define its canonical space: a
laptop's display upright, not URDF's 0). :func:`ancsh.data.urdf.load_urdf` reads it: the object starts at the base
link (the root link and the fixed joint placing the base are where the object was put, not part of it), so
``ancsh data import`` and ``ancsh fit-cad`` see the model that was written, with its base frame, orientation, rest
states and category.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..geometry.transforms import Sim3
from .articulated import ArticulatedModel

__all__ = ["OBJECT_ELEMENT", "check_urdf_folder", "rpy_matrix", "write_urdf", "urdf_rpy"]

#: The element of a written URDF that names its base link, canonical orientation and category (module docstring).
OBJECT_ELEMENT = "ancsh"


def urdf_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw of a rotation matrix ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (radians)."""
    R = np.asarray(R, dtype=np.float64)
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if math.hypot(R[0, 0], R[1, 0]) < 1e-12:  # gimbal lock: yaw folded into roll
        return math.atan2(-R[1, 2], R[1, 1]), pitch, 0.0
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """The rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` (3, 3) of URDF roll, pitch, yaw (radians); inverse of
    :func:`urdf_rpy`."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    Ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    Rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    return Rz @ Ry @ Rx


def _origin(T: Sim3) -> str:
    xyz = " ".join(repr(float(v)) for v in T.translation)
    rpy = " ".join(repr(float(v)) for v in urdf_rpy(T.rotation))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def _name(text: str) -> str:
    return quoteattr(str(text))


def check_urdf_folder(folder, *, overwrite: bool = False, argument: str = "folder",
                      overwrite_hint: str = "overwrite it") -> Path:
    """``folder`` as a Path where a URDF may be written: not a symbolic link (nothing is written through a link), and
    not an existing non-empty folder (or a file) unless ``overwrite``; ``ValueError`` naming ``argument`` otherwise
    (command-line options check before any work with their own name and hint)."""
    folder = Path(folder)
    if folder.is_symlink():
        raise ValueError(f"{argument}: {folder} is a symbolic link; give the folder itself (nothing is written through "
                         "a link)")
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())) and not overwrite:
        raise ValueError(f"{argument}: {folder} exists and is not empty; choose another folder or {overwrite_hint}")
    return folder


def write_urdf(model: ArticulatedModel, folder, *, states=None, T_root_base: Sim3 | None = None, root: str = "camera",
               name: str | None = None, overwrite: bool = False) -> Path:
    """Write ``model`` as a URDF folder (see the module docstring); returns the ``.urdf`` path.

    Parameters
    ----------
    model : ArticulatedModel
        Every part meshed; metres.
    folder : str or Path
        Created; an existing non-empty folder is refused unless ``overwrite``.
    states : (K,) array_like, optional
        Joint states written to ``joint_states.json`` (default: the rest states). A limit that would exclude
        a state is widened to it (and said in the file's comment).
    T_root_base : Sim3, optional
        Rigid pose of the base part in the root link's frame (default: the identity).
    root : str
        Name of the root link (``"camera"`` for a fit in the camera frame).
    name : str, optional
        Robot name and file stem (default: the model's name).
    overwrite : bool
        Replace the files of an existing folder.

    Raises
    ------
    ValueError
        A part without a mesh, states of the wrong shape, a non-rigid ``T_root_base``, a root name that is a part's,
        or an existing folder without ``overwrite``.
    """
    from ..outputs import write_bytes_atomically

    if not isinstance(model, ArticulatedModel):
        raise ValueError(f"model: expected an ArticulatedModel, got {type(model).__name__}")
    missing = [p.name for p in model.parts if p.mesh is None]
    if missing:
        raise ValueError(f"model: part(s) {missing} have no mesh to export")
    q = model.rest_states if states is None else np.asarray(states, dtype=np.float64)
    if q.shape != (model.num_joints,) or not np.all(np.isfinite(q)):
        raise ValueError(f"states: expected {model.num_joints} finite joint states, got {np.asarray(states).tolist()}")
    T_root_base = Sim3() if T_root_base is None else T_root_base
    if not isinstance(T_root_base, Sim3) or abs(T_root_base.scale - 1.0) > 1e-9:
        raise ValueError("T_root_base: expected a rigid Sim3 (scale 1)")
    if root in model.part_names:
        raise ValueError(f"root: {root!r} is also a part's name; choose another root link name")
    folder = check_urdf_folder(folder, overwrite=overwrite)
    stem = name or model.name or "object"
    links = [f"  <link name={_name(root)}/>"]
    offsets = {i: Sim3() for i in range(model.num_parts)}  # part index -> D (part frame in its link frame)
    for k, j in enumerate(model.joints):
        offsets[model.joint_parts(k)[1]] = Sim3(np.eye(3), -j.pivot) @ j.origin
    widened = []
    joints = [f'  <joint name={_name(f"{root}_to_{model.parts[model.base_index].name}")} type="fixed">'
              f"<parent link={_name(root)}/><child link={_name(model.parts[model.base_index].name)}/>"
              f"{_origin(Sim3(T_root_base.rotation, T_root_base.translation))}</joint>"]
    for k, j in enumerate(model.joints):
        p, c = model.joint_parts(k)
        J = offsets[p] @ Sim3(np.eye(3), j.pivot)  # joint frame in the parent's link frame
        lo, hi = float(j.lower), float(j.upper)
        if q[k] < lo or q[k] > hi:
            widened.append(j.name)
            lo, hi = min(lo, float(q[k])), max(hi, float(q[k]))
        kind = "revolute" if j.is_revolute else "prismatic"
        limit = (f'<limit lower="{lo!r}" upper="{hi!r}" effort="100.0" velocity="1.0"/>' if math.isfinite(lo)
                 and math.isfinite(hi) else "")
        if not limit and j.is_revolute:
            kind = "continuous"
        axis = " ".join(repr(float(v)) for v in j.axis)
        joints.append(f"  <joint name={_name(j.name)} type={_name(kind)}><parent link={_name(model.parts[p].name)}/>"
                      f"<child link={_name(model.parts[c].name)}/>{_origin(J)}<axis xyz=\"{axis}\"/>{limit}</joint>")
    for i, part in enumerate(model.parts):
        mesh_file = f"meshes/{i:02d}_{re.sub(r'[^A-Za-z0-9_.-]', '_', part.name)}.obj"  # never a path out
        write_bytes_atomically(folder / mesh_file, part.mesh.export(file_type="obj").encode())
        geom = f"{_origin(offsets[i])}<geometry><mesh filename={_name(mesh_file)}/></geometry>"
        links.append(f"  <link name={_name(part.name)}><visual>{geom}</visual><collision>{geom}</collision></link>")
    note = f" limits widened to the states of {widened}" if widened else ""
    rpy = " ".join(repr(float(v)) for v in urdf_rpy(model.R_canon_base))  # the base link's frame is the base part's
    category = f" category={_name(model.category)}" if model.category else ""
    rest = " ".join(repr(float(v)) for v in model.rest_states)
    record = (f"  <{OBJECT_ELEMENT} base_link={_name(model.parts[model.base_index].name)} canonical_rpy=\"{rpy}\""
              f" rest=\"{rest}\"{category}/>")
    text = (f'<?xml version="1.0"?>\n<!-- written by ancsh; load it at the joint states of joint_states.json.{note} -->\n'
            f"<robot name={_name(stem)}>\n" + "\n".join([record, *links, *joints]) + "\n</robot>\n")
    path = folder / f"{stem}.urdf"
    write_bytes_atomically(path, text.encode())
    write_bytes_atomically(folder / "joint_states.json",
                           (json.dumps({j.name: float(v) for j, v in zip(model.joints, q)}, indent=1) + "\n").encode())
    return path
