"""The calibrated confidence: features of a fit, a logistic regression of 'good', its reliability, its use in predict."""

import json
import warnings

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.data.conventions import CONVENTIONS
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
    f = fit_features(q, CONVENTIONS["laptop"].typical_size)
    assert f.shape == (len(FEATURES),)
    assert f[0] == 0.0 and f[1] == 1.0 and f[2] == pytest.approx(0.4) and f[4] == pytest.approx(np.log(130))


@pytest.mark.slow
def test_collect_holds_good_and_bad_fits_of_every_source():
    """The minimum frames of the mix: every source in both halves, labels by the rotation rule, other categories'
    fits never good, and both outcomes present (the rendered frames alone were nearly all good)."""
    from ancsh.studies.confidence_calibration import MIN_FRAMES, SOURCES, fitting_half

    data = collect("laptop", MIN_FRAMES, progress=False)
    n = len(data["good"])
    assert data["X"].shape == (n, len(FEATURES)) and data["good"].dtype == bool and data["frame"].shape == (n,)
    assert np.array_equal(data["good"], data["rot_deg"] < 10.0)
    assert data["source_frames"] == {s: MIN_FRAMES * SOURCES.count(s) // len(SOURCES) for s in SOURCES}
    src = np.asarray(data["source"])
    assert not data["good"][src == "other"].any()
    assert data["good"].any() and not data["good"].all()
    half = fitting_half(data["frame"])
    kept = {s for s in SOURCES if s not in data["failed"] or data["failed"][s] < data["source_frames"][s]}
    for s in kept - {"merged", "other"}:  # the sources whose fits mostly pass their checks
        assert (half & (src == s)).any() and (~half & (src == s)).any(), s
    assert np.all(np.diff(data["frame"]) >= 0) and data["frame"].max() < MIN_FRAMES


def test_hard_segments_are_the_share_asked_for():
    from ancsh.studies.confidence_calibration import CROP_KEEP, _crop, _grown

    rng = np.random.default_rng(4)
    mask = np.zeros((60, 80), dtype=bool)
    mask[20:40, 30:60] = True
    depth = np.where(rng.random(mask.shape) < 0.5, 1.0, 0.0)
    for _ in range(20):
        crop = _crop(mask, rng)
        assert not np.any(crop & ~mask)
        assert CROP_KEEP[0] - 0.05 <= crop.sum() / mask.sum() <= CROP_KEEP[1] + 0.05
        grown = _grown(mask, depth, rng)
        assert np.all(grown[mask]) and np.all(depth[grown & ~mask] > 0) and grown.sum() > mask.sum()


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


@pytest.mark.parametrize("install", [[], ["--install"]])
def test_calibrate_refuses_fewer_frames_than_its_minimum(capsys, install):
    """Issue 63: ``calibrate --frames 5`` exits non-zero naming the minimum, with or without --install, before any
    work (nothing is installed)."""
    from ancsh.learned.inference.confidence import calibration_path
    from ancsh.studies.confidence_calibration import MIN_FRAMES

    before = calibration_path("laptop").read_bytes()
    for frames in ("2", "5", str(MIN_FRAMES - 1)):
        assert main(["calibrate", "--category", "laptop", "--frames", frames, *install, "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert "--frames" in err and f"at least {MIN_FRAMES} frames" in err
    assert calibration_path("laptop").read_bytes() == before


def test_calibrate_object_installs_only_from_enough_frames(capsys):
    """A calibration from a handful of frames (issue 35: 3 fit frames) is refused before any work when it would be
    installed over the shipped one."""
    from ancsh.cli.learned import MIN_INSTALL_FRAMES
    from ancsh.learned.inference.confidence import object_calibration_path

    shipped = object_calibration_path("laptop")
    before = shipped.read_bytes()
    frames = str(MIN_INSTALL_FRAMES - 1)
    assert main(["calibrate", "--category", "laptop", "--object", "--frames", frames, "--install", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "--install" in err and f"at least {MIN_INSTALL_FRAMES} frames" in err
    assert shipped.read_bytes() == before


def test_calibrate_scenes_needs_object(capsys):
    """``--scenes`` belongs to the p_object calibration: without ``--object`` it is an error, not ignored."""
    assert main(["calibrate", "--category", "laptop", "--frames", "400", "--scenes", "3", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "--scenes" in err and "--object" in err


def _synthetic_collect(rng, frames, informative=True):
    """What :func:`collect` returns, for ``frames`` example frames of one fit each (a fake, no network)."""
    from ancsh.studies.confidence_calibration import SOURCES

    X = rng.normal(size=(frames, len(FEATURES)))
    good = rng.random(frames) < (1.0 / (1.0 + np.exp(-3.0 * X[:, 0])) if informative else 0.5)
    src = [SOURCES[i % len(SOURCES)] for i in range(frames)]
    return {"X": X, "good": good, "rot_deg": np.where(good, 1.0, 30.0), "source": src,
            "frame": np.arange(frames), "failed": {"merged": 3},
            "source_frames": {s: src.count(s) for s in dict.fromkeys(SOURCES)}}


def test_calibrate_writes_an_informative_model_and_refuses_one_outcome(monkeypatch, tmp_path, capsys):
    """End to end without the network: the installed-to-be JSON is a logistic regression with both check-fit Brier
    scores and its report names the command and the sources; fits of one outcome are an error naming --frames (no
    constant is written)."""
    from ancsh.studies import confidence_calibration as cc

    rng = np.random.default_rng(5)
    fake = _synthetic_collect(rng, 200)
    monkeypatch.setattr(cc, "collect", lambda *a, **k: fake)
    out = tmp_path / "report"
    assert main(["calibrate", "--category", "laptop", "--frames", "200", "--out", str(out), "--no-progress"]) == 0
    cal = json.loads((out / "laptop_confidence.json").read_text())
    assert cal["model"] == "logistic" and any(c != 0.0 for c in cal["coef"]) and cal["example_frames"] == 200
    assert cal["brier_check"]["logistic"] < cal["brier_check"]["constant"] and 0.5 < cal["auc_check"] <= 1.0
    md = (out / "laptop_confidence.md").read_text()
    assert "calibrate --category laptop --frames 200" in md and "| perturbed |" in md and "beats the constant" in md
    one_outcome = dict(fake, good=np.ones(200, dtype=bool))
    monkeypatch.setattr(cc, "collect", lambda *a, **k: one_outcome)
    out2 = tmp_path / "one"
    assert main(["calibrate", "--category", "laptop", "--frames", "200", "--out", str(out2), "--no-progress"]) == 2
    assert "--frames" in capsys.readouterr().err and not (out2 / "laptop_confidence.json").exists()


def test_infer_takes_the_raw_prediction_from_either_provider_interface():
    from types import SimpleNamespace

    from ancsh.learned.inference.predict import infer

    corr, raw = object(), object()
    new = SimpleNamespace(infer=lambda obs: SimpleNamespace(correspondences=corr, prediction=raw))
    old = SimpleNamespace(correspond=lambda obs: corr, last_prediction=raw)
    bare = SimpleNamespace(correspond=lambda obs: corr)
    assert infer(new, None) == (corr, raw) and infer(old, None) == (corr, raw) and infer(bare, None) == (corr, None)


def test_a_constant_model_is_an_error_not_a_calibration():
    """Informative features: the regression beats the base rate on the check fits; features unrelated to the outcome:
    the regression is still the result, and the report says it does not beat the constant; a constant model (the base
    rate, or a regression of features that never vary) and too few fits of an outcome are errors."""
    from ancsh.studies.confidence_calibration import (MIN_FRAMES_PER_OUTCOME, _model_sentence, calibrate_and_check,
                                                      check_informative, constant_calibrator)

    rng = np.random.default_rng(3)
    X = rng.normal(size=(400, len(FEATURES)))
    informative = rng.random(400) < 1.0 / (1.0 + np.exp(-3.0 * X[:, 0]))
    cal, rel = calibrate_and_check(X[:200], informative[:200], X[200:], informative[200:])
    assert cal["model"] == "logistic" and cal["brier_check"]["logistic"] < cal["brier_check"]["constant"]
    assert rel["brier"] == cal["brier_check"]["logistic"] and "beats the constant" in _model_sentence(cal)
    noise = rng.random(400) < 0.9
    cal, rel = calibrate_and_check(X[:200], noise[:200], X[200:], noise[200:])
    assert cal["model"] == "logistic" and rel["brier"] == cal["brier_check"]["logistic"]
    if cal["brier_check"]["logistic"] >= cal["brier_check"]["constant"]:
        assert "does not beat the constant" in _model_sentence(cal)
    with pytest.raises(ValueError, match="constant model"):
        check_informative(constant_calibrator(noise))
    with pytest.raises(ValueError, match="constant model"):
        check_informative({k: v for k, v in cal.items() if k != "coef"})
    with pytest.raises(ValueError, match="constant model"):  # features that never vary: every coefficient 0
        fit_calibrator(np.ones((200, len(FEATURES))), informative[:200])
    check_informative(cal)
    # one bad fit too few among the fitting fits, each told apart by its first feature: refused, not a constant
    few_bad = np.ones(400, dtype=bool)
    few_bad[:MIN_FRAMES_PER_OUTCOME - 1] = False
    few_bad[200:200 + MIN_FRAMES_PER_OUTCOME] = False
    with pytest.raises(ValueError, match="good_fit"):
        calibrate_and_check(X[:200], few_bad[:200], X[200:], few_bad[200:])
    with pytest.raises(ValueError, match="good_check"):
        calibrate_and_check(X[200:], few_bad[200:], X[:200], few_bad[:200])


def test_every_shipped_calibration_carries_information():
    """Issue 63: no shipped p_good calibration is a constant model, and each is one of the shipped weights: it ranks
    a fit with the best evidence (every point an inlier, no residual, certain segmentation) above one with the worst."""
    from ancsh.data.procedural import CATEGORIES
    from ancsh.learned.network.weights import weights_path
    from ancsh.outputs import file_sha256
    from ancsh.studies.confidence_calibration import check_informative

    shipped = [c for c in CATEGORIES if confidence.calibration_path(c).is_file()]
    assert shipped == [c for c in CATEGORIES if weights_path(c).is_file()]
    for category in shipped:
        cal = json.loads(confidence.calibration_path(category).read_text())
        check_informative(cal)
        assert cal["features"] == list(FEATURES) and cal["weights_sha256"] == file_sha256(weights_path(category))
        best = np.array([1.0, 0.0, 1.0, 1.0, np.log(1024)])
        worst = np.array([0.3, 0.3, 0.1, 0.3, np.log(1024)])
        assert probability_good(cal, best) > probability_good(cal, worst), category
