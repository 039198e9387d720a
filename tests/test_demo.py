"""`ancsh demo` end to end (one category) and the shared frame evaluation."""

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.evaluation import evaluate_fit
from ancsh.geometry import Sim3, axis_angle_matrix
from ancsh.model import ancsh_ground_truth, random_articulated_model, sample_frame
from ancsh.solvers import Correspondences, Observation, fit
from ancsh.solvers.types import FitStatus


def test_demo_prints_table_and_writes_picture(tmp_path, capsys):
    rc = main(["demo", "--categories", "laptop", "--provider", "oracle", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0
    assert "display" in out and "ANCSH exact" in out and "NPCS (per part)" in out
    assert (tmp_path / "laptop.png").stat().st_size > 10_000


def test_demo_rejects_unknown_category(capsys):
    assert main(["demo", "--categories", "toaster"]) == 2
    assert "toaster" in capsys.readouterr().err


@pytest.fixture(scope="module")
def frame_and_gt():
    model = random_articulated_model(3, num_parts=3)
    f = sample_frame(model, 4, points_per_part=150)
    gt = ancsh_ground_truth(model, f.q, f.T_cam_base, f.points_cam, f.part_labels)
    return f, gt


def test_exact_fit_of_noise_free_correspondences_scores_zero_error(frame_and_gt):
    f, gt = frame_and_gt
    result = fit(Observation(f.points_cam), Correspondences.from_ground_truth(gt), "exact_reduced")
    rec = evaluate_fit(result, gt)
    assert rec.ok
    assert max(p.rot_deg for p in rec.parts) < 1e-5
    assert max(p.trans for p in rec.parts) < 1e-6
    assert min(p.iou for p in rec.parts) > 1 - 1e-6
    assert min(p.iou_pose for p in rec.parts) > 1 - 1e-6
    assert max(j.axis_deg for j in rec.joints) < 1e-5
    d = rec.to_dict()
    assert d["ok"] and d["parts"][0]["rot_deg"] == rec.parts[0].rot_deg and d["joints"][0]["type"] == rec.joints[0].type


def test_rotated_part_pose_shows_its_rotation_error(frame_and_gt):
    f, gt = frame_and_gt
    result = fit(Observation(f.points_cam), Correspondences.from_ground_truth(gt), "per_part")
    T = result.T_cam_npcs[1]
    turned = Sim3(T.rotation @ axis_angle_matrix([0, 0, 1], np.radians(7.0)), T.translation, T.scale)
    from dataclasses import replace

    bad = replace(result, T_cam_npcs=(result.T_cam_npcs[0], turned) + tuple(result.T_cam_npcs[2:]))
    rec = evaluate_fit(bad, gt)
    assert rec.parts[1].rot_deg == pytest.approx(7.0, abs=1e-6)
    assert rec.parts[0].rot_deg < 1e-5
    # the true-size box at the turned pose loses overlap; the untouched part keeps it
    assert rec.parts[1].iou_pose < 1 - 1e-3
    assert rec.parts[0].iou_pose > 1 - 1e-6


def test_evaluate_fit_refuses_a_result_of_another_structure(frame_and_gt):
    """A successful fit with fewer parts or joints than the ground truth is an error, not an empty success."""
    from dataclasses import replace

    f, gt = frame_and_gt
    result = fit(Observation(f.points_cam), Correspondences.from_ground_truth(gt), "exact_reduced")
    assert result.ok
    with pytest.raises(ValueError, match="result: its structure does not match.*2 part poses"):
        evaluate_fit(replace(result, T_cam_npcs=result.T_cam_npcs[:2]), gt)
    with pytest.raises(ValueError, match="joint_states of shape"):
        evaluate_fit(replace(result, joint_states=result.joint_states[:1]), gt)
    with pytest.raises(ValueError, match="part_names"):
        evaluate_fit(result, gt, part_names=["a"])
    failed = evaluate_fit(replace(result, status=FitStatus.MAX_ITER, T_cam_npcs=()), gt)
    assert not failed.ok and failed.parts == () and failed.to_dict()["parts"] == []


def test_aggregate_leaves_out_nan_and_none():
    from ancsh.evaluation import aggregate

    a = aggregate([1.0, float("nan"), None, 3.0, float("inf")])
    assert (a.mean, a.median, a.count) == (2.0, 2.0, 2)
    empty = aggregate([float("nan")])
    assert empty.count == 0 and np.isnan(empty.mean) and empty.to_dict() == {"mean": None, "median": None, "count": 0}
