"""Sim3: composition, inverse, application to points, matrices, validation."""

import numpy as np
import pytest

from ancsh.geometry import SE3, Sim3, random_rotation


def _random_sim3(rng, scale=True):
    return Sim3(random_rotation(rng), rng.standard_normal(3), rng.uniform(0.2, 5.0) if scale else 1.0)


def test_apply_is_scale_rotate_translate(rng):
    T = _random_sim3(rng)
    p = rng.standard_normal((10, 3))
    np.testing.assert_allclose(T.apply(p), T.scale * p @ T.rotation.T + T.translation, atol=1e-14)
    np.testing.assert_allclose(T @ p[0], T.apply(p)[0], atol=1e-14)
    np.testing.assert_allclose(T.apply_direction(p), p @ T.rotation.T, atol=1e-14)


def test_compose_matches_sequential_application_and_matrices(rng):
    T_a_b, T_b_c = _random_sim3(rng), _random_sim3(rng)
    p_c = rng.standard_normal((20, 3))
    T_a_c = T_a_b @ T_b_c
    np.testing.assert_allclose(T_a_c @ p_c, T_a_b @ (T_b_c @ p_c), atol=1e-12)
    np.testing.assert_allclose(T_a_c.matrix(), T_a_b.matrix() @ T_b_c.matrix(), atol=1e-12)


def test_composition_is_associative(rng):
    A, B, C = (_random_sim3(rng) for _ in range(3))
    assert ((A @ B) @ C).allclose(A @ (B @ C), atol=1e-12)


def test_inverse(rng):
    T = _random_sim3(rng)
    assert (T @ T.inverse()).allclose(Sim3.identity(), atol=1e-12)
    assert (T.inverse() @ T).allclose(Sim3.identity(), atol=1e-12)
    p = rng.standard_normal((5, 3))
    np.testing.assert_allclose(T.inverse() @ (T @ p), p, atol=1e-12)
    np.testing.assert_allclose(T.inverse().matrix(), np.linalg.inv(T.matrix()), atol=1e-12)


def test_matrix_round_trip(rng):
    T = _random_sim3(rng)
    assert Sim3.from_matrix(T.matrix()).allclose(T, atol=1e-12)
    assert Sim3.from_rotvec(T.rotvec(), T.translation, T.scale).allclose(T, atol=1e-12)


def test_se3_is_rigid(rng):
    T = SE3(random_rotation(rng), rng.standard_normal(3))
    assert T.is_rigid and T.scale == 1.0
    assert SE3().allclose(Sim3.identity())
    assert not _random_sim3(rng).is_rigid


def test_fields_are_copied_and_read_only(rng):
    R = random_rotation(rng)
    T = Sim3(R, np.zeros(3), 2.0)
    R[0, 0] = 5.0
    assert T.rotation[0, 0] != 5.0
    with pytest.raises(ValueError):
        T.translation[0] = 1.0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"rotation": np.diag([1.0, 1.0, -1.0])}, "rotation: not a rotation"),
        ({"rotation": 2 * np.eye(3)}, "rotation: not a rotation"),
        ({"translation": np.zeros(2)}, r"translation: expected shape \(3,\)"),
        ({"translation": [np.nan, 0, 0]}, "translation: contains NaN"),
        ({"scale": 0.0}, "scale: expected a positive"),
        ({"scale": -1.0}, "scale: expected a positive"),
        ({"scale": np.inf}, "scale: expected a positive"),
    ],
)
def test_invalid_construction(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Sim3(**kwargs)


def test_from_matrix_rejects_what_is_not_a_similarity():
    M = np.eye(4)
    M[2, 2] = -1
    with pytest.raises(ValueError, match="M: upper-left block has non-positive determinant"):
        Sim3.from_matrix(M)
    with pytest.raises(ValueError, match="M: upper-left block is not a uniformly scaled rotation"):
        Sim3.from_matrix(np.diag([1.0, 2.0, 3.0, 1.0]))
    P = np.eye(4)
    P[3, 2] = 1.0  # projective
    with pytest.raises(ValueError, match=r"M: last row must be \[0, 0, 0, 1\]"):
        Sim3.from_matrix(P)


def test_apply_rejects_bad_shape(rng):
    with pytest.raises(ValueError, match=r"points: expected shape \(N, 3\)"):
        _random_sim3(rng).apply(np.zeros((4, 2)))


def test_unchecked_matches_the_validating_constructor_and_is_read_only(rng):
    T = _random_sim3(rng)
    R, t = T.rotation.copy(), T.translation.copy()
    U = Sim3.unchecked(R, t, T.scale)
    assert U.allclose(T, atol=0.0)
    R[0, 0] += 1.0  # the inputs are copied
    assert U.allclose(T, atol=0.0)
    with pytest.raises(ValueError, match="read-only"):
        U.rotation[0, 0] = 2.0
    assert isinstance(U.scale, float)
