"""Depth sequences with ground truth: smooth camera motion and joint open/close cycles.

A sequence is ``length`` consecutive frames of one object instance, ``1 / fps`` seconds apart.
Everything about it -- instance, joint cycles, camera path -- is drawn from one random stream
seeded by ``(config.seed, sequence index)`` (:class:`SequencePlan`); each frame then renders the
planned state and camera, applies the sensor noise and samples points with its own stream
(:func:`~ancsh.data.generate.frame_seed` of its dataset index, as single frames), so a frame is a
pure function of the settings and its index and sequence datasets are generated, stored, verified
and resumed exactly like single-frame ones (:func:`~ancsh.data.generate.generate_dataset`).
Frame ``index`` is time ``index % length`` of sequence ``index // length``.

Motion
------
- **Joints**: each joint follows ``q(t) = a + (b - a) (1 - cos(2 pi t / P + phi)) / 2`` inside its
  limits: open/close cycles with a random sub-range ``[a, b]`` (at least ``min_joint_range`` of the
  limits), period ``P`` and phase.
- **Camera**: a viewpoint of the category's :class:`~ancsh.data.render.ViewpointRange` (azimuth,
  elevation, distance, roll) at the start and one drifted from it by at most ``max_azimuth_drift``,
  ``max_elevation_drift`` and ``max_distance_drift`` at the end (clipped to the range),
  interpolated with a smooth (cosine) ease, looking at the object's box centre at rest.
- **Occlusion and noise** are those of single frames: self-occlusion of the parts and the
  viewing angle, the :class:`~ancsh.data.noise.DepthNoise` model. Frames are not redrawn (time
  goes on), so the plan is: drawn again (up to ``max_attempts`` times) until at least
  ``min_accepted`` of ``checks`` evenly spread noise-free frames show every part as single frames
  require (:meth:`~ancsh.data.generate.FrameGenerator.accept`).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

import numpy as np

from ..geometry._checks import check_int, check_number
from ..geometry.transforms import Sim3

__all__ = ["SequenceMotion", "SequencePlan", "plan_sequence", "read_sequences"]


@dataclass(frozen=True)
class SequenceMotion:
    """How the sequences of a dataset move (part of :class:`~ancsh.data.generate.GenerationConfig`).

    Attributes
    ----------
    length : int
        Frames per sequence, ``>= 2``.
    fps : float
        Frames per second (the time step of the motion), ``> 0``.
    joint_period_s : (float, float)
        Range of the open/close period of every joint (seconds).
    min_joint_range : float
        Smallest share of a joint's limits a cycle covers, in ``(0, 1]``.
    max_azimuth_drift, max_elevation_drift : float
        Largest camera drift over a sequence (radians).
    max_distance_drift : float
        Largest relative change of the camera distance over a sequence.
    min_accepted : float
        Share of the checked frames that must show every part, in ``[0, 1]``.
    checks : int
        Frames checked per plan (evenly spread), ``>= 1``.
    max_attempts : int
        Plans drawn before giving up (:class:`~ancsh.data.generate.FrameRejected`).
    """

    length: int = 60
    fps: float = 30.0
    joint_period_s: tuple = (2.0, 5.0)
    min_joint_range: float = 0.5
    max_azimuth_drift: float = np.radians(30.0)
    max_elevation_drift: float = np.radians(10.0)
    max_distance_drift: float = 0.15
    min_accepted: float = 0.8
    checks: int = 5
    max_attempts: int = 50

    def __post_init__(self):
        object.__setattr__(self, "length", check_int(self.length, "length", minimum=2))
        object.__setattr__(self, "checks", check_int(self.checks, "checks", minimum=1))
        object.__setattr__(self, "max_attempts", check_int(self.max_attempts, "max_attempts", minimum=1))
        check_number(self.fps, "fps", minimum=0.0, lower_open=True)
        lo, hi = (float(x) for x in np.asarray(self.joint_period_s, dtype=np.float64).reshape(-1)[:2])
        if len(np.ravel(self.joint_period_s)) != 2 or not 0 < lo <= hi or not np.isfinite(hi):
            raise ValueError(f"joint_period_s: expected (low, high) with 0 < low <= high, got {self.joint_period_s!r}")
        object.__setattr__(self, "joint_period_s", (lo, hi))
        check_number(self.min_joint_range, "min_joint_range", minimum=0.0, maximum=1.0, lower_open=True)
        check_number(self.min_accepted, "min_accepted", minimum=0.0, maximum=1.0)
        for name in ("max_azimuth_drift", "max_elevation_drift", "max_distance_drift"):
            check_number(getattr(self, name), name, minimum=0.0)

    def to_dict(self) -> dict:
        return json.loads(json.dumps(asdict(self)))

    def split(self, index: int) -> tuple[int, int]:
        """``(sequence, time)`` of dataset frame ``index``."""
        return divmod(int(index), self.length)


@dataclass(frozen=True)
class SequencePlan:
    """The drawn motion of one sequence.

    Attributes
    ----------
    instance : int
        Instance index (see :meth:`~ancsh.data.generate.FrameGenerator.instance`).
    joint_low, joint_high : (K,) float64
        Absolute joint states between which each joint cycles (radians / metres).
    joint_period : (K,) float64
        Seconds.
    joint_phase : (K,) float64
        Radians.
    camera_start, camera_end : (4,) float64
        ``(azimuth, elevation, distance in metres, roll)`` at the first and the last frame.
    target : (3,) float64
        Look-at point in the base frame (metres).
    R_canon_base : (3, 3) float64
    fps : float
    length : int
    """

    instance: int
    joint_low: np.ndarray
    joint_high: np.ndarray
    joint_period: np.ndarray
    joint_phase: np.ndarray
    camera_start: np.ndarray
    camera_end: np.ndarray
    target: np.ndarray
    R_canon_base: np.ndarray
    fps: float
    length: int

    def joint_states(self, t: int) -> np.ndarray:
        """Absolute joint states ``(K,)`` at time index ``t``."""
        s = float(t) / self.fps
        w = 0.5 * (1.0 - np.cos(2.0 * np.pi * s / self.joint_period + self.joint_phase))
        return self.joint_low + (self.joint_high - self.joint_low) * w

    def camera(self, t: int) -> Sim3:
        """``T_cam_base`` at time index ``t``."""
        from .render import viewpoint_pose

        e = 0.5 * (1.0 - np.cos(np.pi * float(t) / max(self.length - 1, 1)))  # smooth ease 0 -> 1
        az, el, d, roll = self.camera_start + e * (self.camera_end - self.camera_start)
        return viewpoint_pose(self.target, self.R_canon_base, distance=d, azimuth=az, elevation=el, roll=roll)


def plan_sequence(model, instance: int, viewpoints, motion: SequenceMotion, rng) -> SequencePlan:
    """Draw the joint cycles and the camera path of one sequence of ``model``.

    Parameters
    ----------
    model : ArticulatedModel
    instance : int
        Stored in the plan.
    viewpoints : ViewpointRange
        The category's camera range.
    motion : SequenceMotion
    rng : numpy.random.Generator
    """
    from .render import object_extent

    lo = np.maximum(model.lower_limits, -np.pi)
    hi = np.minimum(model.upper_limits, np.pi)
    span = hi - lo
    width = span * rng.uniform(motion.min_joint_range, 1.0, size=len(lo))
    a = lo + rng.uniform(0.0, 1.0, size=len(lo)) * (span - width)
    period = rng.uniform(*motion.joint_period_s, size=len(lo))
    phase = rng.uniform(0.0, 2.0 * np.pi, size=len(lo))
    center, diag = object_extent(model, model.rest_states)
    vr = viewpoints
    start = np.array([rng.uniform(*vr.azimuth), rng.uniform(*vr.elevation), rng.uniform(*vr.distance) * diag,
                      rng.uniform(-vr.roll, vr.roll)])
    drift = np.array([motion.max_azimuth_drift, motion.max_elevation_drift, motion.max_distance_drift * start[2], 0.0])
    end = start + rng.uniform(-1.0, 1.0, size=4) * drift
    end[0] = np.clip(end[0], *vr.azimuth)
    end[1] = np.clip(end[1], *vr.elevation)
    end[2] = np.clip(end[2], vr.distance[0] * diag, vr.distance[1] * diag)
    target = center + rng.normal(0.0, vr.target_jitter * diag, size=3)
    return SequencePlan(int(instance), a, a + width, period, phase, start, end, target, model.R_canon_base.copy(),
                        float(motion.fps), int(motion.length))


def read_sequences(source) -> list[list]:
    """The frames of a sequence dataset grouped by sequence, each list in time order.

    Parameters
    ----------
    source : str, Path or list
        Shards or directories (see :func:`~ancsh.data.dataset.shard_paths`).

    Raises
    ------
    ValueError
        When the dataset holds single frames (no sequence index).
    """
    from .dataset import FrameDataset

    groups: dict = {}
    for fr in FrameDataset(source):
        if fr.sequence_index < 0:
            raise ValueError(f"source: {source} holds single frames, not sequences (no sequence index)")
        groups.setdefault(fr.sequence_index, []).append(fr)
    return [sorted(groups[s], key=lambda f: f.time_index) for s in sorted(groups)]
