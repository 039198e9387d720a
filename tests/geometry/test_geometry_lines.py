"""Line-line distance and axis angles: skew, intersecting, parallel, anti-parallel lines."""

import numpy as np
import pytest

from ancsh.geometry import Sim3, axis_angle_error, direction_angle, line_distance, random_rotation


def _unit(rng):
    v = rng.standard_normal(3)
    return v / np.linalg.norm(v)


def test_skew_lines_along_axes():
    # x-axis and the line through (0, 0, 2) along y: the common perpendicular is the z-axis.
    assert line_distance([0, 0, 0], [1, 0, 0], [5, -3, 2], [0, 1, 0]) == pytest.approx(2.0, abs=1e-15)


def test_skew_lines_match_the_closest_points(rng):
    for _ in range(20):
        p1, p2 = rng.standard_normal((2, 3))
        u1, u2 = _unit(rng), _unit(rng)
        # Closest points from the normal equations of min |p1 + s u1 - p2 - t u2|^2.
        A = np.array([[u1 @ u1, -u1 @ u2], [u1 @ u2, -u2 @ u2]])
        s, t = np.linalg.solve(A, [(p2 - p1) @ u1, (p2 - p1) @ u2])
        expected = np.linalg.norm(p1 + s * u1 - p2 - t * u2)
        assert line_distance(p1, u1, p2, u2) == pytest.approx(expected, abs=1e-12)


def test_intersecting_lines_have_distance_zero(rng):
    x = rng.standard_normal(3)
    u1, u2 = _unit(rng), _unit(rng)
    assert line_distance(x - 2 * u1, u1, x + 3 * u2, u2) == pytest.approx(0.0, abs=1e-14)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_parallel_and_antiparallel_lines(rng, sign):
    u = _unit(rng)
    offset = np.cross(u, _unit(rng))
    offset *= 0.7 / np.linalg.norm(offset)
    p1 = rng.standard_normal(3)
    assert line_distance(p1, u, p1 + offset + 4.0 * u, sign * u) == pytest.approx(0.7, abs=1e-14)
    # Nearly parallel: continuous with the parallel value.
    tilt = u + 1e-10 * _unit(rng)
    assert line_distance(p1, u, p1 + offset, sign * tilt) == pytest.approx(0.7, abs=1e-8)
    # Coincident lines.
    assert line_distance(p1, u, p1 + 3.0 * u, sign * u) == pytest.approx(0.0, abs=1e-14)


def test_distance_is_symmetric_and_rigid_invariant_and_ignores_direction_length(rng):
    p1, p2 = rng.standard_normal((2, 3))
    u1, u2 = _unit(rng), _unit(rng)
    d = line_distance(p1, u1, p2, u2)
    assert line_distance(p2, u2, p1, u1) == pytest.approx(d, abs=1e-14)
    assert line_distance(p1 + 3 * u1, -2.5 * u1, p2, 0.1 * u2) == pytest.approx(d, abs=1e-13)
    T = Sim3(random_rotation(rng), rng.standard_normal(3))
    moved = line_distance(T @ p1, T.apply_direction(u1), T @ p2, T.apply_direction(u2))
    assert moved == pytest.approx(d, abs=1e-13)


@pytest.mark.parametrize("theta", [0.0, 1e-9, 0.3, np.pi / 2, 2.5, np.pi])
def test_axis_and_direction_angles(rng, theta):
    u = _unit(rng)
    v = np.cross(u, _unit(rng))
    v /= np.linalg.norm(v)
    w = np.cos(theta) * u + np.sin(theta) * v
    assert direction_angle(u, w) == pytest.approx(theta, abs=1e-12)
    assert axis_angle_error(u, w) == pytest.approx(min(theta, np.pi - theta), abs=1e-12)
    assert axis_angle_error(u, -w) == pytest.approx(axis_angle_error(u, w), abs=1e-15)
    assert 0.0 <= axis_angle_error(u, 3.0 * w) <= np.pi / 2


def test_zero_direction_and_bad_shapes_are_rejected():
    with pytest.raises(ValueError, match="u2: zero vector"):
        line_distance(np.zeros(3), [1, 0, 0], np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match=r"p1: expected shape \(3,\)"):
        line_distance(np.zeros(2), [1, 0, 0], np.zeros(3), [0, 1, 0])
    with pytest.raises(ValueError, match="u1: contains NaN"):
        axis_angle_error([np.nan, 0, 0], [0, 1, 0])
