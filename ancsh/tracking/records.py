"""What a tracker reports per frame: :class:`TrackStatus` and :class:`TrackedFrame`, shared by the category tracker
(:mod:`ancsh.tracking.tracker`) and the instance tracker (:mod:`ancsh.tracking.instance`); :class:`TrackRecord` (one
track on one frame) and :class:`MultiFrame` (every track on one frame) of the multi-object tracker
(:mod:`ancsh.tracking.multi`)."""

from __future__ import annotations

from dataclasses import dataclass, field
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


@dataclass(frozen=True)
class TrackRecord:
    """One track on one frame.

    Attributes
    ----------
    id : int
        The track's id (stable over the sequence; never reused).
    status : str
        ``born`` (a verified detection started it), ``tracked`` (its measurement applied), ``outlier`` (measured far
        from the prediction: not applied), ``coasting`` (no acceptable measurement: the prediction),
        ``reinitialised`` (restarted from a detection).
    message : str
    source : str
        The measurement's correspondences (``network``, ``carried``, ``detection``, ``none``).
    model : FitResult
        The fitted model at the filtered state (camera frame).
    joint_states, joint_states_std : (K,) float64
        Filtered joint states relative to rest and their standard deviations (radians / metres).
    measured_states : (K,) float64
        This frame's measurement (NaN without one).
    translation_std : (3,) float64
        Of the root translation (metres).
    rotation_std : (3,) float64
        Of the root rotation about each camera axis (radians).
    pixels : int
        Pixels of its region this frame.
    p_object : float or None
        The last verification's ``p_object``.
    misses : int
        Frames in a row without an accepted measurement.
    """

    id: int
    status: str
    message: str
    source: str
    model: object  # FitResult
    joint_states: np.ndarray
    joint_states_std: np.ndarray
    measured_states: np.ndarray
    translation_std: np.ndarray
    rotation_std: np.ndarray
    pixels: int
    p_object: float | None
    misses: int
    mask: np.ndarray | None = field(default=None, repr=False)

    def to_dict(self) -> dict:
        from ..outputs import json_safe

        m = self.model
        return json_safe({
            "id": self.id, "status": self.status, "message": self.message, "source": self.source,
            "joint_states": self.joint_states.tolist(), "joint_states_std": self.joint_states_std.tolist(),
            "measured_states": self.measured_states.tolist(),
            "part_poses": [{"rotation": T.rotation.tolist(), "translation": T.translation.tolist(), "scale": float(T.scale)}
                           for T in m.T_cam_npcs],
            "translation_std": self.translation_std.tolist(), "rotation_std_deg": np.rad2deg(self.rotation_std).tolist(),
            "joint_axes_cam": np.asarray(m.joint_axes_cam).tolist(), "joint_pivots_cam": np.asarray(m.joint_pivots_cam).tolist(),
            "pixels": self.pixels, "p_object": self.p_object, "misses": self.misses,
        })


@dataclass(frozen=True)
class MultiFrame:
    """The tracker's answer for one frame: every live track's record, the tracks that ended, what ran.

    Attributes
    ----------
    index : int
    tracks : tuple of TrackRecord
    ended : tuple of int
        Ids of the tracks that ended on this frame.
    detected : bool
        Detection ran on this frame.
    detections : int
        Verified objects it found (0 when it did not run).
    stages_ms : dict
        Milliseconds of ``regions``, ``measure`` (every track's step), ``verify``, ``detect``.
    time_s : float
    """

    index: int
    tracks: tuple
    ended: tuple
    detected: bool
    detections: int
    stages_ms: dict
    time_s: float

    def to_dict(self) -> dict:
        """One line of ``ancsh track``'s output (``ancsh.track/2``)."""
        return {"frame": int(self.index), "tracks": [t.to_dict() for t in self.tracks], "ended": list(self.ended),
                "detected": bool(self.detected), "detections": int(self.detections),
                "stages_ms": {k: float(v) for k, v in self.stages_ms.items()}, "time_ms": 1e3 * float(self.time_s)}
