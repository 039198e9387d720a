"""The calibrated confidence: features of a fit, a logistic regression of 'good', its reliability, its use in predict."""

import json
import warnings

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.learned.inference import confidence
from ancsh.learned.inference.confidence import FEATURES, fit_features, probability_good
from ancsh.studies.confidence_calibration import collect, fit_calibrator, reliability


def test_calibrator_recovers_a_known_logistic_relation():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(4000, len(FEATURES)))
    p_true = 1.0 / (1.0 + np.exp(-(2.0 * X[:, 0] - 1.0 * X[:, 1] + 0.5)))
    good = rng.random(4000) < p_true
    cal = fit_calibrator(X[:2000], good[:2000])
    assert cal["features"] == list(FEATURES) and len(cal["coef"]) == len(FEATURES)
    p = np.array([probability_good(cal, x) for x in X[2000:]])
    assert np.abs(p - p_true[2000:]).mean() < 0.05
    rel = reliability(cal, X[2000:], good[2000:])
    for b in rel["bins"]:
        if b["frames"] > 100:
            assert abs(b["predicted"] - b["observed"]) < 0.08
    assert rel["brier"] < rel["brier_constant"]
    with pytest.raises(ValueError, match="both good and bad"):
        fit_calibrator(X[:10], np.ones(10, dtype=bool))
    # far outside the calibration range (e.g. 50x the points): 0 or 1, without an overflow warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        far = np.zeros(len(FEATURES))
        far[0] = 1e4
        assert probability_good(cal, far) == 1.0 and probability_good(cal, -far) == 0.0


def test_features_treat_missing_evidence_as_worst():
    q = [{"points": 100, "inlier_ratio": 0.9, "residual_m": 0.01, "seg_margin": 0.8},
         {"points": 0, "inlier_ratio": float("nan"), "residual_m": float("nan"), "seg_margin": float("nan")},
         {"points": 30, "inlier_ratio": float("nan"), "residual_m": float("nan"), "seg_margin": 0.4}]
    f = fit_features(q, "laptop")
    assert f.shape == (len(FEATURES),)
    assert f[0] == 0.0 and f[1] == 1.0 and f[2] == pytest.approx(0.4) and f[4] == pytest.approx(np.log(130))


@pytest.mark.slow
def test_collect_labels_rendered_frames():
    data = collect("laptop", 4, progress=False)
    assert data["X"].shape == (4, len(FEATURES)) and data["good"].dtype == bool
    assert np.array_equal(data["good"], data["rot_deg"] < 10.0)


def test_predict_reports_the_calibrated_probability(monkeypatch, tmp_path):
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.learned.inference.predict import predict_depth
    from ancsh.learned.network.weights import weights_path
    from ancsh.outputs import file_sha256

    cal = {"features": list(FEATURES), "good_rotation_deg": 10.0, "mean": [0.0] * 5, "scale": [1.0] * 5,
           "coef": [0.0] * 5, "intercept": float(np.log(3.0)), "frames": 10, "good_rate": 0.75,
           "weights_sha256": file_sha256(weights_path("laptop"))}
    path = tmp_path / "laptop_confidence.json"
    path.write_text(json.dumps(cal))
    monkeypatch.setattr(confidence, "calibration_path", lambda category: path)
    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
    frame = gen.frame(2)  # an open laptop, found without a mask
    _, renderer = gen.instance(frame.instance_index)
    depth = renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth
    data = predict_depth(depth, frame.intrinsics, "laptop").to_json()
    assert data["ok"] and data["confidence"]["p_good"] == pytest.approx(0.75)
    path.write_text(json.dumps({**cal, "weights_sha256": "0" * 64}))  # calibrated for other weights: not used
    assert predict_depth(depth, frame.intrinsics, "laptop").to_json()["confidence"]["p_good"] is None
    path.unlink()
    assert predict_depth(depth, frame.intrinsics, "laptop").to_json()["confidence"]["p_good"] is None


def test_calibrate_refuses_too_few_frames(capsys):
    assert main(["calibrate", "--category", "laptop", "--frames", "2"]) == 2
    assert "--frames" in capsys.readouterr().err


@pytest.mark.parametrize("kind", [[], ["--object"]])
def test_calibrate_installs_only_from_enough_frames(capsys, kind):
    """A calibration from a handful of frames (issue 35: 3 fit frames) is refused before any work when it would be
    installed over the shipped one."""
    from ancsh.cli.learned import MIN_INSTALL_FRAMES
    from ancsh.learned.inference.confidence import calibration_path, object_calibration_path

    shipped = (object_calibration_path if kind else calibration_path)("laptop")
    before = shipped.read_bytes()
    frames = str(MIN_INSTALL_FRAMES - 1)
    assert main(["calibrate", "--category", "laptop", *kind, "--frames", frames, "--install", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "--install" in err and f"at least {MIN_INSTALL_FRAMES} frames" in err
    assert shipped.read_bytes() == before


def test_infer_takes_the_raw_prediction_from_either_provider_interface():
    from types import SimpleNamespace

    from ancsh.learned.inference.predict import infer

    corr, raw = object(), object()
    new = SimpleNamespace(infer=lambda obs: SimpleNamespace(correspondences=corr, prediction=raw))
    old = SimpleNamespace(correspond=lambda obs: corr, last_prediction=raw)
    bare = SimpleNamespace(correspond=lambda obs: corr)
    assert infer(new, None) == (corr, raw) and infer(old, None) == (corr, raw) and infer(bare, None) == (corr, None)


def test_calibration_falls_back_to_the_base_rate_where_the_evidence_does_not_predict():
    """Informative features: the regression is kept; features unrelated to the outcome at a 96 % base rate: the
    constant base rate is (the regression's check-frame Brier score is no better); p_good is then the rate."""
    from ancsh.studies.confidence_calibration import choose_calibrator

    rng = np.random.default_rng(3)
    X = rng.normal(size=(400, len(FEATURES)))
    informative = rng.random(400) < 1.0 / (1.0 + np.exp(-3.0 * X[:, 0]))
    cal, rel = choose_calibrator(X[:200], informative[:200], X[200:], informative[200:])
    assert cal["model"] == "logistic" and cal["brier_check"]["logistic"] < cal["brier_check"]["constant"]
    assert rel["brier"] == cal["brier_check"]["logistic"]
    noise = rng.random(400) < 0.96
    noise[:4] = False  # both outcomes in the fitting half
    cal, rel = choose_calibrator(X[:200], noise[:200], X[200:], noise[200:])
    assert cal["model"] == "constant" and cal["brier_check"]["constant"] <= cal["brier_check"]["logistic"]
    assert probability_good(cal, X[250]) == pytest.approx(noise[:200].mean())
    assert rel["brier"] == cal["brier_check"]["constant"]
    # every fitting frame good (a network without a bad fit in them): the constant at the add-one rate, not an error
    all_good = np.ones(400, dtype=bool)
    all_good[300] = False
    cal, rel = choose_calibrator(X[:200], all_good[:200], X[200:], all_good[200:])
    assert cal["model"] == "constant" and set(cal["brier_check"]) == {"constant"}
    assert probability_good(cal, X[250]) == pytest.approx(201 / 202)
    assert rel["frames"] == 200 and rel["good_rate"] == pytest.approx(199 / 200)
    from ancsh.studies.confidence_calibration import _model_sentence

    assert "one outcome only" in _model_sentence(cal)  # the report says why no regression was tried
    # three bad fits among 200 fitting frames, each told apart by its first feature (a regression would even win on
    # the check frames): too few to fit five coefficients, so the constant rate
    few_bad = X[:, 0] > -1.9
    assert (~few_bad[:200]).sum() == 3 and (~few_bad[200:]).sum() >= 3
    cal, _ = choose_calibrator(X[:200], few_bad[:200], X[200:], few_bad[200:])
    assert cal["model"] == "constant" and probability_good(cal, X[250]) == pytest.approx(197 / 200)
