"""Evaluation helpers: realistic initial guesses, the AD criterion, rendered sequences, the report."""

import numpy as np

from ancsh.data.procedural import make_object
from ancsh.data.render import object_extent
from ancsh.geometry.rotations import geodesic_angle
from ancsh.geometry.transforms import Sim3
from ancsh.studies.cad import FrameRecord, PartPoints, ad_correct, perturbed_init, render_sequence, write_report


def test_perturbed_init_stays_in_the_stated_ranges():
    model = make_object("laptop", 1)
    T = Sim3(np.eye(3), [0.0, 0.0, 1.5])
    diag = object_extent(model, model.rest_states)[1]
    rng = np.random.default_rng(0)
    for _ in range(20):
        init = perturbed_init(model, T, rng)
        assert 15.0 - 1e-9 <= np.degrees(geodesic_angle(init.T_cam_base.rotation, T.rotation)) <= 30.0 + 1e-9
        model.check_states(init.q)
        assert np.linalg.norm(init.T_cam_base.translation - T.translation) < 0.05 * diag + 0.3 * diag


def test_ad_criterion_against_a_known_shift():
    model = make_object("drawer", 0)
    pp = PartPoints(model)
    truth = [Sim3(np.eye(3), [0.0, 0.0, 2.0]) @ T for T in model.forward_kinematics(model.rest_states)]
    ok, ratios = ad_correct(pp, truth, truth)
    assert ok.all() and np.all(ratios == 0)
    shift = 0.12 * pp.diameters[1]  # moving only part 1 by 12% of its diameter
    moved = list(truth)
    moved[1] = Sim3(np.eye(3), [shift, 0.0, 0.0]) @ truth[1]
    ok, ratios = ad_correct(pp, moved, truth)
    assert ok.tolist() == [True, False, True, True]
    np.testing.assert_allclose(ratios[1], 0.12)


def test_render_sequence_keeps_the_articulation_and_labels_points(tmp_path):
    model = make_object("laptop", 0)
    q = model.random_states(np.random.default_rng(1))
    seq = render_sequence(model, q, 3, 0, noise=True, points=500)
    assert len(seq) == 3
    for fr in seq:
        np.testing.assert_array_equal(fr.q, q)
        assert fr.points_cam.shape == (500, 3) and fr.part_labels.shape == (500,)
        assert np.all(fr.points_cam[:, 2] > 0) and set(np.unique(fr.part_labels)) <= {0, 1}
    rec = [FrameRecord("o", noise, 0, m, [True, c], c, [0.01], 0.1, "success") for noise in (False, True)
           for m, c in (("articulated_icp", True), ("whole_object_icp", False))]
    meta = {"objects": [{"name": "o", "parts": ["a", "b"], "joints": [("j", "revolute")]}], "skipped": ["x: no joint"],
            "config": {"frames": 1, "points": 10, "image_size": [320, 240]}}
    text = write_report(rec, meta, tmp_path / "r.md", command="test", methods=("articulated_icp", "whole_object_icp"))
    assert "| articulated_icp | 100.0% | 100.0% |" in text and "| whole_object_icp | 0.0% | 0.0% |" in text
    assert (tmp_path / "r.json").is_file() and "x: no joint" in text
