"""What a tracker reports per frame: :class:`TrackStatus` and :class:`TrackedFrame`, shared by the category tracker
(:mod:`ancsh.tracking.tracker`) and the instance tracker (:mod:`ancsh.tracking.instance`)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np


class TrackStatus(str, Enum):
    """What the tracker did on a frame."""

    INITIALISED = "initialised"  # the first successful (cold) fit of the sequence
    TRACKED = "tracked"  # a warm-started fit from the previous frame
    REINITIALISED = "reinitialised"  # a cold fit after a lost frame or a failed warm fit
    LOST = "lost"  # no acceptable fit on this frame


@dataclass(frozen=True)
class TrackedFrame:
    """The tracker's answer for one frame.

    Attributes
    ----------
    index : int
        Frame number in the sequence (0-based).
    status : TrackStatus
    message : str
        Why (the failed check of a lost frame, the reason of a re-initialisation).
    result : FitResult, CadFitResult or None
        The accepted fit (``None`` when lost).
    joint_states : (K,) float64
        Joint states relative to rest (radians / metres); NaN when lost.
    source : str
        Where this frame's correspondences came from: ``"network"`` (the provider),
        ``"carried"`` (the previous fit's point template), ``"template"`` (the carried category template,
        warm articulated ICP), ``"model"`` (a known URDF) or ``"none"``.
    iterations : int
        Solver iterations of the accepted fit (0 when lost).
    time_s : float
        Wall time of the whole step (seconds).
    """

    index: int
    status: TrackStatus
    message: str
    result: object
    joint_states: np.ndarray
    source: str
    iterations: int = 0
    time_s: float = 0.0

    @property
    def ok(self) -> bool:
        """``True`` unless the frame is lost."""
        return self.status != TrackStatus.LOST

    def to_dict(self) -> dict:
        """JSON-ready record of the frame (one line of ``ancsh track``'s output; NaN -> ``None``)."""
        r = self.result
        poses = []
        if r is not None:
            for T in getattr(r, "T_cam_npcs", None) or getattr(r, "T_cam_parts", ()):
                poses.append({"rotation": T.rotation.tolist(), "translation": T.translation.tolist(), "scale": float(T.scale)})
        sigma = joint_state_std(r)
        unc = getattr(r, "uncertainty", None)
        return {
            "frame": int(self.index), "status": self.status.value, "message": self.message, "source": self.source,
            "fit_status": None if r is None else r.status.value,
            "joint_states": [None if not np.isfinite(v) else float(v) for v in self.joint_states],
            "joint_states_std": None if sigma is None else [None if not np.isfinite(v) else float(v) for v in sigma],
            "part_poses_std": None if unc is None else [{k: float(v) if np.isfinite(v) else None for k, v in part.items()}
                                                        for part in unc.summary()["parts"]],
            "uncertainty": None if unc is None else {"status": unc.status, "inflation": unc.inflation.source},
            "part_poses": poses, "iterations": int(self.iterations), "time_ms": 1e3 * float(self.time_s),
        }


def joint_state_std(result) -> np.ndarray | None:
    """Standard deviations ``(K,)`` of a fit's joint states, where the fit reports its uncertainty.

    Reads ``result.uncertainty.joint_state_covariance`` (the fit covariances of
    :mod:`ancsh.solvers.uncertainty`, where present); ``None`` for a result without them.
    """
    unc = getattr(result, "uncertainty", None)
    cov = getattr(unc, "joint_state_covariance", None)
    if cov is None:
        return None
    return np.sqrt(np.clip(np.diag(np.asarray(cov, dtype=np.float64)), 0.0, None))
