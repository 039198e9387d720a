"""Instance-level CAD-based fitting: template correspondences, articulated ICP, rigid baselines.

When the exact object is known (its URDF or CAD model), its part poses and joint states
are found by articulated ICP: alternate closest-point correspondences on the model
surface (:class:`TemplateProvider`) and the constrained solve in reduced coordinates
(object pose + joint states, limits as bounds). Rigid per-part and whole-object ICP are
the baselines.
"""

from .result import CadFitResult, IcpIteration, joint_states_from_part_poses
from .rigid import RigidIcpConfig, per_part_icp, whole_object_icp
from .template import ArticulatedPose, ModelSurface, robust_weights

__all__ = [
    "ArticulatedPose",
    "CadFitResult",
    "IcpIteration",
    "ModelSurface",
    "RigidIcpConfig",
    "joint_states_from_part_poses",
    "per_part_icp",
    "robust_weights",
    "whole_object_icp",
]
