"""Validation of the shared solver types."""

import numpy as np
import pytest

from ancsh.model.articulated import JointType
from ancsh.solvers.types import Correspondences, CorrespondenceProvider, FitResult, FitStatus, Observation


def _corr(**over):
    """Three parts in a chain 0 -> 1 -> 2 (revolute, prismatic), 9 points."""
    args = dict(
        part_labels=np.repeat([0, 1, 2], 3),
        npcs=np.random.default_rng(0).normal(size=(9, 3)),
        npcs_scale=np.ones(3),
        npcs_translation=np.zeros((3, 3)),
        joint_types=("revolute", "prismatic"),
        joint_parents=[0, 1],
        joint_children=[1, 2],
        joint_axes_naocs=[[0, 0, 1.0], [1.0, 0, 0]],
        joint_pivots_naocs=np.zeros((2, 3)),
    )
    args.update(over)
    return Correspondences(**args)


def test_observation_rejects_nan_and_bad_shape():
    with pytest.raises(ValueError, match="points_cam"):
        Observation(np.array([[0.0, np.nan, 1.0]]))
    with pytest.raises(ValueError, match="points_cam"):
        Observation(np.zeros((4, 2)))
    assert Observation(np.zeros((0, 3))).num_points == 0


def test_correspondences_valid_and_structure():
    c = _corr()
    assert c.joint_types == (JointType.REVOLUTE, JointType.PRISMATIC)
    assert c.root_part == 0 and c.topological_joints == (0, 1)
    assert c.structure_key() == (3, ("revolute", "prismatic"), (0, 1), (1, 2))
    with pytest.raises(ValueError, match="read-only"):
        c.npcs[0, 0] = 1.0


@pytest.mark.parametrize(
    "over, match",
    [
        (dict(part_labels=np.repeat([0, 1, 3], 3)), "part_labels"),
        (dict(npcs=np.zeros((8, 3))), "part_labels"),
        (dict(npcs_scale=[1.0, -1.0, 1.0]), "npcs_scale"),
        (dict(joint_axes_naocs=[[0, 0, 2.0], [1.0, 0, 0]]), "joint_axes_naocs"),
        (dict(joint_types=("revolute", "hinge")), "joint_types"),
        (dict(joint_children=[1, 1]), "joint_children"),
        (dict(joint_parents=[0, 0], joint_children=[1, 1]), "joint_types: contradictory"),
        (dict(joint_types=("revolute", "revolute"), joint_children=[1, 0]), "joint_children: joints 0 and 1 both join"),
        (dict(joint_types=("revolute", "revolute"), joint_parents=[0, 0], joint_children=[1, 0]), "joint_children"),
        (dict(joint_types=("revolute",), joint_parents=[0], joint_children=[1], joint_axes_naocs=[[0, 0, 1.0]],
              joint_pivots_naocs=[[0, 0, 0.0]]), "joint_parents"),
        (dict(joint_limits=[[1.0, 0.0], [0.0, 1.0]]), "joint_limits"),
        (dict(weights=-np.ones(9)), "weights"),
    ],
)
def test_correspondences_reject_bad_fields(over, match):
    with pytest.raises(ValueError, match=match):
        _corr(**over)


def test_contradictory_joint_types_between_the_same_parts():
    with pytest.raises(ValueError, match="joint_types: contradictory"):
        _corr(
            npcs_scale=np.ones(3), joint_types=("revolute", "prismatic", "prismatic"),
            joint_parents=[0, 1, 1], joint_children=[1, 2, 0],
            joint_axes_naocs=np.tile([0, 0, 1.0], (3, 1)), joint_pivots_naocs=np.zeros((3, 3)),
        )


def test_from_ground_truth_matches_the_ground_truth(fit_case):
    case = fit_case(3, num_parts=4, tree=True)
    c = case.correspondences
    np.testing.assert_array_equal(c.part_labels, case.gt.part_labels)
    np.testing.assert_allclose(np.linalg.norm(c.npcs_extents, axis=1), 1.0, atol=1e-9)
    assert c.num_joints == 3 and c.joint_limits.shape == (3, 2)


def test_failure_result_shapes_and_protocol():
    r = FitResult.failure(FitStatus.TOO_FEW_POINTS, "x", formulation="soft", solver="lsq", num_joints=2, num_points=5)
    assert not r.ok and r.joint_axes_cam.shape == (2, 3) and np.all(np.isnan(r.joint_states))
    assert r.inliers.shape == (5,) and r.T_cam_npcs == ()

    class Provider:
        def correspond(self, observation):
            return _corr()

    assert isinstance(Provider(), CorrespondenceProvider)
