"""p_object (ancsh.studies.object_evidence): is the fitted segment an object of the category at all?"""

import json

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.learned.inference.confidence import OBJECT_FEATURES, probability_good
from ancsh.data.scenes import clutter_model
from ancsh.studies.object_evidence import REFINEMENTS, available_refinements, collect_object_evidence, fit_object_calibrator, measure


def test_clutter_is_a_rigid_mesh_about_the_size_asked_for():
    rng = np.random.default_rng(0)
    for _ in range(20):
        model = clutter_model(rng, 0.5)
        assert model.num_parts == 1 and not model.joints
        ext = np.ptp(model.parts[0].vertices, axis=0)
        assert 0.02 < ext.max() < 4.0


def test_the_regression_separates_what_its_features_separate_and_measures_per_source():
    rng = np.random.default_rng(1)
    d = len(OBJECT_FEATURES)
    pos = rng.normal(0.0, 1.0, (60, d)) + 2.0
    neg = rng.normal(0.0, 1.0, (30, d)) - 2.0
    X, y = np.vstack([pos, neg]), np.r_[np.ones(60, bool), np.zeros(30, bool)]
    cal = fit_object_calibrator(X, y)
    assert cal["features"] == list(OBJECT_FEATURES) and cal["frames"] == 90
    assert probability_good(cal, np.full(d, 2.0)) > 0.95 and probability_good(cal, np.full(d, -2.0)) < 0.05
    out = measure(cal, X, y, ["laptop"] * 60 + ["clutter"] * 30, 0.5)
    assert out["laptop"]["frames"] == 60 and out["laptop"]["accepted"] > 0.9 and out["clutter"]["accepted"] < 0.1
    assert out["_all"]["true_accept"] == out["laptop"]["accepted"]
    with pytest.raises(ValueError, match="both"):
        fit_object_calibrator(pos, np.ones(60, bool))


def test_measure_splits_the_acceptance_per_refinement():
    rng = np.random.default_rng(2)
    d = len(OBJECT_FEATURES)
    X = np.vstack([rng.normal(2.0, 0.3, (20, d)), rng.normal(-2.0, 0.3, (20, d))])
    y = np.r_[np.ones(20, bool), np.zeros(20, bool)]
    cal = fit_object_calibrator(X, y)
    # the "none" fits' objects look like other things here: only its share of objects accepted drops
    X_check = X.copy()
    refinement = ["none", "network"] * 20
    X_check[:20:2] = -2.0
    out = measure(cal, X_check, y, ["laptop"] * 20 + ["clutter"] * 20, 0.5, refinement)
    by = out["_refinement"]
    assert list(by) == ["none", "network"]
    assert by["none"]["objects"] == 10 and by["none"]["others"] == 10
    assert by["none"]["true_accept"] == 0.0 and by["network"]["true_accept"] == 1.0
    assert by["none"]["false_accept"] == 0.0 and by["network"]["false_accept"] == 0.0
    assert out["_all"]["true_accept"] == 0.5
    assert "_refinement" not in measure(cal, X, y, ["laptop"] * 20 + ["clutter"] * 20, 0.5)


def test_the_report_sets_the_shipped_model_beside_the_new_one_per_refinement(tmp_path):
    from ancsh.studies.object_evidence import write_object_report

    rng = np.random.default_rng(3)
    d = len(OBJECT_FEATURES)
    X = np.vstack([rng.normal(2.0, 0.3, (20, d)), rng.normal(-2.0, 0.3, (20, d))])
    y = np.r_[np.ones(20, bool), np.zeros(20, bool)]
    new = fit_object_calibrator(X, y)
    old = dict(new, intercept=new["intercept"] - 100.0)  # rejects everything
    refinement, source = ["none", "network"] * 20, ["laptop"] * 20 + ["clutter"] * 20
    data = {"failed": {}, "source": source, "refinements": ["none", "network"]}
    paths = write_object_report("laptop", new, measure(new, X, y, source, 0.5, refinement), data, tmp_path, command="c",
                                threshold=0.5, installed=measure(old, X, y, source, 0.5, refinement))
    text = paths["md"].read_text()
    assert "shipped before: laptop fits accepted" in text
    # the old model rejects everything: its acceptance is 0 %, its ranking (AUC) the same as the new one's
    assert "| none | 10 | 100% | 10 | 0% | 1.000 | 0% | 0% | 1.000 |" in text
    assert "| network | 10 | 100% | 10 | 0% | 1.000 | 0% | 0% | 1.000 |" in text
    paths = write_object_report("laptop", new, measure(new, X, y, source, 0.5, refinement), data, tmp_path / "alone",
                                command="c", threshold=0.5)
    assert "shipped before" not in paths["md"].read_text()


def test_auc_counts_the_pairs_ranked_right_and_ties_as_half():
    from ancsh.studies.object_evidence import auc

    assert auc([0.9, 0.8], [0.1, 0.2]) == 1.0 and auc([0.1], [0.9]) == 0.0
    assert auc([0.5, 0.9], [0.5, 0.1]) == pytest.approx((0.5 + 1 + 1 + 1) / 4)
    assert np.isnan(auc([], [0.3]))


def test_every_shipped_refinement_is_measured_and_unknown_ones_are_refused():
    # every category ships a template library and a refinement network (ancsh/weights/<category>_refine.pt)
    assert available_refinements("laptop") == REFINEMENTS
    with pytest.raises(ValueError, match="refinements"):
        collect_object_evidence("laptop", 8, refinements=("icp",))
    with pytest.raises(ValueError, match="refinements"):
        collect_object_evidence("laptop", 8, refinements=())


@pytest.mark.slow
def test_calibrate_object_writes_a_report_and_a_model_predict_can_read(tmp_path, capsys):
    assert main(["calibrate", "--category", "laptop", "--object", "--frames", "8", "--out", str(tmp_path), "--no-progress"]) == 0
    cal = json.loads((tmp_path / "laptop_object.json").read_text())
    assert cal["features"] == list(OBJECT_FEATURES) and len(cal["coef"]) == len(OBJECT_FEATURES)
    assert len(cal["weights_sha256"]) == 64 and cal["refinements"] == list(REFINEMENTS)
    text = (tmp_path / "laptop_object.md").read_text()
    assert "ancsh calibrate --category laptop --object --frames 8" in text and "| laptop | yes |" in text
    for refinement in REFINEMENTS:  # each refinement's fits measured apart
        assert f"\n| {refinement} | " in text
    assert "shipped before: laptop fits accepted" in text  # the shipped model measured on the same check fits
    evidence = tmp_path / "laptop_object_evidence.npz"  # the examples, to fit the model again without the frames
    assert main(["calibrate", "--category", "laptop", "--object", "--evidence", str(evidence), "--out",
                 str(tmp_path / "again"), "--no-progress"]) == 0
    again = json.loads((tmp_path / "again" / "laptop_object.json").read_text())
    assert again["coef"] == pytest.approx(cal["coef"]) and again["intercept"] == pytest.approx(cal["intercept"])
    assert "--evidence" in (tmp_path / "again" / "laptop_object.md").read_text()
    capsys.readouterr()
    (tmp_path / "junk.npz").write_text("not an archive")
    for bad, why in ((tmp_path / "junk.npz", "is not an object evidence file"), (tmp_path / "none.npz", "is not a file")):
        assert main(["calibrate", "--category", "laptop", "--object", "--evidence", str(bad), "--out",
                     str(tmp_path / "bad")]) == 2
        assert "--evidence" in (err := capsys.readouterr().err) and why in err
    assert main(["calibrate", "--category", "laptop", "--evidence", str(evidence), "--out", str(tmp_path / "bad")]) == 2
    assert "--evidence: only with --object" in capsys.readouterr().err
    assert main(["calibrate", "--category", "laptop", "--object", "--frames", "5", "--out", str(tmp_path)]) == 2
    assert "--frames: expected at least 8 frames with --object" in capsys.readouterr().err
    assert "rendered scenes" not in text and "in a scene" not in text
    assert main(["calibrate", "--category", "laptop", "--object", "--frames", "8", "--scenes", "2", "--out",
                 str(tmp_path / "scenes"), "--no-progress"]) == 0
    text = (tmp_path / "scenes" / "laptop_object.md").read_text()
    assert "--object --frames 8 --scenes 2" in text and "rendered scenes" in text


def test_scene_candidates_are_labelled_by_their_overlap_with_the_object():
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.data.scenes import render_scene
    from ancsh.learned.inference.category import load_category
    from ancsh.learned.inference.provider import LearnedProvider
    from ancsh.studies.object_evidence import _scene_candidates

    scene = render_scene(FrameGenerator(GenerationConfig(category="laptop", split="test", seed=3)), 0, 0, stairs=False)
    found, failed = _scene_candidates(scene.depth, scene.intrinsics, [scene.visible], load_category("laptop"),
                                      LearnedProvider("laptop", seed=0), 0)
    assert len(found) + failed >= 1 and all(len(x) == len(OBJECT_FEATURES) for x, _, _ in found)
    assert any(is_object for _, is_object, _ in found)  # the laptop's segment (alone, or with what is attached to it)
    assert {r for _, _, r in found} == {"none"}  # fitted once per refinement asked for: the first stage alone


def test_planar_share_tells_a_wall_from_a_corner():
    from ancsh.learned.inference.confidence import planar_share

    rng = np.random.default_rng(2)
    wall = np.c_[rng.uniform(-1, 1, (500, 2)), rng.normal(0, 0.002, 500)]
    corner = np.vstack([wall[:250], np.c_[rng.uniform(-1, 1, 250), np.zeros(250) + rng.normal(0, 0.002, 250),
                                          rng.uniform(0.1, 1, 250)]])
    assert planar_share(wall, 0.01) > 0.98
    assert 0.45 < planar_share(corner, 0.01) < 0.6
    assert planar_share(wall[:2], 0.01) == 1.0


def test_an_object_calibration_of_other_features_is_not_applied(tmp_path, monkeypatch):
    """A calibration made before a feature was added (7 numbers) is ignored, not misapplied to 8."""
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.learned.inference import confidence
    from ancsh.learned.inference.predict import predict_depth
    from ancsh.learned.network.weights import weights_path
    from ancsh.outputs import file_sha256

    stale = {"features": list(OBJECT_FEATURES[:-1]), "mean": [0.0] * 7, "scale": [1.0] * 7, "coef": [-9.0] * 7,
             "intercept": -9.0, "weights_sha256": file_sha256(weights_path("laptop"))}
    (tmp_path / "laptop_object.json").write_text(json.dumps(stale))
    monkeypatch.setattr(confidence, "object_calibration_path", lambda category: tmp_path / f"{category}_object.json")
    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=5))
    frame = gen.frame(0)
    _, renderer = gen.instance(frame.instance_index)
    depth = renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth
    pred = predict_depth(depth, frame.intrinsics, "laptop", mask=depth > 0)
    assert pred.p_object is None and pred.render_compare is not None and pred.result.ok
