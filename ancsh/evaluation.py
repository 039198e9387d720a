"""Frame-level evaluation of a fit against ANCSH ground truth (the paper's Table 1 metrics).

One definition used by the demo, the benchmarks and the evaluations. Lengths are divided by
the object scale (metres per NAOCS unit), as in the paper's tables; joint-state errors are in
degrees (revolute) or object units (prismatic).
"""

from __future__ import annotations

import numpy as np

from .geometry.boxes import OrientedBox
from .geometry.metrics import axis_angle_error_deg, box_iou, joint_state_error, line_distance, rotation_error_deg


def evaluate_fit(result, gt, part_names=None, joint_names=None) -> dict:
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
    dict
        ``status``, ``ok``, ``parts`` (``name, rot_deg, trans, scale_rel, iou, iou_pose``) and ``joints``
        (``name, type, state_err, axis_deg, line_dist``); ``parts``/``joints`` are empty for a
        failed fit. ``iou`` compares the estimated amodal box with the true one; ``iou_pose``
        places a box of the true size at the fitted pose, so it isolates the pose error from the
        size estimate (for thin parts, a few degrees of rotation move the box faces by more than
        the part's thickness, and both are low).
    """
    M, K = gt.num_parts, gt.num_joints
    part_names = [f"part{j}" for j in range(M)] if part_names is None else list(part_names)
    joint_names = [f"joint{k}" for k in range(K)] if joint_names is None else list(joint_names)
    L = float(gt.T_cam_naocs.scale)
    rec = {"status": result.status.value, "ok": bool(result.ok), "parts": [], "joints": []}
    if not result.ok or len(result.T_cam_npcs) != M:
        return rec
    for j, (T, T_gt) in enumerate(zip(result.T_cam_npcs, gt.T_cam_npcs)):
        gt_box = gt.boxes_cam[j]
        iou = box_iou(result.boxes_cam[j], gt_box) if len(result.boxes_cam) == M else float("nan")
        iou_pose = box_iou(OrientedBox(T.translation, T.rotation, gt_box.extents), gt_box)
        rec["parts"].append({
            "name": part_names[j],
            "rot_deg": rotation_error_deg(T.rotation, T_gt.rotation),
            "trans": float(np.linalg.norm(T.translation - T_gt.translation)) / L,
            "scale_rel": abs(T.scale / T_gt.scale - 1.0),
            "iou": float(iou),
            "iou_pose": float(iou_pose),
        })
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
        rec["joints"].append({
            "name": joint_names[k],
            "type": jt.value,
            "state_err": state,
            "axis_deg": axis_angle_error_deg(axis, gt.joint_axes_cam[k]) if ok_axis else float("nan"),
            "line_dist": (
                line_distance(result.joint_pivots_cam[k], axis, gt.joint_pivots_cam[k], gt.joint_axes_cam[k]) / L
                if revolute and pivot_ok
                else float("nan")
            ),
        })
    return rec
