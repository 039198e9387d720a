"""Every shipped network loads by category name and beats trivial predictors on held-out instances."""

import numpy as np
import pytest

from ancsh.learned.network.weights import load_network, shipped_categories

SHIPPED = shipped_categories()
SHIPPED_DIRECT = shipped_categories("direct_voting")

TEST_FRAMES = 4


def test_laptop_weights_are_shipped():
    assert "laptop" in SHIPPED and "laptop" in SHIPPED_DIRECT


def _model_of(category):
    from ancsh.data.procedural import load_instance

    return load_instance(category, "test", 0)


@pytest.mark.parametrize("category", SHIPPED)
def test_weights_are_small_match_the_category_and_beat_their_stored_baselines(category):
    from ancsh.learned.network.weights import weights_path

    assert weights_path(category).stat().st_size < 5e6
    net = load_network(category)
    model = _model_of(category)
    assert net.kind == "ancsh" and net.num_parts == model.num_parts and net.step > 0
    assert net.revolute.tolist() == [j.is_revolute for j in model.joints]
    assert net.metrics["seg_acc"] > net.metrics["seg_acc_majority"]
    assert net.metrics["npcs_err"] < net.metrics["npcs_err_zero"]


@pytest.fixture(scope="module")
def test_frames(tmp_path_factory):
    from ancsh.data.generate import GenerationConfig, generate_dataset

    def make(category):
        out = tmp_path_factory.mktemp(f"{category}_test")
        generate_dataset(GenerationConfig(category=category, split="test", seed=11, shard_size=4), TEST_FRAMES, out, progress=False)
        return out

    return make


@pytest.mark.slow
@pytest.mark.parametrize("category", SHIPPED)
def test_weights_beat_trivial_baselines_on_fresh_test_frames(category, test_frames):
    from ancsh.data.dataset import read_frames
    from ancsh.learned.training.data import arrays_from_dataset
    from ancsh.learned.inference.provider import LearnedProvider
    from ancsh.learned.training.train import evaluate_arrays, trivial_baselines
    from ancsh.solvers.types import Observation

    frames_dir = test_frames(category)
    net = load_network(category)
    arrays = arrays_from_dataset(frames_dir)
    scores = evaluate_arrays(net.model, arrays, net.config)
    base = trivial_baselines(arrays)
    assert scores["seg_acc"] > base["seg_acc_majority"] + 0.1
    assert scores["npcs_err"] < 0.5 * base["npcs_err_zero"]
    assert scores["axis_err_deg"] < 20.0

    provider = LearnedProvider(category)
    frame = next(iter(read_frames(frames_dir)))
    corr = provider.correspond(Observation(frame.points))
    assert np.mean(corr.part_labels == frame.gt.part_labels) > base["seg_acc_majority"]
    for k in range(frame.gt.num_joints):
        cos = abs(corr.joint_axes_naocs[k] @ frame.gt.joint_axes_naocs[k])
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))) < 20.0


@pytest.mark.parametrize("category", SHIPPED_DIRECT)
def test_direct_voting_weights_beat_a_constant_axis(category):
    net = load_network(category, kind="direct_voting")
    model = _model_of(category)
    assert net.kind == "direct_voting" and net.revolute.tolist() == [j.is_revolute for j in model.joints]
    assert net.metrics["seg_acc"] > net.metrics["seg_acc_majority"]
    assert net.metrics["axis_err_deg"] < net.metrics["axis_err_deg_mean_axis"] / 4


def test_weights_command_lists_every_shipped_file(tmp_path, capsys):
    from ancsh.cli import main
    from ancsh.learned.network.weights import available_weights, weights_summary

    out = tmp_path / "weights.md"
    assert main(["weights", "--out", str(out)]) == 0
    text, printed = out.read_text(), capsys.readouterr().out
    assert "ancsh weights --out" in text
    assert "2-core" not in text and "torch thread(s), steps of batch" in text  # the files' settings, not a machine
    for name in available_weights():
        assert f"`{name}.pt`" in text and f"`{name}.pt`" in printed
    table, curves = text.split("## Learning curves")
    curves, _, pose = curves.partition("## Pose validation")
    rows = [line for line in table.splitlines() if line.startswith("| `")]
    assert len(rows) == len(available_weights())
    curve_rows = [line for line in curves.splitlines() if line.startswith("| `")]
    summary = {r["name"]: r for r in weights_summary()}
    # every ANCSH network (first stages and refinement networks) has a validation NPCS curve
    assert len(curve_rows) == sum(r["kind"] == "ancsh" for r in summary.values())
    assert sum(r["kind"] == "ancsh" and not r["refiner"] for r in summary.values()) == len(shipped_categories())
    for name, r in summary.items():
        assert r["refiner"] == name.endswith("_refine") and (f"`{name}.pt` | ancsh (refiner) |" in text) == r["refiner"]
    pose_rows = [line for line in pose.splitlines() if line.startswith("| `")]
    assert len(pose_rows) == sum(bool(r["pose_curve"]) for r in summary.values())
    for line in pose_rows:  # each row lists its history's pose validations and names the best one
        pc = summary[line.split("`")[1][:-3]]["pose_curve"]
        best = min(pc, key=lambda p: p["score"])
        assert line.count(": ") == len(pc) and f"{best['score']:.1f} ({best['step']})" in line


def test_training_settings_sentence_comes_from_the_files_configs():
    from ancsh.studies.weights import training_settings

    row = lambda name, threads: {"name": name, "num_threads": threads, "batch_size": 16, "num_points": 1024}  # noqa: E731
    assert training_settings([row("a", 1), row("b", 1)]) == \
        "Trained (each file's config) with 1 torch thread(s), steps of batch 16, 1024 points."
    text = training_settings([row("a", 1), row("b", 2), row("c", 1)])
    assert "1 torch thread(s), steps of batch 16, 1024 points (`a.pt`, `c.pt`)" in text and "2 torch thread(s)" in text
    assert training_settings([]) == ""


def test_learning_curve_fit_recovers_a_power_law_and_its_projections():
    from ancsh.learned.network.weights import learning_curve_fit

    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(100.0, 3000.0, size=20))
    early = t < 1500.0
    err = np.where(early, 5.0, 0.4 * t**-0.25)  # the early part off the law: only the second half is fitted
    c = learning_curve_fit(t, err)
    assert c["exponent"] == pytest.approx(-0.25) and c["points"] == int((t >= 1500.0).sum())
    assert c["fitted_final"] == pytest.approx(0.4 * t.max() ** -0.25)
    assert c["time_factor_2x"] == pytest.approx(2.0**4) and c["time_factor_5x"] == pytest.approx(5.0**4)
    assert learning_curve_fit(t, np.full(20, 0.1))["time_factor_2x"] == float("inf")  # flat: no projection
    with pytest.raises(ValueError, match="val_err"):
        learning_curve_fit(t, err[:-1])
    with pytest.raises(ValueError, match="val_err"):
        learning_curve_fit(t, -err)
    with pytest.raises(ValueError, match="tail_fraction"):
        learning_curve_fit(t, err, tail_fraction=0.0)
    with pytest.raises(ValueError, match="points in the fitted range"):
        learning_curve_fit(t[:2], err[:2])
