"""Instance-level CAD-based fitting: template correspondences, articulated ICP, rigid baselines.

When the exact object is known (its URDF or CAD model), its part poses and joint states
are found by articulated ICP: alternate closest-visible-point correspondences on the model
surface (:class:`TemplateProvider`, a :class:`~ancsh.solvers.types.CorrespondenceProvider`)
and the solver core's constrained solve in reduced coordinates (object pose + joint states,
limits as bounds), with multi-start (:func:`articulated_icp`; the covariance of its fit:
:func:`icp_uncertainty`). Rigid per-part and whole-object ICP (:func:`per_part_icp`,
:func:`whole_object_icp`) are the baselines; :mod:`.evaluate` measures all of them with the AD
metric (``ancsh evaluate-cad``). :func:`fit_depth` is ``ancsh fit-cad``: with the automatic start, the symmetric
starts of a near-symmetric model and the status at the sensor noise (:mod:`.verdict`).

Importing this package does not import open3d or CasADi; the first fit does.
"""

from .articulated import ArticulatedIcpConfig, articulated_icp, auto_init, icp_uncertainty, symmetric_hypotheses
from .depth import depth_points, fit_depth
from .result import CadFitResult, IcpIteration, joint_states_from_part_poses
from .rigid import RigidIcpConfig, per_part_icp, whole_object_icp
from .template import ArticulatedPose, ModelSurface, ModelTemplate, TemplateCorrespondences, TemplateProvider, robust_weights

__all__ = [
    "ArticulatedIcpConfig",
    "ArticulatedPose",
    "CadFitResult",
    "IcpIteration",
    "ModelSurface",
    "ModelTemplate",
    "RigidIcpConfig",
    "TemplateCorrespondences",
    "TemplateProvider",
    "articulated_icp",
    "auto_init",
    "depth_points",
    "fit_depth",
    "icp_uncertainty",
    "joint_states_from_part_poses",
    "per_part_icp",
    "robust_weights",
    "symmetric_hypotheses",
    "whole_object_icp",
]
