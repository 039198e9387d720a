"""The paper's evaluation metrics (Sec. 5), as plain functions of one estimate and its truth.

- Part-based: rotation error (degrees, geodesic), translation error, 3D IoU of the amodal
  boxes (:func:`box_iou`, exact).
- Joint states: revolute angle error (degrees), prismatic translation error.
- Joint parameters: axis orientation error (degrees, ``u ~ -u``) and, for revolute joints,
  the minimum line-to-line distance (:func:`line_distance`).
- Average distance (AD) of model points under two poses (the real-data evaluation).
"""

from __future__ import annotations

import numpy as np

from ._checks import as_array, as_points
from .box_iou import box_iou
from .lines import axis_angle_error, line_distance
from .rotations import geodesic_angle
from .transforms import Sim3

__all__ = [
    "AD_THRESHOLD",
    "ad_error",
    "axis_angle_error_deg",
    "box_iou",
    "joint_state_error",
    "line_distance",
    "rotation_error_deg",
    "translation_error",
]


def rotation_error_deg(R_est, R_gt) -> float:
    """Geodesic angle between two ``(3, 3)`` rotations, in degrees, in ``[0, 180]``."""
    return float(np.degrees(geodesic_angle(R_est, R_gt)))


def translation_error(t_est, t_gt) -> float:
    """Euclidean distance between two ``(3,)`` translations (units of the inputs, e.g. metres)."""
    return float(np.linalg.norm(as_array(t_est, "t_est", (3,)) - as_array(t_gt, "t_gt", (3,))))


def joint_state_error(q_est: float, q_gt: float, joint_type: str) -> float:
    """Error of a joint state: degrees for a revolute joint, input units for a prismatic one.

    Parameters
    ----------
    q_est, q_gt : float
        Joint states (radians for revolute, metres for prismatic), both relative to the same rest.
    joint_type : str or JointType
        ``"revolute"`` (the angle difference, wrapped to ``[0, 180]`` degrees) or
        ``"prismatic"`` (the absolute difference).
    """
    q_est, q_gt = float(q_est), float(q_gt)
    if not (np.isfinite(q_est) and np.isfinite(q_gt)):
        raise ValueError(f"q_est, q_gt: expected finite joint states, got {q_est}, {q_gt}")
    d = q_est - q_gt
    if joint_type == "revolute":
        return float(np.degrees(abs(np.arctan2(np.sin(d), np.cos(d)))))
    if joint_type == "prismatic":
        return abs(d)
    raise ValueError(f"joint_type: expected 'revolute' or 'prismatic', got {joint_type!r}")


def axis_angle_error_deg(u_est, u_gt) -> float:
    """Angle between two joint axes in degrees, in ``[0, 90]`` (``u`` and ``-u`` are one axis)."""
    return float(np.degrees(axis_angle_error(u_est, u_gt)))


AD_THRESHOLD = 0.1
"""The AD criterion's threshold (Michel et al. 2015, the ANCSH paper's AD accuracy): a part pose is correct when its
:func:`ad_error` is below this fraction of the part's diameter."""


def ad_error(points_model, T_est: Sim3, T_gt: Sim3) -> float:
    """Average distance (AD) between model points under the estimated and the true pose.

    Parameters
    ----------
    points_model : (N, 3) float64
        Points in the model (part) frame, ``N >= 1``.
    T_est, T_gt : Sim3
        Estimated and true ``T_cam_model``.

    Returns
    -------
    float
        ``mean_i |T_est @ p_i - T_gt @ p_i|`` in camera units (metres).
    """
    p = as_points(points_model, "points_model", min_points=1)
    for name, T in (("T_est", T_est), ("T_gt", T_gt)):
        if not isinstance(T, Sim3):
            raise ValueError(f"{name}: expected a Sim3, got {type(T).__name__}")
    return float(np.mean(np.linalg.norm(T_est.apply(p) - T_gt.apply(p), axis=1)))
