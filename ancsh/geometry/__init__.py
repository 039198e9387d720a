"""Pure numpy float64 geometry: rotations, Sim(3), Umeyama, RANSAC, boxes, metrics."""

from .boxes import OrientedBox
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

__all__ = [
    "OrientedBox",
    "SE3",
    "Sim3",
    "axis_angle_matrix",
    "exp_so3",
    "geodesic_angle",
    "hat",
    "log_so3",
    "matrix_to_quat",
    "project_to_rotation",
    "quat_to_matrix",
    "random_rotation",
    "rotation_angle",
    "rotation_between",
    "vee",
]
