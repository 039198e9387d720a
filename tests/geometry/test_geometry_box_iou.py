"""Exact oriented-box IoU: closed forms, Monte-Carlo agreement, symmetry, invariance, edge cases."""

import numpy as np
import pytest

from ancsh.geometry import OrientedBox, Sim3, axis_angle_matrix, box_iou, intersection_volume, random_rotation


def _aabb_iou(lo_a, hi_a, lo_b, hi_b):
    overlap = np.clip(np.minimum(hi_a, hi_b) - np.maximum(lo_a, lo_b), 0, None)
    inter = np.prod(overlap)
    return inter / (np.prod(hi_a - lo_a) + np.prod(hi_b - lo_b) - inter)


def test_axis_aligned_boxes_match_the_closed_form(rng):
    for _ in range(50):
        lo_a, lo_b = rng.uniform(-1, 1, (2, 3))
        hi_a, hi_b = lo_a + rng.uniform(0.1, 2, 3), lo_b + rng.uniform(0.1, 2, 3)
        a, b = OrientedBox.axis_aligned(lo_a, hi_a), OrientedBox.axis_aligned(lo_b, hi_b)
        assert box_iou(a, b) == pytest.approx(_aabb_iou(lo_a, hi_a, lo_b, hi_b), abs=1e-12)


def test_same_axis_aligned_boxes_in_a_common_rotated_frame(rng):
    lo_a, hi_a = np.zeros(3), np.array([1.0, 2.0, 0.5])
    lo_b, hi_b = np.array([0.3, -0.5, 0.1]), np.array([2.0, 1.0, 1.0])
    T = Sim3(random_rotation(rng), rng.standard_normal(3), 1.7)
    a = OrientedBox.axis_aligned(lo_a, hi_a).transformed(T)
    b = OrientedBox.axis_aligned(lo_b, hi_b).transformed(T)
    assert box_iou(a, b) == pytest.approx(_aabb_iou(lo_a, hi_a, lo_b, hi_b), abs=1e-12)


def test_square_turned_by_45_degrees_gives_an_octagon_prism():
    # Unit square and the same square turned 45 degrees overlap in a regular octagon
    # of area 2 (sqrt 2 - 1); the height 0.5 of overlap makes a prism.
    a = OrientedBox(np.zeros(3), np.eye(3), np.ones(3))
    b = OrientedBox([0.0, 0.0, 0.5], axis_angle_matrix([0, 0, 1], np.pi / 4), np.ones(3))
    inter = 2 * (np.sqrt(2) - 1) * 0.5
    assert intersection_volume(a, b) == pytest.approx(inter, abs=1e-12)
    assert box_iou(a, b) == pytest.approx(inter / (2 - inter), abs=1e-12)


def test_agrees_with_monte_carlo_for_random_rotated_boxes():
    rng = np.random.default_rng(4)
    m = 40_000
    for _ in range(12):
        a = OrientedBox(rng.uniform(-0.3, 0.3, 3), random_rotation(rng), rng.uniform(0.3, 1.5, 3))
        b = OrientedBox(rng.uniform(-0.3, 0.3, 3), random_rotation(rng), rng.uniform(0.3, 1.5, 3))
        local = rng.uniform(-0.5, 0.5, (m, 3)) * a.extents
        p = b.contains(local @ a.rotation.T + a.center).mean()  # fraction of a inside b
        estimate = p * a.volume
        sem = np.sqrt(p * (1 - p) / m) * a.volume
        assert p > 0.01  # the sample really tests an overlap
        assert abs(intersection_volume(a, b) - estimate) < 5 * sem + 1e-12


def test_identical_boxes_have_iou_one(rng):
    box = OrientedBox(rng.standard_normal(3), random_rotation(rng), rng.uniform(0.1, 2, 3))
    assert box_iou(box, box) == pytest.approx(1.0, abs=1e-12)
    assert intersection_volume(box, box) == pytest.approx(box.volume, rel=1e-12)


def test_disjoint_and_touching_boxes_have_iou_zero(rng):
    a = OrientedBox.axis_aligned([0, 0, 0], [1, 1, 1])
    assert box_iou(a, OrientedBox.axis_aligned([2, 2, 2], [3, 3, 3])) == 0.0
    # Disjoint but within each other's bounding spheres: separated by a face plane.
    near = OrientedBox([1.6, 0.5, 0.5], axis_angle_matrix([1, 1, 0], 0.3), [0.5, 2.0, 2.0])
    assert np.linalg.norm(near.center - a.center) < 0.5 * (a.diagonal + near.diagonal)
    assert box_iou(a, near) == 0.0
    for touching in (
        OrientedBox.axis_aligned([1, 0, 0], [2, 1, 1]),  # shared face
        OrientedBox.axis_aligned([1, 1, 0], [2, 2, 1]),  # shared edge
        OrientedBox.axis_aligned([1, 1, 1], [2, 2, 2]),  # shared corner
        OrientedBox.axis_aligned([1, 0.2, 0.2], [2, 0.7, 0.7]),  # face inside a face
    ):
        assert box_iou(a, touching) == 0.0
        assert box_iou(touching, a) == 0.0


def test_containment(rng):
    outer = OrientedBox(rng.standard_normal(3), random_rotation(rng), np.array([2.0, 3.0, 4.0]))
    inner = OrientedBox(outer.center + 0.1, random_rotation(rng), np.array([0.5, 0.7, 0.9]))
    assert np.all(outer.contains(inner.corners()))
    assert intersection_volume(outer, inner) == pytest.approx(inner.volume, rel=1e-12)
    assert box_iou(outer, inner) == pytest.approx(inner.volume / outer.volume, rel=1e-12)


def test_symmetric_and_invariant_to_a_common_rigid_transform(rng):
    for _ in range(20):
        a = OrientedBox(rng.uniform(-0.5, 0.5, 3), random_rotation(rng), rng.uniform(0.2, 2, 3))
        b = OrientedBox(rng.uniform(-0.5, 0.5, 3), random_rotation(rng), rng.uniform(0.2, 2, 3))
        iou = box_iou(a, b)
        assert 0.0 <= iou <= 1.0
        assert box_iou(b, a) == pytest.approx(iou, abs=1e-12)
        T = Sim3(random_rotation(rng), rng.standard_normal(3) * 10)
        assert box_iou(a.transformed(T), b.transformed(T)) == pytest.approx(iou, abs=1e-10)
        # A common scale changes volumes, not the ratio.
        S = Sim3(np.eye(3), np.zeros(3), 3.0)
        assert box_iou(a.transformed(S), b.transformed(S)) == pytest.approx(iou, abs=1e-10)


def test_box_rotated_by_its_own_symmetry_is_the_same_box(rng):
    a = OrientedBox(rng.standard_normal(3), random_rotation(rng), [0.4, 1.0, 2.0])
    flipped = OrientedBox(a.center, a.rotation @ axis_angle_matrix([0, 0, 1], np.pi), a.extents)
    assert box_iou(a, flipped) == pytest.approx(1.0, abs=1e-12)


def test_tiny_overlap_is_positive_and_accurate():
    a = OrientedBox.axis_aligned([0, 0, 0], [1, 1, 1])
    b = OrientedBox.axis_aligned([1 - 1e-6, 0, 0], [2, 1, 1])
    assert intersection_volume(a, b) == pytest.approx(1e-6, rel=1e-6)


def test_zero_volume_boxes():
    a = OrientedBox.axis_aligned([0, 0, 0], [1, 1, 1])
    flat = OrientedBox.axis_aligned([0.2, 0.2, 0.5], [0.8, 0.8, 0.5])
    assert box_iou(a, flat) == 0.0 and box_iou(flat, a) == 0.0
    with pytest.raises(ValueError, match="both boxes have zero volume"):
        box_iou(flat, flat)
    with pytest.raises(ValueError, match="b: expected an OrientedBox"):
        box_iou(a, np.zeros(3))
