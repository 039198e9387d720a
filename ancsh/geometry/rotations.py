"""Rotations in 3D: exp/log maps, geodesic angles, quaternions, random rotations.

All functions work on float64 numpy arrays. Angles are in radians. Quaternions are
``(w, x, y, z)`` with ``w >= 0`` on output. The exp/log maps are accurate near
``theta = 0`` (Taylor series) and near ``theta = pi`` (axis from the symmetric part).
"""

from __future__ import annotations

import numpy as np

from ._checks import as_array, as_rotation, check_generator

_SMALL = 1e-8


def hat(v) -> np.ndarray:
    """Skew-symmetric matrix ``[v]_x`` with ``hat(v) @ w == cross(v, w)``; ``(3,) -> (3, 3)``."""
    x, y, z = as_array(v, "v", (3,))
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def vee(W) -> np.ndarray:
    """Inverse of :func:`hat` (uses the antisymmetric part of ``W``); ``(3, 3) -> (3,)``."""
    W = as_array(W, "W", (3, 3))
    return 0.5 * np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]])


def exp_so3(rotvec) -> np.ndarray:
    """Rotation matrix of a rotation vector (axis * angle, radians); ``(3,) -> (3, 3)``."""
    w = as_array(rotvec, "rotvec", (3,))
    theta2 = float(w @ w)
    theta = np.sqrt(theta2)
    K = hat(w)
    if theta < 1e-4:
        # Taylor series of sin(t)/t and (1 - cos t)/t^2, exact to O(t^6).
        a = 1.0 - theta2 / 6.0 + theta2 * theta2 / 120.0
        b = 0.5 - theta2 / 24.0 + theta2 * theta2 / 720.0
    else:
        a = np.sin(theta) / theta
        b = (1.0 - np.cos(theta)) / theta2
    return np.eye(3) + a * K + b * (K @ K)


def rotation_angle(R) -> float:
    """Rotation angle of ``R`` in ``[0, pi]`` radians, accurate at both ends."""
    R = as_array(R, "R", (3, 3))
    # atan2(|sin|, cos) is well conditioned where arccos((tr - 1)/2) is not.
    s = 0.5 * np.linalg.norm(vee(R) * 2.0)
    c = 0.5 * (np.trace(R) - 1.0)
    return float(np.arctan2(s, c))


def log_so3(R) -> np.ndarray:
    """Rotation vector of a rotation matrix (inverse of :func:`exp_so3`); ``(3, 3) -> (3,)``.

    For ``theta`` near ``pi`` the axis is taken from the symmetric part
    ``(R + R^T)/2 = cos(t) I + (1 - cos t) u u^T`` with its sign fixed by the
    antisymmetric part, so the result stays accurate up to and at ``pi``.
    """
    R = as_rotation(R, "R", tol=1e-5)
    theta = rotation_angle(R)
    w_sin = vee(R)  # = sin(theta) * axis
    if theta < 1e-4:
        return w_sin * (1.0 + theta * theta / 6.0)
    if theta < np.pi - 1e-3:
        return w_sin * (theta / np.sin(theta))
    S = 0.5 * (R + R.T)
    c = np.cos(theta)
    M = (S - c * np.eye(3)) / (1.0 - c)  # ~ u u^T
    k = int(np.argmax(np.diag(M)))
    u = M[:, k] / np.sqrt(max(M[k, k], _SMALL))
    u /= np.linalg.norm(u)
    if u @ w_sin < 0:
        u = -u
    return u * theta


def axis_angle_matrix(axis, angle: float) -> np.ndarray:
    """Rotation by ``angle`` radians about the unit ``axis`` (normalised here); ``-> (3, 3)``."""
    a = as_array(axis, "axis", (3,))
    n = np.linalg.norm(a)
    if n < 1e-12:
        raise ValueError("axis: zero vector cannot be a rotation axis")
    return exp_so3(a / n * float(angle))


def geodesic_angle(R_a, R_b) -> float:
    """Angle in radians of ``R_a^T R_b``: the geodesic distance on SO(3), in ``[0, pi]``."""
    R_a = as_array(R_a, "R_a", (3, 3))
    R_b = as_array(R_b, "R_b", (3, 3))
    return rotation_angle(R_a.T @ R_b)


def project_to_rotation(M) -> np.ndarray:
    """Nearest rotation matrix (Frobenius norm) to a ``(3, 3)`` matrix, via SVD."""
    M = as_array(M, "M", (3, 3))
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    return U @ D @ Vt


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a quaternion ``(w, x, y, z)`` (normalised here); ``(4,) -> (3, 3)``."""
    q = as_array(q, "q", (4,))
    n = np.linalg.norm(q)
    if n < 1e-12:
        raise ValueError("q: zero quaternion")
    w, x, y, z = q / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quat(R) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` with ``w >= 0`` of a rotation matrix; ``(3, 3) -> (4,)``."""
    R = as_rotation(R, "R", tol=1e-5)
    tr = np.trace(R)
    # Shepperd's method: pick the largest of w, x, y, z for stability.
    cands = np.array([tr, R[0, 0], R[1, 1], R[2, 2]])
    i = int(np.argmax(cands))
    if i == 0:
        s = 2.0 * np.sqrt(1.0 + tr)
        q = np.array([0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s])
    elif i == 1:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = np.array([(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s])
    elif i == 2:
        s = 2.0 * np.sqrt(1.0 - R[0, 0] + R[1, 1] - R[2, 2])
        q = np.array([(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s])
    else:
        s = 2.0 * np.sqrt(1.0 - R[0, 0] - R[1, 1] + R[2, 2])
        q = np.array([(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s])
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def random_rotation(rng, size: int | None = None) -> np.ndarray:
    """Rotations drawn uniformly (Haar measure) from SO(3).

    Parameters
    ----------
    rng : numpy.random.Generator or int
        Source of randomness.
    size : int, optional
        Number of rotations; ``None`` returns one ``(3, 3)`` matrix, else ``(size, 3, 3)``.
    """
    rng = check_generator(rng)
    n = 1 if size is None else int(size)
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    Rs = np.stack([quat_to_matrix(qi) for qi in q])
    return Rs[0] if size is None else Rs


def rotation_between(a, b) -> np.ndarray:
    """Smallest rotation taking direction ``a`` to direction ``b`` (both normalised here)."""
    a = as_array(a, "a", (3,))
    b = as_array(b, "b", (3,))
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(a @ b)
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        # 180 degrees about any axis perpendicular to a.
        perp = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        return axis_angle_matrix(perp, np.pi)
    return axis_angle_matrix(axis, np.arctan2(s, c))
