"""ANCSH ground truth: NAOCS, NPCS, part poses, amodal boxes, joints and joint association.

Paper Sec. 4.1 (representation), 4.2 (joint association and targets), 4.4 (camera-space joints).

Frames
------
- ``base``: the model's base-part frame (metres).
- ``naocs``: the object with every joint at its rest state, rotated by
  ``model.R_canon_base``, zero-centred on the tight axis-aligned box (NAOCS axes) of all
  mesh vertices and scaled so that box has diagonal 1.
- ``npcs`` (one per part ``j``): NAOCS orientation, zero-centred on the part's own tight
  box (NAOCS axes), unit diagonal. ``p_naocs = s_j * p_npcs + t_j``.

The NAOCS -> camera map of part ``j`` at joint states ``q`` is
``T_cam_base @ T_base_part_j(q) @ T_base_part_j(rest)^-1 @ T_naocs_base^-1``; the part
pose is ``T_cam_npcs_j = (that) @ T_naocs_npcs_j``.

Joint parameters
----------------
Axes keep the sign of the model's joint axis. Every joint's canonical pivot is the point
of its line ``(pivot, axis)`` closest to the NAOCS origin (for a revolute joint the
point on the rotation axis; for a prismatic joint a reference point on the line through
the model's joint pivot). Camera-space axis and pivot are the NAOCS ones mapped by the
*parent* part's NAOCS -> camera transform (for a revolute joint the child's transform
gives the same line and the same pivot).
"""

from __future__ import annotations

from dataclasses import dataclass

import weakref

import numpy as np

from ..geometry._checks import as_array, as_points
from ..geometry.boxes import OrientedBox
from ..geometry.transforms import Sim3
from .articulated import ArticulatedModel, JointType

__all__ = [
    "AncshGroundTruth",
    "CanonicalSpace",
    "ancsh_ground_truth",
    "canonical_space",
    "joint_association",
]

_MIN_DIAGONAL = 1e-12


class _NpcsToNaocs:
    """Shared accessors of the per-part NPCS -> NAOCS maps (``npcs_scale``, ``npcs_translation``)."""

    npcs_scale: np.ndarray
    npcs_translation: np.ndarray

    @property
    def num_parts(self) -> int:
        return len(self.npcs_scale)

    def T_naocs_npcs(self, j: int) -> Sim3:
        """NPCS of part ``j`` -> NAOCS (identity rotation, scale ``s_j``, translation ``t_j``)."""
        j = _check_index(j, self.num_parts, "j")
        return Sim3(np.eye(3), self.npcs_translation[j], float(self.npcs_scale[j]))


@dataclass(frozen=True)
class CanonicalSpace(_NpcsToNaocs):
    """Per-model NAOCS and NPCS definition, independent of joint state and camera.

    Attributes
    ----------
    T_naocs_base : Sim3
        Base frame with joints at rest -> NAOCS (rotation ``model.R_canon_base``).
    npcs_scale : (M,) float64
        ``s_j`` with ``p_naocs = s_j * p_npcs + t_j`` (the part box diagonal in NAOCS units).
    npcs_translation : (M, 3) float64
        ``t_j``: the part box centre in NAOCS.
    npcs_extents : (M, 3) float64
        Part tight-box side lengths in NPCS (each row has norm 1).
    joint_axes_naocs : (K, 3) float64
        Unit joint axes in NAOCS.
    joint_pivots_naocs : (K, 3) float64
        Point of each joint line closest to the NAOCS origin.
    joint_types : tuple of JointType
        ``(K,)``.
    naocs_extents : (3,) float64
        Side lengths of the object's tight box in NAOCS (norm 1).
    """

    T_naocs_base: Sim3
    npcs_scale: np.ndarray
    npcs_translation: np.ndarray
    npcs_extents: np.ndarray
    joint_axes_naocs: np.ndarray
    joint_pivots_naocs: np.ndarray
    joint_types: tuple
    naocs_extents: np.ndarray

    def npcs_box(self, j: int) -> OrientedBox:
        """Tight box of part ``j`` in its NPCS: centred at 0, unit diagonal."""
        j = _check_index(j, self.num_parts, "j")
        return OrientedBox(np.zeros(3), np.eye(3), self.npcs_extents[j])


def canonical_space(model: ArticulatedModel) -> CanonicalSpace:
    """NAOCS and per-part NPCS of ``model`` (paper Sec. 4.1), computed once per model.

    Models are immutable, so the result is cached per model object (weakly: the cache
    entry goes with the model).

    Parameters
    ----------
    model : ArticulatedModel
        Every part needs a mesh (its vertices define the tight boxes).

    Raises
    ------
    ValueError
        If ``model`` is not an ArticulatedModel, a part has no mesh or no vertices, or the
        object or a part collapses to a single point.
    """
    if not isinstance(model, ArticulatedModel):
        raise ValueError(f"model: expected an ArticulatedModel, got {type(model).__name__}")
    cached = _CANONICAL_CACHE.get(model)
    if cached is None:
        cached = _CANONICAL_CACHE[model] = _compute_canonical_space(model)
    return cached


_CANONICAL_CACHE: "weakref.WeakKeyDictionary[ArticulatedModel, CanonicalSpace]" = weakref.WeakKeyDictionary()


def _compute_canonical_space(model: ArticulatedModel) -> CanonicalSpace:
    rest = model.rest_states
    poses_rest = model.forward_kinematics(rest)
    R = model.R_canon_base
    # Part vertices in the canonically rotated base frame at rest.
    verts = []
    for j, part in enumerate(model.parts):
        v = as_points(part.vertices, f"model part {part.name!r} vertices", min_points=1)
        verts.append(poses_rest[j].apply(v) @ R.T)
    allv = np.concatenate(verts)
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    if diag < _MIN_DIAGONAL:
        raise ValueError("model: all mesh vertices coincide; the NAOCS box has zero diagonal")
    s = 1.0 / diag
    T_naocs_base = Sim3(R, -s * 0.5 * (lo + hi), s)

    M = model.num_parts
    scales, trans, extents = np.empty(M), np.empty((M, 3)), np.empty((M, 3))
    for j, v in enumerate(verts):
        vn = s * v + T_naocs_base.translation
        plo, phi = vn.min(axis=0), vn.max(axis=0)
        d = float(np.linalg.norm(phi - plo))
        if d < _MIN_DIAGONAL:
            raise ValueError(f"model: part {model.parts[j].name!r} collapses to a point (zero box diagonal)")
        scales[j], trans[j], extents[j] = d, 0.5 * (plo + phi), (phi - plo) / d

    K = model.num_joints
    axes, pivots = np.empty((K, 3)), np.empty((K, 3))
    for k in range(K):
        a_base, p_base = model.joint_line_in_base(k, rest)
        a = T_naocs_base.apply_direction(a_base)
        a = a / np.linalg.norm(a)
        p = T_naocs_base.apply(p_base)
        axes[k], pivots[k] = a, p - (p @ a) * a

    return CanonicalSpace(
        T_naocs_base=T_naocs_base,
        npcs_scale=_frozen(scales),
        npcs_translation=_frozen(trans),
        npcs_extents=_frozen(extents),
        joint_axes_naocs=_frozen(axes),
        joint_pivots_naocs=_frozen(pivots),
        joint_types=tuple(j.type for j in model.joints),
        naocs_extents=_frozen(s * (hi - lo)),
    )


@dataclass(frozen=True)
class AncshGroundTruth(_NpcsToNaocs):
    """ANCSH ground truth of one frame (``N`` points, ``M`` parts, ``K`` joints).

    Attributes
    ----------
    part_labels : (N,) int64
        Part index of each point, ``0..M-1``.
    npcs : (N, 3) float64
        Each point in the NPCS of its part.
    naocs : (N, 3) float64
        Each point in NAOCS.
    npcs_scale : (M,) float64
        NPCS -> NAOCS scale ``s_j``.
    npcs_translation : (M, 3) float64
        NPCS -> NAOCS translation ``t_j``.
    T_cam_npcs : tuple of Sim3
        ``(M,)`` part poses: camera from NPCS (rotation, translation in metres, scale).
    boxes_cam : tuple of OrientedBox
        ``(M,)`` amodal part boxes in the camera frame (metres).
    joint_types : tuple of JointType
        ``(K,)``.
    joint_parents, joint_children : (K,) int64
        Part indices connected by each joint.
    joint_axes_naocs : (K, 3) float64
        Unit axes in NAOCS.
    joint_pivots_naocs : (K, 3) float64
        Canonical pivots in NAOCS (see module docstring).
    joint_axes_cam : (K, 3) float64
        Unit axes in the camera frame.
    joint_pivots_cam : (K, 3) float64
        Pivots in the camera frame (metres).
    joint_states : (K,) float64
        ``q - rest`` (radians for revolute, metres for prismatic).
    joint_association : (N,) int64
        ``0`` = no joint, ``k + 1`` = joint ``k``.
    joint_targets : (N, 7) float64
        NAOCS targets: axis (3), unit direction from the point to its projection on the
        axis (3), distance to the axis (1). Zeros where not associated; prismatic joints
        fill the axis only. A point exactly on a revolute axis gets a zero direction.
    T_cam_naocs : Sim3
        NAOCS -> camera of the base part (the object pose of the NAOCS baseline).
    """

    part_labels: np.ndarray
    npcs: np.ndarray
    naocs: np.ndarray
    npcs_scale: np.ndarray
    npcs_translation: np.ndarray
    T_cam_npcs: tuple
    boxes_cam: tuple
    joint_types: tuple
    joint_parents: np.ndarray
    joint_children: np.ndarray
    joint_axes_naocs: np.ndarray
    joint_pivots_naocs: np.ndarray
    joint_axes_cam: np.ndarray
    joint_pivots_cam: np.ndarray
    joint_states: np.ndarray
    joint_association: np.ndarray
    joint_targets: np.ndarray
    T_cam_naocs: Sim3

    @property
    def num_joints(self) -> int:
        return len(self.joint_types)

    def T_cam_naocs_part(self, j: int) -> Sim3:
        """NAOCS -> camera for part ``j`` at this frame's joint states."""
        j = _check_index(j, self.num_parts, "j")
        return self.T_cam_npcs[j] @ self.T_naocs_npcs(j).inverse()


def ancsh_ground_truth(
    model: ArticulatedModel, q, T_cam_base: Sim3, points_cam, part_labels, *, sigma: float = 0.2
) -> AncshGroundTruth:
    """ANCSH ground truth for surface points of ``model`` at joint states ``q``.

    Parameters
    ----------
    model : ArticulatedModel
        With meshes on every part.
    q : (K,) array_like
        Absolute joint states (radians / metres), within the limits.
    T_cam_base : Sim3
        Base frame -> camera (pose of the base part in the camera).
    points_cam : (N, 3) array_like
        Observed surface points in the camera frame (metres) at states ``q``.
    part_labels : (N,) array_like of int
        Part index of each point, ``0..M-1``.
    sigma : float
        Revolute association radius in NAOCS units (paper: 0.2).

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, non-integer or out-of-range labels, ``q``
        outside the limits, ``sigma`` not positive, ``T_cam_base`` not a Sim3.
    """
    cs = canonical_space(model)
    q = model.check_states(q, "q")
    if not isinstance(T_cam_base, Sim3):
        raise ValueError(f"T_cam_base: expected a Sim3, got {type(T_cam_base).__name__}")
    points_cam = as_points(points_cam, "points_cam")
    labels = _check_labels(part_labels, points_cam.shape[0], model.num_parts)
    sigma = _check_sigma(sigma)

    M, K, N = model.num_parts, model.num_joints, points_cam.shape[0]
    poses_q = model.forward_kinematics(q)
    poses_rest = model.forward_kinematics(model.rest_states)
    T_base_naocs = cs.T_naocs_base.inverse()
    T_cam_naocs_parts = [T_cam_base @ poses_q[j] @ poses_rest[j].inverse() @ T_base_naocs for j in range(M)]

    naocs = np.empty((N, 3))
    npcs = np.empty((N, 3))
    T_cam_npcs, boxes = [], []
    for j in range(M):
        T_naocs_npcs = cs.T_naocs_npcs(j)
        T = T_cam_naocs_parts[j] @ T_naocs_npcs
        T_cam_npcs.append(T)
        boxes.append(cs.npcs_box(j).transformed(T))
        sel = labels == j
        if np.any(sel):
            naocs[sel] = T_cam_naocs_parts[j].inverse().apply(points_cam[sel])
            npcs[sel] = T_naocs_npcs.inverse().apply(naocs[sel])

    parents = np.empty(K, dtype=np.int64)
    children = np.empty(K, dtype=np.int64)
    axes_cam, pivots_cam = np.empty((K, 3)), np.empty((K, 3))
    for k in range(K):
        parents[k], children[k] = model.joint_parts(k)
        T = T_cam_naocs_parts[parents[k]]
        a = T.apply_direction(cs.joint_axes_naocs[k])
        axes_cam[k] = a / np.linalg.norm(a)
        pivots_cam[k] = T.apply(cs.joint_pivots_naocs[k])

    association, targets = joint_association(
        naocs, labels, cs.joint_types, parents, children, cs.joint_axes_naocs, cs.joint_pivots_naocs, sigma=sigma
    )
    return AncshGroundTruth(
        part_labels=_frozen(labels),
        npcs=_frozen(npcs),
        naocs=_frozen(naocs),
        npcs_scale=cs.npcs_scale,
        npcs_translation=cs.npcs_translation,
        T_cam_npcs=tuple(T_cam_npcs),
        boxes_cam=tuple(boxes),
        joint_types=cs.joint_types,
        joint_parents=_frozen(parents),
        joint_children=_frozen(children),
        joint_axes_naocs=cs.joint_axes_naocs,
        joint_pivots_naocs=cs.joint_pivots_naocs,
        joint_axes_cam=_frozen(axes_cam),
        joint_pivots_cam=_frozen(pivots_cam),
        joint_states=_frozen(q - model.rest_states),
        joint_association=_frozen(association),
        joint_targets=_frozen(targets),
        T_cam_naocs=T_cam_naocs_parts[model.base_index],
    )


def joint_association(naocs, part_labels, joint_types, joint_parents, joint_children, axes_naocs, pivots_naocs,
                      *, sigma: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """Per-point joint association and 7-D joint targets in NAOCS (paper Sec. 4.2).

    A point qualifies for revolute joint ``k`` when it lies on part ``parent_k`` or
    ``child_k`` within ``sigma`` of the axis, and for prismatic joint ``k`` when it lies on
    the moving part ``child_k``. A point qualifying for several revolute joints goes to the
    nearest axis; a revolute candidate takes precedence over the (at most one) prismatic
    joint of the point's part, which keeps all other points of its moving part.

    Parameters
    ----------
    naocs : (N, 3) float64
        Points in NAOCS.
    part_labels : (N,) int
        Part of each point.
    joint_types : sequence of JointType, (K,)
    joint_parents, joint_children : (K,) int
    axes_naocs, pivots_naocs : (K, 3) float64
        Unit axes and points on the axes in NAOCS.
    sigma : float
        Revolute association radius (NAOCS units).

    Returns
    -------
    association : (N,) int64
        ``0`` none, ``k + 1`` joint ``k``.
    targets : (N, 7) float64
        Axis (3), unit direction point -> axis (3), distance (1); see
        :class:`AncshGroundTruth`.
    """
    naocs = as_points(naocs, "naocs")
    N, K = naocs.shape[0], len(joint_types)
    labels = np.asarray(part_labels)
    if labels.shape != (N,):
        raise ValueError(f"part_labels: expected shape ({N},) matching naocs, got {labels.shape}")
    joint_parents = np.asarray(joint_parents)
    joint_children = np.asarray(joint_children)
    if joint_parents.shape != (K,) or joint_children.shape != (K,):
        raise ValueError(f"joint_parents, joint_children: expected shape ({K},) matching joint_types")
    sigma = _check_sigma(sigma)
    axes = as_array(axes_naocs, "axes_naocs", (K, 3))
    pivots = as_array(pivots_naocs, "pivots_naocs", (K, 3))
    if K and np.max(np.abs(np.linalg.norm(axes, axis=1) - 1.0)) > 1e-6:
        raise ValueError("axes_naocs: expected unit vectors")
    best_dist = np.full(N, np.inf)
    association = np.zeros(N, dtype=np.int64)
    targets = np.zeros((N, 7))
    # Prismatic first, so revolute candidates overwrite them.
    order = sorted(range(K), key=lambda k: JointType(joint_types[k]) == JointType.REVOLUTE)
    for k in order:
        a = axes[k]
        if JointType(joint_types[k]) == JointType.PRISMATIC:
            sel = labels == joint_children[k]
            association[sel] = k + 1
            targets[sel, :3] = a
            continue
        on_parts = (labels == joint_parents[k]) | (labels == joint_children[k])
        rel = pivots[k] - naocs  # point -> pivot
        to_axis = rel - np.outer(rel @ a, a)  # point -> its projection on the axis
        dist = np.linalg.norm(to_axis, axis=1)
        sel = on_parts & (dist <= sigma) & (dist < best_dist)
        best_dist[sel] = dist[sel]
        association[sel] = k + 1
        targets[sel, :3] = a
        with np.errstate(invalid="ignore", divide="ignore"):
            direction = np.where(dist[:, None] > 1e-12, to_axis / dist[:, None], 0.0)
        targets[sel, 3:6] = direction[sel]
        targets[sel, 6] = dist[sel]
    return association, targets


# --- helpers -------------------------------------------------------------------------
def _check_labels(part_labels, n: int, num_parts: int) -> np.ndarray:
    labels = np.asarray(part_labels)
    if labels.shape != (n,):
        raise ValueError(f"part_labels: expected shape ({n},) matching points_cam, got {labels.shape}")
    if n and not np.issubdtype(labels.dtype, np.integer):
        if not np.issubdtype(labels.dtype, np.floating) or not np.all(np.isfinite(labels)) or np.any(labels != np.round(labels)):
            raise ValueError(f"part_labels: expected integer part indices, got dtype {labels.dtype}")
    labels = labels.astype(np.int64)
    bad = (labels < 0) | (labels >= num_parts)
    if np.any(bad):
        raise ValueError(
            f"part_labels: label {int(labels[bad][0])} out of range 0..{num_parts - 1} (model has {num_parts} parts)"
        )
    return labels


def _check_sigma(sigma) -> float:
    sigma = float(sigma)
    if not np.isfinite(sigma) or sigma <= 0:
        raise ValueError(f"sigma: expected a positive finite number, got {sigma}")
    return sigma


def _check_index(j, count: int, name: str) -> int:
    if isinstance(j, bool) or not isinstance(j, (int, np.integer)) or not 0 <= int(j) < count:
        raise ValueError(f"{name}: expected a part index in 0..{count - 1}, got {j!r}")
    return int(j)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.flags.writeable = False
    return a
