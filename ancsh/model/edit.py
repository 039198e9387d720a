"""New models from old ones: scale, re-parameterise a joint, rename and reorder parts.

Every function returns a new :class:`~ancsh.model.articulated.ArticulatedModel` and leaves its
input untouched; meshes are copied where they change. The URDF importer uses these to put a
real object into its category's convention (:mod:`ancsh.data.conventions`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..geometry._checks import as_rotation
from ..geometry.transforms import Sim3
from .articulated import ArticulatedModel, Joint, Part

__all__ = ["reparameterized", "restructured", "scaled", "scaled_states", "simplified", "with_limits", "with_orientation"]


def _model(model: ArticulatedModel, parts, joints, **kw) -> ArticulatedModel:
    args = dict(name=model.name, category=model.category, R_canon_base=model.R_canon_base)
    args.update(kw)
    return ArticulatedModel(tuple(parts), tuple(joints), **args)


def scaled(model: ArticulatedModel, factor: float) -> ArticulatedModel:
    """The model uniformly scaled by ``factor`` (> 0): meshes, pivots, joint origins and
    prismatic limits and rest states scale; revolute angles do not.

    Parameters
    ----------
    model : ArticulatedModel
    factor : float
        Positive, finite scale factor (e.g. object units -> metres).
    """
    factor = float(factor)
    if not np.isfinite(factor) or factor <= 0:
        raise ValueError(f"factor: expected a positive finite scale, got {factor}")
    parts = []
    for p in model.parts:
        mesh = None
        if p.mesh is not None:
            mesh = p.mesh.copy()
            mesh.apply_scale(factor)
        parts.append(Part(p.name, mesh))
    joints = []
    for j in model.joints:
        s = 1.0 if j.is_revolute else factor
        origin = Sim3(j.origin.rotation, factor * j.origin.translation)
        joints.append(replace(j, pivot=factor * j.pivot, origin=origin, lower=s * j.lower, upper=s * j.upper, rest=s * j.rest))
    return _model(model, parts, joints)


def scaled_states(model: ArticulatedModel, q, factor: float) -> np.ndarray:
    """Joint states ``(K,)`` of ``model`` carried to ``scaled(model, factor)``: prismatic states (metres) scale,
    revolute ones (radians) do not, so every part keeps its place relative to the scaled base."""
    revolute = np.array([j.is_revolute for j in model.joints], dtype=bool)
    q = np.asarray(q, dtype=np.float64)
    return np.where(revolute, q, float(factor) * q)


def simplified(model: ArticulatedModel, max_faces: int) -> ArticulatedModel:
    """The model with every part mesh of more than ``max_faces`` triangles decimated to about that
    many (open3d quadric decimation); joints unchanged, smaller meshes kept as they are.

    Parameters
    ----------
    model : ArticulatedModel
    max_faces : int
        Triangle budget per part, ``>= 4``.
    """
    import open3d as o3d
    import trimesh

    if isinstance(max_faces, bool) or int(max_faces) != max_faces or max_faces < 4:
        raise ValueError(f"max_faces: expected an integer >= 4, got {max_faces!r}")
    parts = []
    for p in model.parts:
        if p.mesh is None or len(p.mesh.faces) <= max_faces:
            parts.append(p)
            continue
        m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.asarray(p.mesh.vertices, dtype=np.float64)),
                                      o3d.utility.Vector3iVector(np.asarray(p.mesh.faces, dtype=np.int32)))
        m = m.simplify_quadric_decimation(int(max_faces))
        mesh = trimesh.Trimesh(np.asarray(m.vertices), np.asarray(m.triangles), process=False)
        parts.append(Part(p.name, mesh))
    return _model(model, parts, model.joints)


def reparameterized(model: ArticulatedModel, k: int, *, zero: float, sign: int = 1, rest: float | None = None,
                    name: str | None = None) -> ArticulatedModel:
    """Joint ``k`` re-parameterised as ``q_new = sign * (q_old - zero)``; same motion.

    The child's pose at ``q_new`` equals the old pose at ``q_old = zero + sign * q_new``:
    the joint origin absorbs the old motion at ``zero`` and the axis is flipped when
    ``sign = -1``; limits are mapped and re-ordered.

    Parameters
    ----------
    model : ArticulatedModel
    k : int
        Joint index.
    zero : float
        Old state that becomes state 0 (radians or model units).
    sign : {1, -1}
    rest : float, optional
        New rest state (in the new parameterisation; default: the old rest mapped).
    name : str, optional
        New joint name.
    """
    if sign not in (1, -1):
        raise ValueError(f"sign: expected 1 or -1, got {sign!r}")
    if not 0 <= k < model.num_joints:
        raise ValueError(f"k: joint index {k} outside 0..{model.num_joints - 1}")
    j = model.joints[k]
    zero = float(zero)
    if not np.isfinite(zero):
        raise ValueError(f"zero: expected a finite state, got {zero}")
    origin = j.motion(zero) @ j.origin
    lo, hi = sorted((sign * (j.lower - zero), sign * (j.upper - zero)))
    new_rest = sign * (j.rest - zero) if rest is None else float(rest)
    new = Joint(name or j.name, j.type, j.parent, j.child, axis=sign * j.axis, pivot=j.pivot,
                lower=lo, upper=hi, rest=new_rest, origin=origin)
    joints = list(model.joints)
    joints[k] = new
    return _model(model, model.parts, joints)


def restructured(model: ArticulatedModel, part_order, part_names, joint_names=None) -> ArticulatedModel:
    """Parts reordered and renamed; joints reordered so that joint ``k`` moves new part ``k+1``.

    Parameters
    ----------
    part_order : sequence of int
        Old part index of each new part (a permutation; new part 0 must be the base).
    part_names : sequence of str
        New name of each new part.
    joint_names : sequence of str, optional
        New name of each new joint (default: keep the names).
    """
    order = [int(i) for i in part_order]
    if sorted(order) != list(range(model.num_parts)):
        raise ValueError(f"part_order: expected a permutation of 0..{model.num_parts - 1}, got {order}")
    if order[0] != model.base_index:
        raise ValueError(f"part_order: the new part 0 must be the base (old part {model.base_index}), got {order[0]}")
    if len(part_names) != len(order):
        raise ValueError(f"part_names: expected {len(order)} names, got {len(part_names)}")
    rename = {model.parts[old].name: new for old, new in zip(order, part_names)}
    parts = [Part(rename[model.parts[old].name], model.parts[old].mesh) for old in order]
    joints = []
    for new_child in range(1, len(order)):
        k = model.parent_joint(order[new_child])
        j = model.joints[k]
        jname = j.name if joint_names is None else joint_names[new_child - 1]
        joints.append(replace(j, name=jname, parent=rename[j.parent], child=rename[j.child]))
    return _model(model, parts, joints)


def with_limits(model: ArticulatedModel, lower, upper) -> ArticulatedModel:
    """The model with its joints' limits replaced by ``lower`` / ``upper`` ``(K,)`` (radians or model units;
    ``-inf`` / ``inf`` for none); geometry, axes and rest states unchanged.

    Raises
    ------
    ValueError
        Naming ``lower`` or ``upper``: a wrong shape, NaN, ``lower > upper``, or a rest state outside the new limits.
    """
    from ..geometry._checks import as_array

    K = model.num_joints
    lo = as_array(lower, "lower", (K,), finite=False)
    hi = as_array(upper, "upper", (K,), finite=False)
    for name, v in (("lower", lo), ("upper", hi)):
        if np.any(np.isnan(v)):
            raise ValueError(f"{name}: contains NaN")
    rest = model.rest_states
    bad = np.nonzero((lo > hi) | (rest < lo) | (rest > hi))[0]
    if bad.size:
        k = int(bad[0])
        raise ValueError(f"lower, upper: joint {model.joints[k].name!r} gets [{lo[k]:.6g}, {hi[k]:.6g}], which must be "
                         f"ordered and hold its rest state {rest[k]:.6g}")
    joints = [replace(j, lower=float(a), upper=float(b)) for j, a, b in zip(model.joints, lo, hi)]
    return _model(model, model.parts, joints)


def with_orientation(model: ArticulatedModel, R_canon_base) -> ArticulatedModel:
    """The same model with another canonical orientation ``R_canon_base`` (3, 3)."""
    R = as_rotation(R_canon_base, "R_canon_base")
    return _model(model, model.parts, model.joints, R_canon_base=R)
