"""The result of a CAD-based fit, shared by articulated ICP and the rigid baselines."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...geometry.rotations import log_so3
from ...geometry.transforms import Sim3
from ...model.articulated import ArticulatedModel
from ..types import FitStatus

__all__ = ["CadFitResult", "IcpIteration", "joint_states_from_part_poses"]


@dataclass(frozen=True)
class IcpIteration:
    """One iteration of an ICP loop (for plots and convergence checks).

    Attributes
    ----------
    T_cam_parts : tuple of Sim3
        ``(M,)`` part poses after the iteration.
    q : (K,) float64
        Absolute joint states after the iteration (NaN where not estimated).
    inlier_ratio : float
        Fraction of observed points within the gating distance.
    rmse : float
        Root mean square closest-point distance of the inliers (metres).
    max_distance : float
        Gating distance used (metres).
    """

    T_cam_parts: tuple
    q: np.ndarray
    inlier_ratio: float
    rmse: float
    max_distance: float


@dataclass(frozen=True)
class CadFitResult:
    """Pose of a known articulated model fitted to an observation.

    Attributes
    ----------
    method : str
        ``"articulated_icp"``, ``"per_part_icp"`` or ``"whole_object_icp"``.
    T_cam_parts : tuple of Sim3
        ``(M,)`` estimated part poses (part frame -> camera, rigid, metres).
    q : (K,) float64
        Estimated absolute joint states (radians / metres). Per-part ICP reads them off the
        relative part poses (:func:`joint_states_from_part_poses`).
    T_cam_base : Sim3
        Estimated base pose.
    status : FitStatus
        ``SUCCESS`` (converged), ``MAX_ITER`` (the iteration limit stopped the loop; for the rigid
        baselines: one more ICP iteration would still change the fitness or RMSE by ``1e-8`` or
        more, for some part), or a failure (``TOO_FEW_POINTS`` when no observed point lies near
        the model, ``INVALID_INPUT``, ``NUMERICAL_FAILURE``).
    message : str
    inlier_ratio : float
        Fraction of observed points within the final gating distance of the fitted model.
    rmse : float
        RMS distance of those inliers to the fitted model surface (metres).
    iterations : int
        ICP iterations run; ``-1`` for the rigid baselines (open3d does not report the count).
    time_s : float
        Wall time of the fit (seconds).
    history : tuple of IcpIteration
        Per-iteration estimates of the best start (empty for the baselines).
    starts : int
        Number of initial estimates tried.
    uncertainty : FitUncertainty or None
        Articulated ICP: covariances of the fitted part poses (in the part frames of
        :attr:`T_cam_parts`; scale fixed), object pose (:attr:`T_cam_base`) and joint states
        (:func:`~ancsh.solvers.icp.articulated.icp_uncertainty`); ``None`` for the baselines, a
        failed fit, or ``ArticulatedIcpConfig(uncertainty=False)``.
    part_points, part_inliers : tuple of int
        Articulated ICP (and the instance tracker's warm fits): per part, the observed points whose
        nearest model point lies on it within the first iteration's gate, and those of them within the
        final gate (:func:`~ancsh.solvers.icp.articulated.part_evidence`). A part with too few inliers
        among them fails the fit (``TOO_FEW_INLIERS``): its pose and joint state would rest on no
        evidence. Empty for the baselines and fits without an estimate.
    """

    method: str
    T_cam_parts: tuple
    q: np.ndarray
    T_cam_base: Sim3
    status: FitStatus
    message: str = ""
    inlier_ratio: float = 0.0
    rmse: float = float("inf")
    iterations: int = 0
    time_s: float = 0.0
    history: tuple = field(default_factory=tuple)
    starts: int = 1
    uncertainty: object = None
    part_points: tuple = ()
    part_inliers: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "status", FitStatus(self.status))
        if self.uncertainty is not None:
            from ..uncertainty import FitUncertainty

            if not isinstance(self.uncertainty, FitUncertainty):
                raise ValueError(f"uncertainty: expected a FitUncertainty or None, got {type(self.uncertainty).__name__}")

    @property
    def ok(self) -> bool:
        """``True`` when the fit converged (:attr:`FitStatus.SUCCESS`)."""
        return self.status == FitStatus.SUCCESS

    def joint_states(self, model: ArticulatedModel) -> np.ndarray:
        """Joint states relative to rest ``(K,)`` (the convention of reported joint states)."""
        return self.q - model.rest_states

    def to_dict(self) -> dict:
        """JSON-ready summary (rotations as ``(3, 3)`` lists, metres, radians)."""
        return {
            "method": self.method,
            "status": self.status.value,
            "message": self.message,
            "q": [float(v) for v in self.q],
            "T_cam_base": _sim3_dict(self.T_cam_base),
            "T_cam_parts": [_sim3_dict(T) for T in self.T_cam_parts],
            "inlier_ratio": float(self.inlier_ratio),
            "rmse": float(self.rmse),
            "iterations": int(self.iterations),
            "time_s": float(self.time_s),
            "starts": int(self.starts),
            "uncertainty": None if self.uncertainty is None else self.uncertainty.to_dict(),
            "part_points": [int(n) for n in self.part_points],
            "part_inliers": [int(n) for n in self.part_inliers],
        }


def _sim3_dict(T: Sim3) -> dict:
    return {"rotation": T.rotation.tolist(), "translation": T.translation.tolist(), "scale": float(T.scale)}


def joint_states_from_part_poses(model: ArticulatedModel, T_cam_parts) -> np.ndarray:
    """Absolute joint states ``(K,)`` read off independent part poses.

    For joint ``k`` the relative pose ``T_parent_child = T_cam_parent^-1 @ T_cam_child`` is
    compared with the joint's motion ``M(q) = T_parent_child @ origin^-1``: a revolute joint's
    state is the rotation angle of ``M`` about the joint axis (the rotation vector projected
    on the axis), a prismatic joint's the translation of ``M`` along the axis. Parts that
    break the joint (rotation about another axis, a wrong pivot) are simply projected;
    the result is not clamped to the limits.

    Parameters
    ----------
    model : ArticulatedModel
    T_cam_parts : sequence of Sim3
        ``(M,)`` part poses in the camera.
    """
    if len(T_cam_parts) != model.num_parts:
        raise ValueError(f"T_cam_parts: expected {model.num_parts} poses, got {len(T_cam_parts)}")
    q = np.empty(model.num_joints)
    for k, joint in enumerate(model.joints):
        p, c = model.joint_parts(k)
        T_pc = T_cam_parts[p].inverse() @ T_cam_parts[c]
        motion = T_pc @ joint.origin.inverse()
        if joint.is_revolute:
            q[k] = float(log_so3(motion.rotation) @ joint.axis)
        else:
            q[k] = float(motion.translation @ joint.axis)
    return q
