"""Normals of point clouds and the translations a closest-point alignment cannot see (ancsh.geometry.normals)."""

import numpy as np
import pytest

from ancsh.geometry.normals import estimate_normals, sliding_projector
from ancsh.geometry.rotations import exp_so3


def _rotation(rng):
    return exp_so3(rng.normal(size=3))


def test_normals_of_a_rotated_plane_are_its_normal():
    """Points on a seeded random plane: every estimated normal is the plane's (up to sign)."""
    rng = np.random.default_rng(0)
    R = _rotation(rng)
    local = np.c_[rng.uniform(-1, 1, size=(300, 2)), np.zeros(300)]
    normals = estimate_normals(local @ R.T + rng.normal(size=3))
    np.testing.assert_allclose(np.abs(normals @ R[:, 2]), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)


def _box_corner(rng, count=900):
    """Three faces of a unit cube meeting at the origin (a box corner in view)."""
    faces = []
    for axis in range(3):
        p = rng.uniform(0, 1, size=(count // 3, 3))
        p[:, axis] = 0.0
        faces.append(p)
    return np.concatenate(faces)


def _cylinder(rng, count=900, radius=0.05, length=1.0):
    a = rng.uniform(0, 2 * np.pi, count)
    return np.c_[radius * np.cos(a), radius * np.sin(a), rng.uniform(0, length, count)]


def test_sliding_projector_of_plane_cylinder_and_box_corner():
    """A plane slides within itself (rank-2 projector onto the plane), a thin cylinder along its axis
    (rank 1), a box corner with three faces in view nowhere (zero): in a seeded random orientation."""
    rng = np.random.default_rng(1)
    R = _rotation(rng)
    plane = np.c_[rng.uniform(-1, 1, size=(400, 2)), np.zeros(400)] @ R.T
    P = sliding_projector(estimate_normals(plane), 0.1)
    np.testing.assert_allclose(P, np.eye(3) - np.outer(R[:, 2], R[:, 2]), atol=1e-6)
    P = sliding_projector(estimate_normals(_cylinder(rng) @ R.T), 0.1)
    np.testing.assert_allclose(P, np.outer(R[:, 2], R[:, 2]), atol=0.05)
    P = sliding_projector(estimate_normals(_box_corner(rng) @ R.T), 0.1)
    np.testing.assert_allclose(P, 0.0, atol=1e-6)


def test_sliding_projector_soft_weights_and_limits():
    """Eigenvalues in [0, 1]; zero-weight normals do not count; no weight at all gives the identity;
    a threshold above every eigenvalue projects every direction in part."""
    rng = np.random.default_rng(2)
    n = rng.normal(size=(50, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    P = sliding_projector(n, 0.5)
    np.testing.assert_allclose(P, P.T, atol=1e-12)
    vals = np.linalg.eigvalsh(P)
    assert np.all(vals >= -1e-12) and np.all(vals <= 1 + 1e-12)
    z = np.tile([0.0, 0.0, 1.0], (10, 1))
    w = np.r_[np.ones(10), np.zeros(50)]
    np.testing.assert_allclose(sliding_projector(np.r_[z, n], 0.1, weights=w), np.diag([1.0, 1.0, 0.0]), atol=1e-12)
    np.testing.assert_allclose(sliding_projector(n, 0.1, weights=np.zeros(50)), np.eye(3))
    assert np.all(np.linalg.eigvalsh(sliding_projector(n, 2.0)) > 0)


def test_normals_bad_input_is_named():
    with pytest.raises(ValueError, match="points"):
        estimate_normals(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="neighbours"):
        estimate_normals(np.zeros((10, 3)), neighbours=2)
    with pytest.raises(ValueError, match="threshold"):
        sliding_projector(np.eye(3), 0.0)
    with pytest.raises(ValueError, match="weights"):
        sliding_projector(np.eye(3), 0.1, weights=[1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="normals"):
        sliding_projector(np.zeros((3, 2)), 0.1)
