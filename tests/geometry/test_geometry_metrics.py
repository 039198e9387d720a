"""Evaluation metrics: rotation/translation error, joint state errors, axis errors, AD."""

import numpy as np
import pytest

from ancsh.geometry import (
    OrientedBox,
    Sim3,
    ad_error,
    axis_angle_error_deg,
    axis_angle_matrix,
    box_iou,
    joint_state_error,
    random_rotation,
    rotation_error_deg,
    translation_error,
)
from ancsh.geometry import metrics


def test_rotation_error_in_degrees(rng):
    R = random_rotation(rng)
    for deg in (0.0, 1e-6, 5.0, 90.0, 179.0, 180.0):
        R_est = R @ axis_angle_matrix(rng.standard_normal(3), np.radians(deg))
        assert rotation_error_deg(R_est, R) == pytest.approx(deg, abs=1e-9)


def test_translation_error():
    assert translation_error([1.0, 2.0, 3.0], [1.0, 2.0, 0.0]) == pytest.approx(3.0)
    with pytest.raises(ValueError, match=r"t_gt: expected shape \(3,\)"):
        translation_error(np.zeros(3), np.zeros(4))


def test_joint_state_error_units_and_wrapping():
    assert joint_state_error(np.radians(30.0), np.radians(10.0), "revolute") == pytest.approx(20.0)
    assert joint_state_error(np.radians(-179.0), np.radians(179.0), "revolute") == pytest.approx(2.0)
    assert joint_state_error(0.1, 0.35, "prismatic") == pytest.approx(0.25)
    with pytest.raises(ValueError, match="joint_type: expected 'revolute' or 'prismatic'"):
        joint_state_error(0.0, 0.0, "ball")
    with pytest.raises(ValueError, match="q_est, q_gt: expected finite"):
        joint_state_error(np.nan, 0.0, "revolute")


def test_joint_state_error_accepts_the_model_joint_type():
    from ancsh.model.articulated import JointType

    assert joint_state_error(0.5, 0.25, JointType.PRISMATIC) == pytest.approx(0.25)
    assert joint_state_error(0.5, 0.25, JointType.REVOLUTE) == pytest.approx(np.degrees(0.25))


def test_axis_angle_error_deg_treats_opposite_axes_as_equal():
    assert axis_angle_error_deg([0, 0, 1], [0, 0, -1]) == pytest.approx(0.0, abs=1e-12)
    assert axis_angle_error_deg([0, 0, 1], [0, 1, 1]) == pytest.approx(45.0)
    assert axis_angle_error_deg([0, 0, 1], [0, 1, -1]) == pytest.approx(45.0)


def test_ad_error(rng):
    p = rng.standard_normal((100, 3))
    T = Sim3(random_rotation(rng), rng.standard_normal(3), 1.3)
    assert ad_error(p, T, T) == 0.0
    shift = Sim3(np.eye(3), [0.0, 0.05, 0.0]) @ T  # every point moves by 5 cm
    assert ad_error(p, shift, T) == pytest.approx(0.05, abs=1e-12)
    # A rotation about the model origin by theta moves a point at radius r by 2 r sin(theta / 2).
    ring = np.c_[np.cos(np.linspace(0, 6, 50)), np.sin(np.linspace(0, 6, 50)), np.zeros(50)] * 0.2
    turned = T @ Sim3(axis_angle_matrix([0, 0, 1], 0.1))
    assert ad_error(ring, turned, T) == pytest.approx(1.3 * 2 * 0.2 * np.sin(0.05), abs=1e-12)
    with pytest.raises(ValueError, match="T_est: expected a Sim3"):
        ad_error(p, np.eye(4), T)
    with pytest.raises(ValueError, match="points_model: need at least 1 points"):
        ad_error(np.zeros((0, 3)), T, T)


def test_metrics_exports_box_iou():
    assert metrics.box_iou is box_iou
    a = OrientedBox.axis_aligned([0, 0, 0], [2, 1, 1])
    assert metrics.box_iou(a, OrientedBox.axis_aligned([1, 0, 0], [3, 1, 1])) == pytest.approx(1 / 3)
