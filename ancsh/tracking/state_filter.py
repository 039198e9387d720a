"""A constant-velocity filter of one tracked object's state: its root part's pose and its joint states.

Each frame a track's tracker gives a *measurement* (a fit: the root part's pose in the camera frame and the joint
states with their standard deviations). :class:`StateFilter` keeps the *filtered state* and its uncertainty:

- **Model.** Every component -- each joint state, each axis of the root's translation, each axis of its rotation
  (an error state about the filtered rotation, left-multiplied: ``R = exp(e) R_mean``) -- moves at a constant
  velocity between frames, disturbed by a white acceleration of standard deviation ``*_accel`` per frame squared
  (:class:`StateFilterConfig`); ``dt`` is one frame. The components are filtered independently (a 2-state Kalman
  filter each: value and velocity).
- **Measurement noise.** A joint state's variance is its fit's (``joint_states_std``, where the fit reports one),
  never below ``*_floor`` squared; the pose's is ``rotation_std`` / ``translation_std`` (the fits report no
  calibrated pose covariance on every frame, and a floor is what keeps a static object still).
- **Outliers.** A measurement whose normalised innovation (``|innovation| / sqrt(S)``) exceeds ``gate`` on any
  component is not applied: the state coasts on its prediction and the frame says ``outlier`` (the caller may
  verify it against the depth and :meth:`StateFilter.restart` from it). After
  ``max_outliers`` outliers in a row the measurements are believed (the object did move: a lid opened quickly) and
  the filter restarts from the last one.
- **Manoeuvres.** A component whose squared normalised innovation exceeds ``adapt`` has its covariance scaled up by
  the ratio before the update (fading memory), so that a joint that starts to move is followed within a few frames.
- **Physics.** Joint states are clamped to the category's range (``limits``, relative to rest), the velocity set to
  zero at a bound.

The filter knows nothing of pixels; :mod:`ancsh.tracking.multi` gives it one measurement a frame per track, and
:func:`filtered_fit` poses a track's fitted model at the filtered state.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..geometry._checks import check_int, check_number
from ..geometry.boxes import OrientedBox
from ..geometry.rotations import axis_angle_matrix, exp_so3, log_so3
from ..geometry.transforms import Sim3

__all__ = ["FilterUpdate", "StateFilter", "StateFilterConfig", "filtered_fit"]


@dataclass(frozen=True)
class StateFilterConfig:
    """Noise of :class:`StateFilter` (validated on construction).

    Attributes
    ----------
    revolute_accel : float
        Standard deviation of a revolute joint's acceleration, radians per frame squared, ``> 0``.
    prismatic_accel : float
        Of a prismatic joint's, metres per frame squared, ``> 0``.
    rotation_accel : float
        Of the root rotation's angular acceleration, radians per frame squared, ``> 0``.
    translation_accel : float
        Of the root translation's acceleration, metres per frame squared, ``> 0``.
    revolute_floor, prismatic_floor : float
        Smallest standard deviation of a measured joint state (radians, metres), ``> 0``.
    rotation_std, translation_std : float
        Standard deviation of a measured root rotation (radians, per axis) and translation (metres, per axis), ``> 0``.
    gate : float
        Normalised innovation beyond which a measurement is an outlier, ``> 0``.
    max_outliers : int
        Outliers in a row after which the filter restarts from the measurement, ``>= 1``.
    initial_velocity_std : float
        Standard deviation of the velocities at a (re)start, in each component's unit per frame, ``> 0``.
    adapt : float
        A measurement whose squared normalised innovation of a component exceeds this (but passes the gate) scales
        that component's covariance up by the ratio before it is applied (fading memory: a lid that starts to move is
        followed within a few frames instead of lagging), ``> 0``.
    coast_damping : float
        Each frame without an applied measurement multiplies the velocities by this, ``[0, 1]`` (a prediction
        over many frames does not run off with one noisy velocity).
    """

    revolute_accel: float = np.deg2rad(1.0)
    prismatic_accel: float = 0.0005
    rotation_accel: float = np.deg2rad(0.2)
    translation_accel: float = 0.001
    revolute_floor: float = np.deg2rad(2.0)
    prismatic_floor: float = 0.004
    rotation_std: float = np.deg2rad(3.0)
    translation_std: float = 0.01
    gate: float = 4.0
    max_outliers: int = 3
    initial_velocity_std: float = 0.02
    adapt: float = 9.0
    coast_damping: float = 0.7

    def __post_init__(self):
        for name in ("revolute_accel", "prismatic_accel", "rotation_accel", "translation_accel", "revolute_floor",
                     "prismatic_floor", "rotation_std", "translation_std", "gate", "initial_velocity_std", "adapt"):
            check_number(getattr(self, name), name, minimum=0.0, lower_open=True)
        object.__setattr__(self, "max_outliers", check_int(self.max_outliers, "max_outliers", minimum=1))
        check_number(self.coast_damping, "coast_damping", minimum=0.0, maximum=1.0)


@dataclass(frozen=True)
class FilterUpdate:
    """What one :meth:`StateFilter.update` did.

    Attributes
    ----------
    applied : bool
        The measurement moved the state (``False``: an outlier, or no measurement).
    outlier : bool
        It was gated out.
    restarted : bool
        The filter restarted from it (``max_outliers`` outliers in a row, or the first measurement).
    innovation : float
        The largest normalised innovation of its components (NaN without a measurement).
    """

    applied: bool
    outlier: bool
    restarted: bool
    innovation: float


def _predict(x: np.ndarray, P: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Constant-velocity prediction of ``n`` independent components: ``x`` (n, 2), ``P`` (n, 2, 2), ``q`` (n,)
    acceleration variances."""
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    G = np.array([[0.25, 0.5], [0.5, 1.0]])
    return x @ F.T, F @ P @ F.T + q[:, None, None] * G


def _gain(P: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Innovation variances ``S`` (n,) and gains ``K`` (n, 2) of a measurement of each component's value with
    variance ``r`` (n,)."""
    S = P[:, 0, 0] + r
    return S, P[:, :, 0] / S[:, None]


def _correct(P: np.ndarray, K: np.ndarray) -> np.ndarray:
    H = np.array([1.0, 0.0])
    I = np.eye(2)
    return (I[None] - K[:, :, None] * H[None, None, :]) @ P


class StateFilter:
    """The filtered state of one object (module docstring).

    Parameters
    ----------
    joint_types : sequence of str
        ``"revolute"`` / ``"prismatic"`` per joint.
    limits : (K, 2) float64, optional
        Each joint's range relative to rest (radians / metres); ``None``: unbounded.
    config : StateFilterConfig, optional
    """

    def __init__(self, joint_types, limits=None, config: StateFilterConfig | None = None):
        self.config = StateFilterConfig() if config is None else config
        if not isinstance(self.config, StateFilterConfig):
            raise ValueError(f"config: expected a StateFilterConfig, got {type(self.config).__name__}")
        self.joint_types = tuple(str(t) for t in joint_types)
        for t in self.joint_types:
            if t not in ("revolute", "prismatic"):
                raise ValueError(f"joint_types: expected 'revolute' or 'prismatic', got {t!r}")
        k = len(self.joint_types)
        lim = np.full((k, 2), [-np.inf, np.inf]) if limits is None else np.asarray(limits, dtype=np.float64).reshape(-1, 2)
        if lim.shape != (k, 2):
            raise ValueError(f"limits: expected ({k}, 2), got {lim.shape}")
        self.limits = lim
        revolute = np.array([t == "revolute" for t in self.joint_types], dtype=bool)
        c = self.config
        # component order: joints, translation x y z, rotation error x y z
        self._accel = np.concatenate([np.where(revolute, c.revolute_accel, c.prismatic_accel),
                                      np.full(3, c.translation_accel), np.full(3, c.rotation_accel)]) ** 2
        self._floor = np.where(revolute, c.revolute_floor, c.prismatic_floor)
        self._x = None  # (n, 2): joint states, translation, rotation error (zero after each correction)
        self._P = None
        self.R = None  # (3, 3) the filtered root rotation
        self.outliers = 0

    @property
    def started(self) -> bool:
        return self._x is not None

    @property
    def num_joints(self) -> int:
        return len(self.joint_types)

    def _variances(self, std) -> np.ndarray:
        k, c = self.num_joints, self.config
        s = np.full(k, np.nan) if std is None else np.asarray(std, dtype=np.float64).reshape(k)
        s = np.where(np.isfinite(s), np.maximum(s, self._floor), self._floor)
        return np.concatenate([s ** 2, np.full(3, c.translation_std ** 2), np.full(3, c.rotation_std ** 2)])

    def _clamp(self) -> None:
        k = self.num_joints
        lo, hi = self.limits[:, 0], self.limits[:, 1]
        q = self._x[:k, 0]
        out = (q < lo) | (q > hi)
        self._x[:k, 0] = np.clip(q, lo, hi)
        self._x[:k, 1] = np.where(out, 0.0, self._x[:k, 1])

    def restart(self, rotation, translation, states, std=None) -> None:
        """Start again from one measurement (the arguments of :meth:`update`): its value, zero velocity."""
        states = np.asarray(states, dtype=np.float64).reshape(self.num_joints)
        translation = np.asarray(translation, dtype=np.float64).reshape(3)
        k = self.num_joints
        c = self.config
        r = self._variances(std)
        self._x = np.zeros((k + 6, 2))
        self._x[:k, 0] = states
        self._x[k:k + 3, 0] = translation
        self._P = np.zeros((k + 6, 2, 2))
        self._P[:, 0, 0] = r
        self._P[:, 1, 1] = c.initial_velocity_std ** 2
        self.R = np.asarray(rotation, dtype=np.float64).copy()
        self.outliers = 0
        self._clamp()


    def predict(self) -> None:
        """Move the state one frame ahead (nothing before the first measurement)."""
        if self._x is None:
            return
        k = self.num_joints
        self._x, self._P = _predict(self._x, self._P, self._accel)
        # the rotation error's value moved by its velocity: fold it into the mean rotation
        self.R = exp_so3(self._x[k + 3:, 0]) @ self.R
        self._x[k + 3:, 0] = 0.0
        self._clamp()

    def coast(self) -> None:
        """No measurement was applied this frame: damp the velocities (``coast_damping``)."""
        if self._x is not None:
            self._x[:, 1] *= self.config.coast_damping

    def update(self, rotation, translation, states, std=None) -> FilterUpdate:
        """Apply one measurement (after :meth:`predict` of this frame).

        Parameters
        ----------
        rotation : (3, 3) float64
            The root part's measured rotation, camera frame.
        translation : (3,) float64
            Its measured translation, camera frame, metres.
        states : (K,) float64
            Measured joint states relative to rest (radians / metres).
        std : (K,) float64, optional
            Their standard deviations.
        """
        states = np.asarray(states, dtype=np.float64).reshape(self.num_joints)
        translation = np.asarray(translation, dtype=np.float64).reshape(3)
        if self._x is None:
            self.restart(rotation, translation, states, std)
            return FilterUpdate(True, False, True, float("nan"))
        k = self.num_joints
        z = np.concatenate([states, translation, log_so3(np.asarray(rotation) @ self.R.T)])
        r = self._variances(std)
        S, K = _gain(self._P, r)
        nu = z - self._x[:, 0]  # the rotation error's predicted value is zero (folded into R by predict)
        nis = nu ** 2 / S
        worst = float(np.sqrt(np.max(nis)))
        if worst > self.config.gate:
            self.outliers += 1
            if self.outliers >= self.config.max_outliers:
                self.restart(rotation, translation, states, std)
                return FilterUpdate(True, True, True, worst)
            return FilterUpdate(False, True, False, worst)
        self.outliers = 0
        grow = np.maximum(1.0, nis / self.config.adapt)  # a component that moves more than its model says: less lag
        if np.any(grow > 1.0):
            self._P = self._P * grow[:, None, None]
            S, K = _gain(self._P, r)
        self._x = self._x + K * nu[:, None]
        self._P = _correct(self._P, K)
        self.R = exp_so3(self._x[k + 3:, 0]) @ self.R
        self._x[k + 3:, 0] = 0.0
        self._clamp()
        return FilterUpdate(True, False, False, worst)

    @property
    def joint_states(self) -> np.ndarray:
        """(K,) filtered joint states relative to rest (radians / metres)."""
        return self._x[: self.num_joints, 0].copy()

    @property
    def joint_states_std(self) -> np.ndarray:
        """(K,) their standard deviations."""
        return np.sqrt(self._P[: self.num_joints, 0, 0])

    @property
    def translation(self) -> np.ndarray:
        """(3,) filtered root translation, camera frame, metres."""
        k = self.num_joints
        return self._x[k:k + 3, 0].copy()

    @property
    def translation_std(self) -> np.ndarray:
        k = self.num_joints
        return np.sqrt(self._P[k:k + 3, 0, 0])

    @property
    def rotation_std(self) -> np.ndarray:
        """(3,) standard deviation of the root rotation's error about each camera axis (radians)."""
        k = self.num_joints
        return np.sqrt(self._P[k + 3:, 0, 0])


def filtered_fit(result, correspondences, rotation, translation, states):
    """``result`` moved to another state of the same fitted model: its root part at ``rotation`` / ``translation``
    (camera frame, metres) and its joints at ``states`` (relative to rest, radians / metres), every child part
    turned (revolute) or slid (prismatic) about its fitted joint axis; axes, pivots and boxes move with their parts.

    Parameters
    ----------
    result : FitResult
        A successful fit.
    correspondences : Correspondences
        What it was fitted on (its joint tree and types).
    rotation : (3, 3) float64
    translation : (3,) float64
    states : (K,) float64
    """
    from ..model.articulated import JointType

    corr = correspondences
    root = corr.root_part
    Tr = result.T_cam_npcs[root]
    C = np.asarray(rotation) @ Tr.rotation.T
    corrections = {root: (C, np.asarray(translation) - C @ Tr.translation)}  # part -> rigid map (C, d) in the camera
    axes, pivots = np.array(result.joint_axes_cam, dtype=np.float64), np.array(result.joint_pivots_cam, dtype=np.float64)
    dq = np.asarray(states, dtype=np.float64) - np.asarray(result.joint_states, dtype=np.float64)
    for k in corr.topological_joints:
        p, c = int(corr.joint_parents[k]), int(corr.joint_children[k])
        Cp, dp = corrections[p]
        a, o = axes[k], pivots[k]
        if corr.joint_types[k] == JointType.REVOLUTE:
            J = axis_angle_matrix(a, float(dq[k]))
            Jd = o - J @ o
        else:
            J, Jd = np.eye(3), dq[k] * a
        corrections[c] = (Cp @ J, Cp @ Jd + dp)
        axes[k], pivots[k] = Cp @ a, Cp @ o + dp
    poses, boxes = [], []
    for j, T in enumerate(result.T_cam_npcs):
        Cj, dj = corrections[j]
        poses.append(Sim3(Cj @ T.rotation, Cj @ T.translation + dj, T.scale))
        if j < len(result.boxes_cam):
            b = result.boxes_cam[j]
            boxes.append(OrientedBox(Cj @ b.center + dj, Cj @ b.rotation, b.extents))
    return dataclasses.replace(result, T_cam_npcs=tuple(poses), joint_axes_cam=axes, joint_pivots_cam=pivots,
                               joint_states=np.asarray(states, dtype=np.float64).copy(), boxes_cam=tuple(boxes),
                               uncertainty=None)
