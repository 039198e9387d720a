"""p_object (ancsh.studies.object_evidence): is the fitted segment an object of the category at all?"""

import json

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.learned.inference.confidence import OBJECT_FEATURES, probability_good
from ancsh.studies.object_evidence import clutter_model, fit_object_calibrator, measure


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


@pytest.mark.slow
def test_calibrate_object_writes_a_report_and_a_model_predict_can_read(tmp_path, capsys):
    assert main(["calibrate", "--category", "laptop", "--object", "--frames", "8", "--out", str(tmp_path), "--no-progress"]) == 0
    cal = json.loads((tmp_path / "laptop_object.json").read_text())
    assert cal["features"] == list(OBJECT_FEATURES) and len(cal["coef"]) == len(OBJECT_FEATURES)
    assert len(cal["weights_sha256"]) == 64
    text = (tmp_path / "laptop_object.md").read_text()
    assert "ancsh calibrate --category laptop --object --frames 8" in text and "| laptop | yes |" in text
    assert main(["calibrate", "--category", "laptop", "--object", "--frames", "5", "--out", str(tmp_path)]) == 2
    assert "--frames: expected at least 8 frames with --object" in capsys.readouterr().err
