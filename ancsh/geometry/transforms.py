"""Similarity transforms ``Sim3`` (rotation, translation, uniform scale).

A transform named ``T_a_b`` maps coordinates in frame ``b`` to frame ``a``:
``p_a = T_a_b @ p_b`` (``T_a_b.apply(p_b)``) and ``T_a_c = T_a_b @ T_b_c``.
A rigid transform (SE(3)) is a ``Sim3`` with ``scale == 1``; :func:`SE3` builds one.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._checks import as_array, as_rotation
from .rotations import exp_so3, log_so3


@dataclass(frozen=True)
class Sim3:
    """``x -> scale * rotation @ x + translation``.

    Attributes
    ----------
    rotation : (3, 3) float64
        Rotation matrix.
    translation : (3,) float64
        Translation, in the units of the target frame (metres in the camera frame).
    scale : float
        Uniform scale, positive.
    """

    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale: float = 1.0

    def __post_init__(self):
        R = as_rotation(self.rotation, "rotation", tol=1e-5)
        t = as_array(self.translation, "translation", (3,))
        s = float(self.scale)
        if not np.isfinite(s) or s <= 0:
            raise ValueError(f"scale: expected a positive finite number, got {self.scale}")
        R = R.copy()
        t = t.copy()
        R.flags.writeable = False
        t.flags.writeable = False
        object.__setattr__(self, "rotation", R)
        object.__setattr__(self, "translation", t)
        object.__setattr__(self, "scale", s)

    # --- construction -------------------------------------------------
    @classmethod
    def identity(cls) -> "Sim3":
        return cls()

    @classmethod
    def unchecked(cls, rotation: np.ndarray, translation: np.ndarray, scale: float) -> "Sim3":
        """Build without validation, for hot loops whose values are valid by construction.

        Parameters
        ----------
        rotation : (3, 3) float64
            A rotation matrix (orthonormal, ``det = +1``); not checked.
        translation : (3,) float64
        scale : float
            Positive; not checked.

        The arrays are copied and made read-only, as by the validating constructor.
        """
        self = object.__new__(cls)
        R = np.array(rotation, dtype=np.float64)
        t = np.array(translation, dtype=np.float64)
        R.flags.writeable = False
        t.flags.writeable = False
        object.__setattr__(self, "rotation", R)
        object.__setattr__(self, "translation", t)
        object.__setattr__(self, "scale", float(scale))
        return self

    @classmethod
    def from_matrix(cls, M) -> "Sim3":
        """From a ``(4, 4)`` homogeneous matrix ``[[s R, t], [0, 1]]``."""
        M = as_array(M, "M", (4, 4))
        if np.abs(M[3] - [0.0, 0.0, 0.0, 1.0]).max() > 1e-12:
            raise ValueError(f"M: last row must be [0, 0, 0, 1], got {M[3].tolist()}")
        A = M[:3, :3]
        s = float(np.cbrt(np.linalg.det(A)))
        if s <= 0:
            raise ValueError("M: upper-left block has non-positive determinant (reflection or singular)")
        err = np.abs(A.T @ A / (s * s) - np.eye(3)).max()
        if err > 1e-5:
            raise ValueError(f"M: upper-left block is not a uniformly scaled rotation (deviation {err:.3g})")
        return cls(A / s, M[:3, 3], s)

    @classmethod
    def from_rotvec(cls, rotvec, translation=(0.0, 0.0, 0.0), scale: float = 1.0) -> "Sim3":
        return cls(exp_so3(rotvec), np.asarray(translation, dtype=float), scale)

    # --- algebra --------------------------------------------------------
    def __matmul__(self, other):
        """Compose with another ``Sim3`` or apply to ``(N, 3)`` / ``(3,)`` points."""
        if isinstance(other, Sim3):  # products of valid transforms are valid
            return Sim3.unchecked(
                self.rotation @ other.rotation,
                self.scale * (self.rotation @ other.translation) + self.translation,
                self.scale * other.scale,
            )
        return self.apply(other)

    def inverse(self) -> "Sim3":
        Rt = self.rotation.T
        return Sim3.unchecked(Rt, -(Rt @ self.translation) / self.scale, 1.0 / self.scale)

    def apply(self, points) -> np.ndarray:
        """Map points; ``(N, 3) -> (N, 3)`` or ``(3,) -> (3,)``."""
        p = np.asarray(points, dtype=np.float64)
        if p.shape == (3,):
            return self.scale * (self.rotation @ p) + self.translation
        p = as_array(p, "points", (None, 3), finite=False)
        return self.scale * (p @ self.rotation.T) + self.translation

    def apply_direction(self, directions) -> np.ndarray:
        """Rotate directions (no scale, no translation); ``(N, 3)`` or ``(3,)``."""
        d = np.asarray(directions, dtype=np.float64)
        return d @ self.rotation.T

    def matrix(self) -> np.ndarray:
        """``(4, 4)`` homogeneous matrix."""
        M = np.eye(4)
        M[:3, :3] = self.scale * self.rotation
        M[:3, 3] = self.translation
        return M

    def rotvec(self) -> np.ndarray:
        return log_so3(self.rotation)

    @property
    def is_rigid(self) -> bool:
        return abs(self.scale - 1.0) < 1e-12

    def allclose(self, other: "Sim3", atol: float = 1e-9) -> bool:
        return (
            np.allclose(self.rotation, other.rotation, atol=atol)
            and np.allclose(self.translation, other.translation, atol=atol)
            and abs(self.scale - other.scale) <= atol
        )

    def __repr__(self) -> str:
        rv = np.round(self.rotvec(), 4).tolist()
        t = np.round(self.translation, 4).tolist()
        return f"Sim3(rotvec={rv}, translation={t}, scale={self.scale:.5g})"


def SE3(rotation=None, translation=None) -> Sim3:
    """A rigid transform: a :class:`Sim3` with unit scale."""
    return Sim3(np.eye(3) if rotation is None else rotation, np.zeros(3) if translation is None else translation, 1.0)
