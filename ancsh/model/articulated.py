"""Articulated models: rigid parts connected by revolute and prismatic joints in a tree.

Conventions
-----------
- Every part has its own frame; its mesh vertices are given in that frame (metres).
- The root ("base") part is the one part that is no joint's child. ``T_base_part``
  maps part-frame points to the base frame.
- A joint stores ``origin = T_parent_child`` at joint state 0, and its ``axis`` (unit)
  and ``pivot`` in the *parent* frame. At state ``q`` (radians for revolute, metres
  for prismatic):

  ``T_parent_child(q) = M(q) @ origin`` where ``M(q)`` rotates by ``q`` about the line
  ``(pivot, axis)`` (revolute) or translates by ``q * axis`` (prismatic).
- Joint state vectors are ordered like :attr:`ArticulatedModel.joints`.
- ``rest`` is the joint state that defines NAOCS (paper Sec. 4.1).
- ``R_canon_base`` rotates the base frame into the category's canonical orientation
  (NAOCS axes); procedural objects are built canonical (identity).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from ..geometry._checks import as_array, as_rotation, check_generator
from ..geometry.rotations import axis_angle_matrix
from ..geometry.transforms import Sim3


class JointType(str, Enum):
    REVOLUTE = "revolute"
    PRISMATIC = "prismatic"


def joint_tree_root(num_parts: int, joint_children) -> int:
    """The part that is no joint's child (the base) of a joint tree given by index arrays."""
    kids = {int(c) for c in joint_children}
    return next(j for j in range(num_parts) if j not in kids)


def joint_tree_order(num_parts: int, joint_parents, joint_children) -> tuple[int, ...]:
    """Joint indices ordered so that every joint's parent part is placed before it (from the root)."""
    parents, children = [int(p) for p in joint_parents], [int(c) for c in joint_children]
    placed, order = {joint_tree_root(num_parts, children)}, []
    while len(order) < len(parents):
        for k in range(len(parents)):
            if k not in order and parents[k] in placed:
                order.append(k)
                placed.add(children[k])
    return tuple(order)


@dataclass(frozen=True, eq=False)
class Part:
    """A rigid part.

    Attributes
    ----------
    name : str
        Unique name within the model.
    mesh : trimesh.Trimesh or None
        Surface in the part frame (metres). ``None`` only for mesh-less test models.
    """

    name: str
    mesh: object = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name: expected a non-empty string, got {self.name!r}")

    @property
    def vertices(self) -> np.ndarray:
        """Mesh vertices ``(V, 3)`` in the part frame (metres)."""
        if self.mesh is None:
            raise ValueError(f"part {self.name!r} has no mesh")
        return np.asarray(self.mesh.vertices, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class Joint:
    """A one-degree-of-freedom joint between a parent and a child part.

    Attributes
    ----------
    name : str
    type : JointType
    parent, child : str
        Part names.
    axis : (3,) float64
        Unit axis in the parent frame.
    pivot : (3,) float64
        A point on the axis in the parent frame (metres); ignored by prismatic joints'
        motion but kept as a reference point.
    lower, upper : float
        Limits (radians or metres); ``-inf``/``inf`` for an unlimited revolute joint.
    rest : float
        Rest state defining NAOCS, within the limits.
    origin : Sim3
        Rigid ``T_parent_child`` at joint state 0.
    """

    name: str
    type: JointType
    parent: str
    child: str
    axis: np.ndarray
    pivot: np.ndarray = field(default_factory=lambda: np.zeros(3))
    lower: float = -np.inf
    upper: float = np.inf
    rest: float = 0.0
    origin: Sim3 = field(default_factory=Sim3)

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"joint name: expected a non-empty string, got {self.name!r}")
        try:
            jtype = JointType(self.type)
        except ValueError:
            raise ValueError(f"joint {self.name!r}: type must be 'revolute' or 'prismatic', got {self.type!r}") from None
        axis = as_array(self.axis, f"joint {self.name!r} axis", (3,))
        n = np.linalg.norm(axis)
        if abs(n - 1.0) > 1e-6:
            raise ValueError(f"joint {self.name!r} axis: expected a unit vector, got norm {n:.6g}")
        pivot = as_array(self.pivot, f"joint {self.name!r} pivot", (3,))
        lower, upper, rest = float(self.lower), float(self.upper), float(self.rest)
        if np.isnan(lower) or np.isnan(upper) or not np.isfinite(rest):
            raise ValueError(f"joint {self.name!r}: limits and rest must be numbers")
        if not lower <= upper:
            raise ValueError(f"joint {self.name!r}: lower limit {lower} exceeds upper limit {upper}")
        if jtype == JointType.PRISMATIC and not (np.isfinite(lower) and np.isfinite(upper)):
            raise ValueError(f"joint {self.name!r}: a prismatic joint needs finite limits")
        if not lower <= rest <= upper:
            raise ValueError(f"joint {self.name!r}: rest state {rest} outside limits [{lower}, {upper}]")
        if not isinstance(self.origin, Sim3) or not self.origin.is_rigid:
            raise ValueError(f"joint {self.name!r} origin: expected a rigid Sim3 (scale 1)")
        if self.parent == self.child:
            raise ValueError(f"joint {self.name!r}: parent and child are the same part {self.parent!r}")
        object.__setattr__(self, "type", jtype)
        object.__setattr__(self, "axis", axis / n)
        object.__setattr__(self, "pivot", pivot)
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(self, "rest", rest)

    @property
    def is_revolute(self) -> bool:
        return self.type == JointType.REVOLUTE

    def motion(self, q: float) -> Sim3:
        """``M(q)`` in the parent frame (see module docstring)."""
        if self.is_revolute:
            R = axis_angle_matrix(self.axis, q)
            return Sim3(R, self.pivot - R @ self.pivot)
        return Sim3(np.eye(3), q * self.axis)

    def T_parent_child(self, q: float) -> Sim3:
        return self.motion(q) @ self.origin


@dataclass(frozen=True, eq=False)
class ArticulatedModel:
    """Parts connected by joints in a tree, validated on construction.

    Attributes
    ----------
    parts : tuple of Part
        Part order defines part labels ``0..M-1``. Procedural categories put the base first.
    joints : tuple of Joint
        Joint order defines joint indices ``0..K-1`` and the joint state vector.
    name : str
        Instance name.
    category : str or None
        Category name (e.g. ``"laptop"``) for category-level models.
    R_canon_base : (3, 3) float64
        Rotation from the base frame to the canonical (NAOCS) orientation.
    """

    parts: tuple
    joints: tuple
    name: str = "object"
    category: str | None = None
    R_canon_base: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self):
        parts = tuple(self.parts)
        joints = tuple(self.joints)
        if not parts:
            raise ValueError("parts: an articulated model needs at least one part")
        for p in parts:
            if not isinstance(p, Part):
                raise ValueError(f"parts: expected Part objects, got {type(p).__name__}")
        for j in joints:
            if not isinstance(j, Joint):
                raise ValueError(f"joints: expected Joint objects, got {type(j).__name__}")
        names = [p.name for p in parts]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"parts: duplicate part names {sorted(dup)}")
        jnames = [j.name for j in joints]
        dup = {n for n in jnames if jnames.count(n) > 1}
        if dup:
            raise ValueError(f"joints: duplicate joint names {sorted(dup)}")
        index = {n: i for i, n in enumerate(names)}
        for j in joints:
            for role in ("parent", "child"):
                if getattr(j, role) not in index:
                    raise ValueError(f"joint {j.name!r}: {role} {getattr(j, role)!r} is not a part of the model")
        children = [j.child for j in joints]
        dup = {c for c in children if children.count(c) > 1}
        if dup:
            raise ValueError(f"joints: part(s) {sorted(dup)} have more than one parent joint (not a tree)")
        roots = [n for n in names if n not in children]
        if len(roots) != 1 or len(joints) != len(parts) - 1:
            raise ValueError(
                f"joints: parts and joints do not form one tree ({len(parts)} parts, {len(joints)} joints, roots {roots})"
            )
        # Topological order from the root; detects cycles and disconnected parts.
        order, frontier = [], [roots[0]]
        while frontier:
            n = frontier.pop(0)
            order.append(n)
            frontier.extend(j.child for j in joints if j.parent == n)
        if len(order) != len(parts):
            raise ValueError("joints: the joint graph has a cycle or a disconnected part")
        R = as_rotation(self.R_canon_base, "R_canon_base")
        object.__setattr__(self, "parts", parts)
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "R_canon_base", R.copy())
        object.__setattr__(self, "_index", index)
        object.__setattr__(self, "_order", tuple(index[n] for n in order))
        object.__setattr__(self, "_parent_joint", {index[j.child]: k for k, j in enumerate(joints)})

    # --- structure ---------------------------------------------------------
    @property
    def num_parts(self) -> int:
        return len(self.parts)

    @property
    def num_joints(self) -> int:
        return len(self.joints)

    @property
    def part_names(self) -> list[str]:
        return [p.name for p in self.parts]

    @property
    def base_index(self) -> int:
        return self._order[0]

    def part_index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"part {name!r} not in model (parts: {self.part_names})") from None

    def joint_index(self, name: str) -> int:
        for k, j in enumerate(self.joints):
            if j.name == name:
                return k
        raise KeyError(f"joint {name!r} not in model (joints: {[j.name for j in self.joints]})")

    def parent_joint(self, part: int) -> int | None:
        """Index of the joint whose child is part ``part`` (``None`` for the base)."""
        return self._parent_joint.get(part)

    def joint_parts(self, k: int) -> tuple[int, int]:
        """``(parent_index, child_index)`` of joint ``k``."""
        j = self.joints[k]
        return self._index[j.parent], self._index[j.child]

    @property
    def topological_order(self) -> tuple[int, ...]:
        """Part indices, every parent before its children, base first."""
        return self._order

    # --- states ------------------------------------------------------------
    @property
    def rest_states(self) -> np.ndarray:
        return np.array([j.rest for j in self.joints], dtype=np.float64)

    @property
    def lower_limits(self) -> np.ndarray:
        return np.array([j.lower for j in self.joints], dtype=np.float64)

    @property
    def upper_limits(self) -> np.ndarray:
        return np.array([j.upper for j in self.joints], dtype=np.float64)

    def check_states(self, q, name: str = "q", tol: float = 1e-9) -> np.ndarray:
        """Validate a joint state vector ``(K,)`` against shape and limits."""
        q = as_array(q, name, (self.num_joints,))
        lo, hi = self.lower_limits, self.upper_limits
        bad = np.nonzero((q < lo - tol) | (q > hi + tol))[0]
        if bad.size:
            k = int(bad[0])
            raise ValueError(
                f"{name}: state {q[k]:.6g} of joint {self.joints[k].name!r} outside its limits "
                f"[{lo[k]:.6g}, {hi[k]:.6g}]"
            )
        return q

    def random_states(self, rng, *, unlimited_range: float = np.pi) -> np.ndarray:
        """Joint states drawn uniformly within the limits (unlimited joints: ``+-unlimited_range``)."""
        rng = check_generator(rng)
        lo = np.maximum(self.lower_limits, -unlimited_range)
        hi = np.minimum(self.upper_limits, unlimited_range)
        return rng.uniform(lo, hi)

    # --- kinematics --------------------------------------------------------
    def forward_kinematics(self, q) -> list[Sim3]:
        """Part poses ``T_base_part`` for joint states ``q`` ``(K,)``, in part order."""
        q = self.check_states(q)
        poses: list[Sim3 | None] = [None] * self.num_parts
        poses[self.base_index] = Sim3()
        for i in self._order[1:]:
            k = self._parent_joint[i]
            pi, _ = self.joint_parts(k)
            poses[i] = poses[pi] @ self.joints[k].T_parent_child(q[k])
        return poses

    def joint_line_in_base(self, k: int, q) -> tuple[np.ndarray, np.ndarray]:
        """Axis ``(3,)`` and pivot ``(3,)`` of joint ``k`` in the base frame at states ``q``."""
        T = self.forward_kinematics(q)[self.joint_parts(k)[0]]
        j = self.joints[k]
        return T.apply_direction(j.axis), T.apply(j.pivot)

    def surface_points(self, q, count: int, rng) -> tuple[np.ndarray, np.ndarray]:
        """Points sampled on all part meshes at states ``q``, in the base frame.

        Returns ``(points (N, 3), labels (N,) int)`` with ``count`` points per part.
        """
        rng = check_generator(rng)
        poses = self.forward_kinematics(q)
        pts, labels = [], []
        for i, part in enumerate(self.parts):
            local = sample_surface(part.mesh, count, rng)
            pts.append(poses[i].apply(local))
            labels.append(np.full(count, i))
        return np.concatenate(pts), np.concatenate(labels)


def sample_surface(mesh, count: int, rng) -> np.ndarray:
    """``count`` points uniformly on a trimesh surface (area-weighted), seeded; ``(count, 3)``."""
    return sample_surface_with_normals(mesh, count, rng)[0]


def sample_surface_with_normals(mesh, count: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """``count`` area-weighted surface samples ``(count, 3)`` and their unit face normals ``(count, 3)``.

    Seeded: the same ``rng`` state gives the same points as :func:`sample_surface`.
    """
    rng = check_generator(rng)
    if mesh is None or not hasattr(mesh, "triangles"):
        raise ValueError(f"mesh: expected a trimesh.Trimesh, got {type(mesh).__name__}")
    tris = np.asarray(mesh.triangles, dtype=np.float64)
    if len(tris) == 0:
        raise ValueError("mesh: has no triangles to sample")
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    areas = 0.5 * np.linalg.norm(cross, axis=1)
    if areas.sum() <= 0:
        raise ValueError("mesh: has zero surface area")
    face = rng.choice(len(tris), size=count, p=areas / areas.sum())
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = tris[face]
    points = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
    normals = cross[face] / np.maximum(np.linalg.norm(cross[face], axis=1, keepdims=True), 1e-300)
    return points, normals
