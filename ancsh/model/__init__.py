"""Articulated models, forward kinematics and ANCSH ground truth."""

from .articulated import ArticulatedModel, Joint, JointType, Part, sample_surface

__all__ = ["ArticulatedModel", "Joint", "JointType", "Part", "sample_surface"]
