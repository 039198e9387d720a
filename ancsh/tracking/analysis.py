"""How much temporal averaging can buy: the frame-to-frame correlation of per-frame errors.

Tracking can beat independent per-frame fits only where the per-frame errors differ from frame
to frame: averaging ``N`` frames whose errors have a common correlation ``rho`` leaves the
variance fraction ``rho + (1 - rho) / N``; errors that are the same on every frame (a bias of the
network on this instance and view) are not averaged away at all. This module measures it on the
*signed* errors of a sequence of per-frame fits against the ground truth:

- :func:`signed_errors`: one frame's error vectors -- per part the rotation error as a rotation
  vector (degrees, camera frame: ``log(R R_gt^T)``) and the translation error vector (object
  diagonals), per joint the signed joint-state error (degrees / object diagonals);
- :func:`error_correlation`: over runs of consecutive frames, the normalised autocorrelation
  ``rho(l) = E[e_t . e_{t+l}] / E[|e_t|^2]`` at lags ``1..max_lag`` -- *raw* (about zero: a
  per-run bias counts as correlation, since averaging cannot remove it either) and *centred*
  (each run's mean error removed: the correlation of the fluctuations alone) -- and the **ideal
  fusion ratio** ``mean |mean(e_{t-N+1..t})| / mean |e_t|`` of a causal average of the last ``N``
  frames' errors (and of all frames so far): what a tracker that knew the motion between frames
  exactly and averaged the per-frame estimates over ``N`` frames would reach, relative to
  per-frame fitting. A tracker that fuses the network's outputs over time cannot do better than
  this bound; meeting ``0.8x`` needs it below 0.8.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry._checks import check_int

__all__ = ["CorrelationStudy", "error_correlation", "signed_errors"]

WINDOWS = (2, 3, 5, 10)
"""Causal averaging windows (frames) of :func:`error_correlation`'s ideal fusion ratios."""


def signed_errors(result, gt) -> dict:
    """Signed error vectors of one fit against its ground truth.

    Parameters
    ----------
    result : FitResult
        A successful category-level fit (camera frame).
    gt : AncshGroundTruth
        The frame's ground truth (same parts and joints).

    Returns
    -------
    dict
        ``"rot"``: ``(M, 3)`` rotation vectors of ``R R_gt^T`` in degrees; ``"trans"``: ``(M, 3)``
        translation errors in object diagonals (``/ gt.T_cam_naocs.scale``); ``"state"``: ``(K,)``
        joint-state errors (degrees for revolute joints, object diagonals for prismatic ones).
    """
    from ..geometry.rotations import log_so3

    if not result.ok:
        raise ValueError(f"result: expected a successful fit, got status {result.status.value}")
    if len(result.T_cam_npcs) != gt.num_parts or len(result.joint_states) != gt.num_joints:
        raise ValueError(f"result: {len(result.T_cam_npcs)} parts and {len(result.joint_states)} joints, the ground truth "
                         f"has {gt.num_parts} and {gt.num_joints}")
    L = float(gt.T_cam_naocs.scale)
    rot = np.array([np.degrees(log_so3(T.rotation @ G.rotation.T)) for T, G in zip(result.T_cam_npcs, gt.T_cam_npcs)])
    trans = np.array([(T.translation - G.translation) / L for T, G in zip(result.T_cam_npcs, gt.T_cam_npcs)])
    state = np.array([(np.degrees(d) if jt.value == "revolute" else d / L) for d, jt in
                      zip(np.asarray(result.joint_states, dtype=np.float64) - np.asarray(gt.joint_states), gt.joint_types)])
    return {"rot": rot.reshape(-1, 3), "trans": trans.reshape(-1, 3), "state": state.reshape(-1)}


@dataclass(frozen=True)
class CorrelationStudy:
    """Frame-to-frame correlation of one kind of error (see the module docstring).

    Attributes
    ----------
    raw, centred : (max_lag,) float64
        Normalised autocorrelation at lags ``1..max_lag`` (NaN where no pair of frames is that far apart).
    fusion : dict
        ``{N: ratio}``: the ideal causal fusion ratio over the last ``N`` frames (``N`` in :data:`WINDOWS`),
        and ``"all"``: over every frame of the run so far.
    frames : int
        Error vectors (frames x parts or joints) the figures are over.
    mean_error : float
        Mean norm of the error vectors (degrees / object diagonals).
    """

    raw: np.ndarray
    centred: np.ndarray
    fusion: dict
    frames: int
    mean_error: float

    def to_dict(self) -> dict:
        return {"raw": [float(x) for x in self.raw], "centred": [float(x) for x in self.centred],
                "fusion": {str(k): float(v) for k, v in self.fusion.items()}, "frames": int(self.frames),
                "mean_error": float(self.mean_error)}


def error_correlation(runs, max_lag: int = 10) -> CorrelationStudy:
    """Autocorrelation and ideal fusion ratios of error vectors over runs of consecutive frames.

    Parameters
    ----------
    runs : sequence of (T_i, d) arrays
        One array per run of consecutive frames (a sequence cut at frames without a fit, and
        one run per part or joint), ``d``-dimensional error vectors (3 for rotation vectors and
        translations, 1 for joint states). Runs shorter than 2 frames add to the fusion ratios only.
    max_lag : int
        Largest lag, ``>= 1``.

    Raises
    ------
    ValueError
        When there is no error vector, or the runs differ in ``d``.
    """
    max_lag = check_int(max_lag, "max_lag", minimum=1)
    runs = [np.asarray(r, dtype=np.float64).reshape(len(r), -1) for r in runs if len(r)]
    if not runs:
        raise ValueError("runs: expected at least one error vector")
    if len({r.shape[1] for r in runs}) != 1:
        raise ValueError(f"runs: error vectors of different sizes {sorted({r.shape[1] for r in runs})}")
    every = np.concatenate(runs)
    power = float(np.mean(np.sum(every ** 2, axis=1)))
    centred_runs = [r - r.mean(axis=0) for r in runs]
    centred_power = float(np.mean(np.concatenate([np.sum(c ** 2, axis=1) for c in centred_runs])))
    raw, centred = np.full(max_lag, np.nan), np.full(max_lag, np.nan)
    for lag in range(1, max_lag + 1):
        pairs = [(r[:-lag], r[lag:], c[:-lag], c[lag:]) for r, c in zip(runs, centred_runs) if len(r) > lag]
        if not pairs:
            continue
        raw[lag - 1] = np.mean(np.concatenate([np.sum(a * b, axis=1) for a, b, _, _ in pairs])) / power if power > 0 else np.nan
        if centred_power > 0:
            centred[lag - 1] = np.mean(np.concatenate([np.sum(a * b, axis=1) for _, _, a, b in pairs])) / centred_power
    base = float(np.mean(np.linalg.norm(every, axis=1)))
    fusion = {}
    for N in WINDOWS + ("all",):
        averaged = []
        for r in runs:
            csum = np.cumsum(np.vstack([np.zeros((1, r.shape[1])), r]), axis=0)
            t = np.arange(1, len(r) + 1)
            start = np.zeros_like(t) if N == "all" else np.maximum(t - N, 0)
            averaged.append(np.linalg.norm((csum[t] - csum[start]) / (t - start)[:, None], axis=1))
        fusion[N] = float(np.mean(np.concatenate(averaged)) / base) if base > 0 else float("nan")
    return CorrelationStudy(raw, centred, fusion, len(every), base)
