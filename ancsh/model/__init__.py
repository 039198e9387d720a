"""Articulated models, forward kinematics and ANCSH ground truth."""

from .articulated import ArticulatedModel, Joint, JointType, Part, sample_surface, sample_surface_with_normals
from .canonical import AncshGroundTruth, CanonicalSpace, ancsh_ground_truth, canonical_space, joint_association
from .synthetic import SyntheticFrame, random_articulated_model, random_camera_pose, sample_frame

__all__ = [
    "AncshGroundTruth",
    "ArticulatedModel",
    "CanonicalSpace",
    "Joint",
    "JointType",
    "Part",
    "SyntheticFrame",
    "ancsh_ground_truth",
    "canonical_space",
    "joint_association",
    "random_articulated_model",
    "random_camera_pose",
    "sample_frame",
    "sample_surface",
    "sample_surface_with_normals",
]
