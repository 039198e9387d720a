"""`ancsh demo` end to end (one category) and the shared frame evaluation."""

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.evaluation import evaluate_fit
from ancsh.geometry import Sim3, axis_angle_matrix
from ancsh.model import ancsh_ground_truth, random_articulated_model, sample_frame
from ancsh.solvers import Correspondences, Observation, fit


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
    assert rec["ok"]
    assert max(p["rot_deg"] for p in rec["parts"]) < 1e-5
    assert max(p["trans"] for p in rec["parts"]) < 1e-6
    assert min(p["iou"] for p in rec["parts"]) > 1 - 1e-6
    assert min(p["iou_pose"] for p in rec["parts"]) > 1 - 1e-6
    assert max(j["axis_deg"] for j in rec["joints"]) < 1e-5


def test_rotated_part_pose_shows_its_rotation_error(frame_and_gt):
    f, gt = frame_and_gt
    result = fit(Observation(f.points_cam), Correspondences.from_ground_truth(gt), "per_part")
    T = result.T_cam_npcs[1]
    turned = Sim3(T.rotation @ axis_angle_matrix([0, 0, 1], np.radians(7.0)), T.translation, T.scale)
    from dataclasses import replace

    bad = replace(result, T_cam_npcs=(result.T_cam_npcs[0], turned) + tuple(result.T_cam_npcs[2:]))
    rec = evaluate_fit(bad, gt)
    assert rec["parts"][1]["rot_deg"] == pytest.approx(7.0, abs=1e-6)
    assert rec["parts"][0]["rot_deg"] < 1e-5
    # the true-size box at the turned pose loses overlap; the untouched part keeps it
    assert rec["parts"][1]["iou_pose"] < 1 - 1e-3
    assert rec["parts"][0]["iou_pose"] > 1 - 1e-6
