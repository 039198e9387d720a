"""Seeded random articulated models and frames for tests and examples.

:func:`random_articulated_model` builds box-shaped parts (side lengths 0.05-0.5 m) joined
by revolute and prismatic joints with random axes, pivots, origins, limits and rest
states, as a chain or as a branching tree. :func:`random_camera_pose` and
:func:`sample_frame` turn a model into camera-frame surface points with part labels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry._checks import check_generator
from ..geometry.rotations import random_rotation
from ..geometry.transforms import Sim3
from .articulated import ArticulatedModel, Joint, JointType, Part

__all__ = ["SyntheticFrame", "random_articulated_model", "random_camera_pose", "sample_frame"]

_SIDE_RANGE = (0.05, 0.5)  # box side lengths (m)


def random_articulated_model(
    rng,
    num_parts: int = 3,
    joint_types=None,
    tree: bool = False,
    *,
    parents=None,
    random_canonical: bool = False,
    unlimited_revolute: bool = False,
) -> ArticulatedModel:
    """A random articulated object of box-shaped parts.

    Parameters
    ----------
    rng : numpy.random.Generator or int
        Seed; the same seed gives the same model.
    num_parts : int
        ``M >= 1``; the model has ``M - 1`` joints. Part 0 is the base.
    joint_types : None, str / JointType, or sequence of length ``M - 1``
        ``None`` draws each joint's type at random; a single type applies to all joints.
    tree : bool
        ``False``: a chain ``0 - 1 - ... - M-1``. ``True``: a random tree with a part that
        has at least two children and (for ``M >= 4``) a part hanging off a non-base part;
        needs ``M >= 3``.
    parents : sequence of int, optional
        Explicit parent of parts ``1..M-1`` (``parents[i - 1] < i``); excludes ``tree``.
    random_canonical : bool
        Draw a random ``R_canon_base`` instead of the identity.
    unlimited_revolute : bool
        Revolute joints without limits (``-inf``, ``inf``).

    Returns
    -------
    ArticulatedModel
        Parts ``part0..``, joints ``joint0..`` (joint ``k`` has child part ``k + 1``), every
        part mesh a ``trimesh`` box with sides in 0.05-0.5 m placed at a random pose in its
        part frame. Revolute limits span 0.2-1.5 rad each side of 0; prismatic limits
        ``[-0.1..0, 0.05..0.4]`` m; rest states uniform within the limits.
    """
    import trimesh

    rng = check_generator(rng)
    if isinstance(num_parts, bool) or not isinstance(num_parts, (int, np.integer)) or num_parts < 1:
        raise ValueError(f"num_parts: expected an integer >= 1, got {num_parts!r}")
    num_parts = int(num_parts)
    K = num_parts - 1
    types = _joint_types(joint_types, K, rng)
    par = _parents(parents, tree, num_parts, rng)

    parts, boxes = [], []
    for i in range(num_parts):
        extents = rng.uniform(*_SIDE_RANGE, size=3)
        T_part_box = np.eye(4)
        T_part_box[:3, :3] = random_rotation(rng) if rng.random() < 0.5 else np.eye(3)
        T_part_box[:3, 3] = rng.uniform(-0.05, 0.05, size=3)
        parts.append(Part(f"part{i}", trimesh.creation.box(extents=extents, transform=T_part_box)))
        boxes.append((T_part_box, extents))

    joints = []
    for k in range(K):
        child, parent = k + 1, par[k]
        T_box, ext = boxes[parent]
        # Attach the child somewhere on or inside the parent's box.
        attach = T_box[:3, :3] @ (rng.uniform(-0.5, 0.5, size=3) * ext) + T_box[:3, 3]
        origin = Sim3(random_rotation(rng), attach)
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        pivot = attach + rng.uniform(-0.1, 0.1, size=3)
        if types[k] == JointType.REVOLUTE:
            if unlimited_revolute:
                lower, upper = -np.inf, np.inf
                rest = float(rng.uniform(-np.pi, np.pi))
            else:
                lower, upper = -rng.uniform(0.2, 1.5), rng.uniform(0.2, 1.5)
                rest = float(rng.uniform(lower, upper))
        else:
            lower, upper = -rng.uniform(0.0, 0.1), rng.uniform(0.05, 0.4)
            rest = float(rng.uniform(lower, upper))
        joints.append(
            Joint(f"joint{k}", types[k], f"part{parent}", f"part{child}", axis, pivot, lower, upper, rest, origin)
        )
    R_canon = random_rotation(rng) if random_canonical else np.eye(3)
    return ArticulatedModel(tuple(parts), tuple(joints), name="random", category=None, R_canon_base=R_canon)


def random_camera_pose(rng, distance=(1.0, 2.0)) -> Sim3:
    """A rigid ``T_cam_base``: random orientation, base origin ``distance`` metres in front of the camera.

    The base origin lands at depth ``z > 0`` within a 20-degree cone around the optical axis.
    """
    rng = check_generator(rng)
    lo, hi = (float(d) for d in distance)
    if not 0 < lo <= hi or not np.isfinite(hi):
        raise ValueError(f"distance: expected 0 < min <= max, got {distance!r}")
    d = rng.uniform(lo, hi)
    tilt = np.deg2rad(20.0) * np.sqrt(rng.random())
    phi = rng.uniform(0, 2 * np.pi)
    direction = np.array([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), np.cos(tilt)])
    return Sim3(random_rotation(rng), d * direction)


@dataclass(frozen=True)
class SyntheticFrame:
    """Noise-free camera-frame surface points of a model at some joint states.

    Attributes
    ----------
    q : (K,) float64
        Absolute joint states.
    T_cam_base : Sim3
        Base -> camera.
    points_cam : (N, 3) float64
        Surface points in the camera frame (metres), all parts (no occlusion).
    part_labels : (N,) int64
        Part index of each point.
    """

    q: np.ndarray
    T_cam_base: Sim3
    points_cam: np.ndarray
    part_labels: np.ndarray


def sample_frame(model: ArticulatedModel, rng, *, points_per_part: int = 200, q=None, T_cam_base=None) -> SyntheticFrame:
    """Surface points of every part at states ``q`` seen from ``T_cam_base``.

    ``q`` defaults to :meth:`ArticulatedModel.random_states`, ``T_cam_base`` to
    :func:`random_camera_pose`.
    """
    rng = check_generator(rng)
    if isinstance(points_per_part, bool) or not isinstance(points_per_part, (int, np.integer)) or points_per_part < 0:
        raise ValueError(f"points_per_part: expected an integer >= 0, got {points_per_part!r}")
    q = model.random_states(rng) if q is None else model.check_states(q, "q")
    if T_cam_base is None:
        T_cam_base = random_camera_pose(rng)
    elif not isinstance(T_cam_base, Sim3):
        raise ValueError(f"T_cam_base: expected a Sim3, got {type(T_cam_base).__name__}")
    pts_base, labels = model.surface_points(q, int(points_per_part), rng)
    return SyntheticFrame(q, T_cam_base, T_cam_base.apply(pts_base), labels.astype(np.int64))


def _joint_types(joint_types, K: int, rng) -> list:
    if joint_types is None:
        return [JointType.REVOLUTE if rng.random() < 0.5 else JointType.PRISMATIC for _ in range(K)]
    if isinstance(joint_types, (str, JointType)):
        joint_types = [joint_types] * K
    joint_types = list(joint_types)
    if len(joint_types) != K:
        raise ValueError(f"joint_types: expected {K} types (num_parts - 1), got {len(joint_types)}")
    try:
        return [JointType(t) for t in joint_types]
    except ValueError:
        raise ValueError(f"joint_types: each must be 'revolute' or 'prismatic', got {joint_types!r}") from None


def _parents(parents, tree: bool, num_parts: int, rng) -> list:
    if parents is not None:
        if tree:
            raise ValueError("parents: give either parents or tree=True, not both")
        par = [int(p) for p in parents]
        if len(par) != num_parts - 1:
            raise ValueError(f"parents: expected {num_parts - 1} entries (parents of parts 1..M-1), got {len(par)}")
        for i, p in enumerate(par, start=1):
            if not 0 <= p < i:
                raise ValueError(f"parents: parent of part {i} must be in 0..{i - 1}, got {p}")
        return par
    if not tree:
        return list(range(num_parts - 1))
    if num_parts < 3:
        raise ValueError(f"num_parts: a branching tree needs at least 3 parts, got {num_parts}")
    while True:
        par = [int(rng.integers(0, i)) for i in range(1, num_parts)]
        branching = max(par.count(p) for p in set(par)) >= 2
        deep = any(p != 0 for p in par)
        if branching and (deep or num_parts < 4):
            return par
