"""Frame-level evaluation of a fit against ANCSH ground truth (the paper's Table 1 metrics).

One definition used by the demo, the benchmarks and the evaluations. Lengths are divided by
the object scale (metres per NAOCS unit), as in the paper's tables; joint-state errors are in
degrees (revolute) or object units (prismatic).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .geometry.boxes import OrientedBox
from .geometry.metrics import axis_angle_error_deg, box_iou, joint_state_error, line_distance, rotation_error_deg

__all__ = ["Aggregate", "FrameEvaluation", "JointErrors", "PartErrors", "aggregate", "evaluate_fit"]


class _Record:
    """``to_dict()`` of a flat record dataclass (its fields, by name)."""

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class PartErrors(_Record):
    """Errors of one part's pose and box.

    Attributes
    ----------
    name : str
    rot_deg : float
        Geodesic rotation error (degrees).
    trans : float
        Translation error divided by the object scale (object units).
    scale_rel : float
        ``|s / s_gt - 1|``.
    iou : float
        3D IoU of the estimated and true amodal boxes (NaN without an estimated box).
    iou_pose : float
        3D IoU of a box of the true size at the estimated pose and the true box.
    """

    name: str
    rot_deg: float
    trans: float
    scale_rel: float
    iou: float
    iou_pose: float



@dataclass(frozen=True)
class JointErrors(_Record):
    """Errors of one joint.

    Attributes
    ----------
    name : str
    type : str
        ``"revolute"`` or ``"prismatic"``.
    state_err : float
        Joint-state error: degrees (revolute) or object units (prismatic); NaN when unknown.
    axis_deg : float
        Axis angle error (degrees, ``u ~ -u``); NaN when the estimate has no axis.
    line_dist : float
        Distance between the estimated and true joint lines (object units; revolute only, else NaN).
    """

    name: str
    type: str
    state_err: float
    axis_deg: float
    line_dist: float



@dataclass(frozen=True)
class FrameEvaluation:
    """The evaluation of one fit on one frame.

    Attributes
    ----------
    status : str
        The fit's :class:`~ancsh.solvers.types.FitStatus` value.
    ok : bool
        Whether the fit succeeded; ``parts`` and ``joints`` are empty otherwise.
    parts : tuple of PartErrors
    joints : tuple of JointErrors
    """

    status: str
    ok: bool
    parts: tuple = ()
    joints: tuple = ()

    def to_dict(self) -> dict:
        """``{"status", "ok", "parts": [...], "joints": [...]}`` (the JSON form of the reports)."""
        return {"status": self.status, "ok": self.ok, "parts": [p.to_dict() for p in self.parts],
                "joints": [j.to_dict() for j in self.joints]}


@dataclass(frozen=True)
class Aggregate:
    """Mean and median of the finite values of a metric over frames, and how many there were.

    ``mean`` and ``median`` are NaN when no value is finite (see :meth:`to_dict` for ``None``).
    """

    mean: float
    median: float
    count: int

    def to_dict(self) -> dict:
        """``{"mean", "median", "count"}``, with ``None`` for NaN (JSON has no NaN)."""
        clean = lambda v: None if math.isnan(v) else v  # noqa: E731
        return {"mean": clean(self.mean), "median": clean(self.median), "count": self.count}


def aggregate(values) -> Aggregate:
    """The one aggregation of per-frame metrics: NaN, infinite and ``None`` values are left out.

    Parameters
    ----------
    values : iterable of float or None
    """
    v = np.asarray([x for x in values if x is not None], dtype=float)
    v = v[np.isfinite(v)]
    if not v.size:
        return Aggregate(float("nan"), float("nan"), 0)
    return Aggregate(float(np.mean(v)), float(np.median(v)), int(v.size))


def evaluate_fit(result, gt, part_names=None, joint_names=None) -> FrameEvaluation:
    """Per-part and per-joint errors of a :class:`~ancsh.solvers.types.FitResult`.

    Parameters
    ----------
    result : FitResult
        The estimate (camera frame).
    gt : AncshGroundTruth
        Ground truth of the same frame.
    part_names, joint_names : sequence of str, optional
        Names for the records (default ``part<j>`` / ``joint<k>``).

    Returns
    -------
    FrameEvaluation
        ``parts``/``joints`` are empty for a failed fit. ``iou`` compares the estimated amodal
        box with the true one; ``iou_pose`` places a box of the true size at the fitted pose, so
        it isolates the pose error from the size estimate (for thin parts, a few degrees of
        rotation move the box faces by more than the part's thickness, and both are low).

    Raises
    ------
    ValueError
        When a successful result does not have the ground truth's structure (part count, joint
        count, joint array shapes, box count) or the names do not match the counts.
    """
    M, K = gt.num_parts, gt.num_joints
    part_names = [f"part{j}" for j in range(M)] if part_names is None else list(part_names)
    joint_names = [f"joint{k}" for k in range(K)] if joint_names is None else list(joint_names)
    if len(part_names) != M or len(joint_names) != K:
        raise ValueError(f"part_names, joint_names: expected {M} and {K} names, got {len(part_names)} and {len(joint_names)}")
    status = result.status.value
    if not result.ok:
        return FrameEvaluation(status, False)
    _check_structure(result, M, K)
    L = float(gt.T_cam_naocs.scale)
    parts = []
    for j, (T, T_gt) in enumerate(zip(result.T_cam_npcs, gt.T_cam_npcs)):
        gt_box = gt.boxes_cam[j]
        iou = box_iou(result.boxes_cam[j], gt_box) if len(result.boxes_cam) == M else float("nan")
        iou_pose = box_iou(OrientedBox(T.translation, T.rotation, gt_box.extents), gt_box)
        parts.append(PartErrors(
            name=part_names[j],
            rot_deg=rotation_error_deg(T.rotation, T_gt.rotation),
            trans=float(np.linalg.norm(T.translation - T_gt.translation)) / L,
            scale_rel=abs(T.scale / T_gt.scale - 1.0),
            iou=float(iou),
            iou_pose=float(iou_pose),
        ))
    joints = []
    for k in range(K):
        jt = gt.joint_types[k]
        revolute = jt.value == "revolute"
        q, q_gt = float(result.joint_states[k]), float(gt.joint_states[k])
        state = joint_state_error(q, q_gt, jt.value) if np.isfinite(q) else float("nan")
        if not revolute:
            state /= L
        axis = result.joint_axes_cam[k]
        ok_axis = bool(np.all(np.isfinite(axis)) and np.linalg.norm(axis) > 0)
        pivot_ok = ok_axis and bool(np.all(np.isfinite(result.joint_pivots_cam[k])))
        joints.append(JointErrors(
            name=joint_names[k],
            type=jt.value,
            state_err=state,
            axis_deg=axis_angle_error_deg(axis, gt.joint_axes_cam[k]) if ok_axis else float("nan"),
            line_dist=(
                line_distance(result.joint_pivots_cam[k], axis, gt.joint_pivots_cam[k], gt.joint_axes_cam[k]) / L
                if revolute and pivot_ok
                else float("nan")
            ),
        ))
    return FrameEvaluation(status, True, tuple(parts), tuple(joints))


def _check_structure(result, M: int, K: int) -> None:
    """Raise ``ValueError`` unless a successful ``result`` has ``M`` parts and ``K`` joints."""
    problems = []
    if len(result.T_cam_npcs) != M:
        problems.append(f"{len(result.T_cam_npcs)} part poses")
    if len(result.boxes_cam) not in (0, M):
        problems.append(f"{len(result.boxes_cam)} boxes")
    for name in ("joint_states", "joint_axes_cam", "joint_pivots_cam"):
        shape = np.shape(getattr(result, name))
        expected = (K,) if name == "joint_states" else (K, 3)
        if shape != expected:
            problems.append(f"{name} of shape {shape} (expected {expected})")
    if problems:
        raise ValueError(
            f"result: its structure does not match the ground truth's {M} parts and {K} joints: " + ", ".join(problems)
        )
