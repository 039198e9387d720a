"""OrientedBox: corners, containment, transforms, validation."""

import numpy as np
import pytest

from ancsh.geometry import OrientedBox, Sim3, random_rotation


def _random_box(rng):
    return OrientedBox(rng.standard_normal(3), random_rotation(rng), rng.uniform(0.1, 2.0, 3))


def test_corners_of_an_axis_aligned_box():
    box = OrientedBox.axis_aligned([0.0, 1.0, 2.0], [1.0, 3.0, 5.0])
    corners = box.corners()
    assert corners.shape == (8, 3)
    expected = {(x, y, z) for x in (0.0, 1.0) for y in (1.0, 3.0) for z in (2.0, 5.0)}
    assert {tuple(c) for c in corners} == expected
    assert box.volume == pytest.approx(6.0)
    assert box.diagonal == pytest.approx(np.sqrt(1 + 4 + 9))


def test_corners_of_a_rotated_box_keep_its_geometry(rng):
    box = _random_box(rng)
    c = box.corners()
    np.testing.assert_allclose(c.mean(axis=0), box.center, atol=1e-14)
    local = (c - box.center) @ box.rotation
    np.testing.assert_allclose(np.abs(local), np.broadcast_to(box.extents / 2, (8, 3)), atol=1e-14)
    d = np.linalg.norm(c[:, None] - c[None], axis=-1)
    assert d.max() == pytest.approx(box.diagonal, abs=1e-14)
    assert np.all(box.contains(c, tol=1e-12))


def test_contains_matches_local_coordinates(rng):
    box = _random_box(rng)
    local = rng.uniform(-1, 1, (2000, 3)) * box.extents  # half inside per axis
    points = local @ box.rotation.T + box.center
    expected = np.all(np.abs(local) <= box.extents / 2, axis=1)
    np.testing.assert_array_equal(box.contains(points), expected)
    assert 0 < expected.sum() < len(expected)


def test_transformed_box_contains_the_transformed_points(rng):
    box = _random_box(rng)
    T = Sim3(random_rotation(rng), rng.standard_normal(3), 2.5)
    moved = box.transformed(T)
    inside = box.center + (rng.uniform(-0.49, 0.49, (100, 3)) * box.extents) @ box.rotation.T
    assert np.all(moved.contains(T @ inside))
    np.testing.assert_allclose(np.sort(moved.extents), np.sort(box.extents * 2.5))
    assert moved.volume == pytest.approx(box.volume * 2.5**3)


def test_tight_axis_aligned(rng):
    p = rng.standard_normal((50, 3))
    box = OrientedBox.tight_axis_aligned(p)
    assert np.all(box.contains(p, tol=1e-12))
    np.testing.assert_allclose(box.extents, p.max(0) - p.min(0))
    with pytest.raises(ValueError, match="points: need at least 1 points"):
        OrientedBox.tight_axis_aligned(np.zeros((0, 3)))


def test_invalid_boxes():
    with pytest.raises(ValueError, match="extents: must be non-negative"):
        OrientedBox(np.zeros(3), np.eye(3), [1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="rotation: not a rotation"):
        OrientedBox(np.zeros(3), -np.eye(3), np.ones(3))
    with pytest.raises(ValueError, match="upper: must be >= lower"):
        OrientedBox.axis_aligned([0, 0, 1], [1, 1, 0])


def test_box_arrays_are_copied_and_read_only(rng):
    center = np.zeros(3)
    box = OrientedBox(center, np.eye(3), np.ones(3))
    center[0] = 5.0
    assert box.center[0] == 0.0
    with pytest.raises(ValueError):
        box.extents[0] = 2.0


def test_unit_diagonal_scales_each_box_to_a_unit_diagonal_and_keeps_its_proportions():
    from ancsh.geometry.boxes import unit_diagonal

    rng = np.random.default_rng(3)
    ext = np.vstack([rng.uniform(0.1, 2.0, size=(4, 3)), np.zeros(3)])
    out = unit_diagonal(ext)
    np.testing.assert_allclose(np.linalg.norm(out[:4], axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(out[:4] * np.linalg.norm(ext[:4], axis=1, keepdims=True), ext[:4], atol=1e-12)
    np.testing.assert_array_equal(out[4], 0.0)  # a degenerate box is left as it is
    np.testing.assert_allclose(unit_diagonal(ext[0]), out[0], atol=0)


def test_unchecked_box_equals_the_validated_one_and_is_frozen():
    from ancsh.geometry.rotations import random_rotation

    rng = np.random.default_rng(5)
    c, R, e = rng.normal(size=3), random_rotation(rng), rng.uniform(0.1, 1.0, 3)
    a, b = OrientedBox(c, R, e), OrientedBox.unchecked(c, R, e)
    for name in ("center", "rotation", "extents"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert not getattr(b, name).flags.writeable
    np.testing.assert_array_equal(a.corners(), b.corners())
    e[0] = 9.0
    assert b.extents[0] != 9.0  # copied
