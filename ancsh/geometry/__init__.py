"""Float64 geometry (numpy, scipy.spatial where needed): rotations, Sim(3), Umeyama, RANSAC, boxes, normals, metrics."""

from .box_iou import box_iou, intersection_volume
from .boxes import OrientedBox
from .lines import axis_angle_error, direction_angle, line_distance
from .metrics import ad_error, axis_angle_error_deg, joint_state_error, rotation_error_deg, translation_error
from .normals import estimate_normals, sliding_projector
from .ransac import RansacResult, RansacStatus, fit_sim3_ransac, mean_group_inlier_ratio, ransac
from .rotations import (
    axis_angle_matrix,
    exp_so3,
    geodesic_angle,
    hat,
    log_so3,
    matrix_to_quat,
    project_to_rotation,
    quat_to_matrix,
    random_rotation,
    rotation_angle,
    rotation_between,
    vee,
)
from .transforms import SE3, Sim3
from .umeyama import DegeneratePointsError, umeyama

__all__ = [
    "DegeneratePointsError",
    "OrientedBox",
    "RansacResult",
    "RansacStatus",
    "SE3",
    "Sim3",
    "ad_error",
    "axis_angle_error",
    "axis_angle_error_deg",
    "axis_angle_matrix",
    "box_iou",
    "direction_angle",
    "estimate_normals",
    "exp_so3",
    "fit_sim3_ransac",
    "geodesic_angle",
    "hat",
    "intersection_volume",
    "joint_state_error",
    "line_distance",
    "log_so3",
    "matrix_to_quat",
    "mean_group_inlier_ratio",
    "project_to_rotation",
    "quat_to_matrix",
    "random_rotation",
    "ransac",
    "rotation_angle",
    "rotation_between",
    "rotation_error_deg",
    "sliding_projector",
    "translation_error",
    "umeyama",
    "vee",
]
