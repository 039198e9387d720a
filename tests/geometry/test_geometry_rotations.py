"""Rotations: exp/log maps near 0 and pi, quaternions, geodesic angles, random rotations."""

import numpy as np
import pytest

from ancsh.geometry import (
    axis_angle_matrix,
    exp_so3,
    geodesic_angle,
    hat,
    log_so3,
    matrix_to_quat,
    project_to_rotation,
    quat_to_matrix,
    random_rotation,
    rotation_angle,
    rotation_between,
    vee,
)


def _unit(rng):
    v = rng.standard_normal(3)
    return v / np.linalg.norm(v)


def _is_rotation(R, tol=1e-12):
    return np.abs(R.T @ R - np.eye(3)).max() < tol and abs(np.linalg.det(R) - 1) < tol


def test_hat_is_cross_product_and_vee_inverts_it(rng):
    v, w = rng.standard_normal((2, 3))
    np.testing.assert_allclose(hat(v) @ w, np.cross(v, w), atol=1e-15)
    np.testing.assert_allclose(vee(hat(v)), v, atol=0)


def test_exp_matches_rodrigues_closed_form(rng):
    u, theta = _unit(rng), 1.234
    K = hat(u)
    R = np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K
    np.testing.assert_allclose(exp_so3(u * theta), R, atol=1e-15)


@pytest.mark.parametrize(
    "theta", [0.0, 1e-12, 1e-10, 1e-6, 1e-4, 0.3, 2.0, np.pi - 1.001e-3, np.pi - 1e-3, np.pi - 1e-6, np.pi - 1e-9]
)
def test_log_exp_round_trip(rng, theta):
    for _ in range(5):
        w = _unit(rng) * theta
        R = exp_so3(w)
        assert _is_rotation(R)
        w_back = log_so3(R)
        np.testing.assert_allclose(w_back, w, atol=1e-12)
        assert rotation_angle(R) == pytest.approx(theta, abs=1e-12)


def test_small_angle_exp_is_accurate_to_first_order():
    w = np.array([1e-10, -2e-10, 3e-10])
    R = exp_so3(w)
    np.testing.assert_allclose(R - np.eye(3), hat(w), atol=1e-20)
    np.testing.assert_allclose(log_so3(R), w, rtol=1e-6)


def test_log_at_exactly_pi_returns_the_axis_up_to_sign(rng):
    for R_axis in [np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), _unit(rng), _unit(rng)]:
        R = 2 * np.outer(R_axis, R_axis) - np.eye(3)  # exact rotation by pi
        w = log_so3(R)
        assert np.linalg.norm(w) == pytest.approx(np.pi, abs=1e-12)
        assert abs(abs(w @ R_axis) - np.pi) < 1e-10
        np.testing.assert_allclose(exp_so3(w), R, atol=1e-12)


def test_log_near_pi_keeps_the_sign_of_the_axis(rng):
    u = _unit(rng)
    for theta in (np.pi - 1e-9, np.pi - 1e-6, np.pi - 1e-3):
        w = log_so3(axis_angle_matrix(u, theta))
        assert w @ u > 0
        np.testing.assert_allclose(w, u * theta, atol=1e-6)


def test_log_rejects_a_non_rotation():
    with pytest.raises(ValueError, match="R: not a rotation"):
        log_so3(np.diag([1.0, 1.0, -1.0]))


def test_quaternion_round_trips(rng):
    for R in random_rotation(rng, 20):
        q = matrix_to_quat(R)
        assert q[0] >= 0 and np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
        np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-14)
    q = rng.standard_normal(4)
    q = q / np.linalg.norm(q) * np.sign(q[0])
    np.testing.assert_allclose(matrix_to_quat(quat_to_matrix(q)), q, atol=1e-14)


def test_quaternion_of_half_turns_uses_every_shepperd_branch():
    for axis in np.eye(3):
        R = axis_angle_matrix(axis, np.pi)
        q = matrix_to_quat(R)
        np.testing.assert_allclose(np.abs(q), np.r_[0.0, axis], atol=1e-15)
        np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-15)


def test_quaternion_matches_axis_angle(rng):
    u, theta = _unit(rng), 0.7
    q = np.r_[np.cos(theta / 2), np.sin(theta / 2) * u]
    np.testing.assert_allclose(quat_to_matrix(q), axis_angle_matrix(u, theta), atol=1e-15)
    with pytest.raises(ValueError, match="q: zero quaternion"):
        quat_to_matrix(np.zeros(4))


@pytest.mark.parametrize("theta", [0.0, 1e-9, 0.5, np.pi / 2, 3.0, np.pi - 1e-9, np.pi])
def test_geodesic_angle_of_known_rotations(rng, theta):
    R_a = random_rotation(rng)
    R_b = R_a @ axis_angle_matrix(_unit(rng), theta)
    assert geodesic_angle(R_a, R_b) == pytest.approx(theta, abs=1e-12)
    assert geodesic_angle(R_b, R_a) == pytest.approx(theta, abs=1e-12)


def test_random_rotation_is_orthonormal_and_reproducible():
    Rs = random_rotation(np.random.default_rng(7), 50)
    assert Rs.shape == (50, 3, 3)
    assert all(_is_rotation(R, 1e-14) for R in Rs)
    np.testing.assert_array_equal(random_rotation(7, 50), Rs)
    assert random_rotation(np.random.default_rng(7)).shape == (3, 3)
    assert not np.allclose(random_rotation(8, 50), Rs)
    with pytest.raises(TypeError, match="rng: expected numpy.random.Generator"):
        random_rotation(0.5)


def test_random_rotation_is_uniform_in_angle():
    # Haar measure: the angle has density (1 - cos t) / pi, so E[t] = pi/2 + 2/pi.
    angles = np.array([rotation_angle(R) for R in random_rotation(3, 4000)])
    sem = angles.std() / np.sqrt(len(angles))
    assert abs(angles.mean() - (np.pi / 2 + 2 / np.pi)) < 5 * sem


def test_project_to_rotation_recovers_a_perturbed_rotation(rng):
    R = random_rotation(rng)
    np.testing.assert_allclose(project_to_rotation(R + 1e-9 * rng.standard_normal((3, 3))), R, atol=1e-8)
    P = project_to_rotation(np.diag([1.0, 2.0, -3.0]))
    assert _is_rotation(P)


def test_rotation_between_directions(rng):
    a, b = _unit(rng), _unit(rng)
    np.testing.assert_allclose(rotation_between(a, b) @ a, b, atol=1e-14)
    np.testing.assert_allclose(rotation_between(a, a), np.eye(3), atol=1e-14)
    R = rotation_between(a, -a)
    assert _is_rotation(R)
    np.testing.assert_allclose(R @ a, -a, atol=1e-14)


def test_axis_angle_matrix_rejects_zero_axis():
    with pytest.raises(ValueError, match="axis: zero vector"):
        axis_angle_matrix(np.zeros(3), 1.0)


def test_hat_rejects_bad_shape():
    with pytest.raises(ValueError, match=r"v: expected shape \(3,\), got \(2,\)"):
        hat([1.0, 2.0])
