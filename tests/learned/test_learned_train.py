"""Configuration, data packing, training (overfitting a few frames), checkpoints and resume."""

import dataclasses
import json

import numpy as np
import pytest
import torch

from ancsh.learned.network.config import TrainConfig
from ancsh.learned.training.data import TrainingArrays
from ancsh.learned.training.train import HistoryRow, Trainer, split_by_instance, trivial_baselines, write_history_csv


def test_config_validates_and_round_trips(tmp_path):
    cfg = TrainConfig(width=0.5, npoints=[128, 32])
    assert cfg.npoints == (128, 32)
    cfg.to_json(tmp_path / "c.json")
    assert TrainConfig.from_json(tmp_path / "c.json") == cfg
    assert TrainConfig.from_json(tmp_path / "c.json", max_steps=7).max_steps == 7
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.width = 1.0
    (tmp_path / "bad.json").write_text(json.dumps({"widht": 0.5}))
    with pytest.raises(ValueError, match="unknown key.*widht"):
        TrainConfig.from_json(tmp_path / "bad.json")
    for kw, match in [
        ({"width": 0}, "width"), ({"kind": "x"}, "kind"), ({"lr_decay": 1.5}, "lr_decay"),
        ({"npoints": (64, 128)}, "npoints"), ({"loss_weights": (1, 1)}, "loss_weights"),
        ({"val_fraction": 0.9}, "val_fraction"), ({"batch_size": 0}, "batch_size"), ({"backbones": 3}, "backbones"),
        ({"kind": "direct_voting", "backbones": 2}, "backbones"), ({"seed": -1}, "seed"),
        ({"pose_start_step": -1}, "pose_start_step"), ({"pose_start_step": 1.5}, "pose_start_step"),
    ]:
        with pytest.raises(ValueError, match=match):
            TrainConfig(**kw)


def test_training_arrays_hold_consistent_targets(tiny_arrays, prismatic_arrays):
    a = tiny_arrays
    assert a.points.shape == (4, 64, 3) and a.num_parts == 2 and a.revolute.tolist() == [True]
    # NAOCS = scale * NPCS + translation: the NAOCS joint targets hold for the reconstructed points.
    naocs = a.scale[..., None] * a.npcs + a.translation
    assoc = a.association > 0
    foot = naocs + a.joint[..., 6:7] * a.joint[..., 3:6]
    axis = a.joint[..., :3]
    # every foot point of one frame lies on one line of direction `axis`
    f = 0
    sel = assoc[f]
    d = foot[f][sel] - foot[f][sel][0]
    off = d - (d @ axis[f][sel][0])[:, None] * axis[f][sel][0]
    assert np.abs(off).max() < 1e-4
    assert np.all(a.joint_mask[~assoc] == 0) and np.all(a.joint_mask[assoc] == 1)
    # prismatic joints supervise the axis only
    p = prismatic_arrays
    assert not p.revolute.any()
    m = p.joint_mask[p.association > 0]
    assert np.all(m[:, :3] == 1) and np.all(m[:, 3:] == 0)
    # camera-frame joint vectors: unit axes on associated points
    np.testing.assert_allclose(np.linalg.norm(a.joint_cam[assoc][:, :3], axis=1), 1, atol=1e-5)


def test_arrays_save_load_and_split(tmp_path, tiny_arrays):
    tiny_arrays.save(tmp_path / "a.npz")
    b = TrainingArrays.load(tmp_path / "a.npz")
    np.testing.assert_array_equal(b.npcs, tiny_arrays.npcs)
    assert b.num_parts == tiny_arrays.num_parts
    train, val = split_by_instance(tiny_arrays, 0.5, seed=0)
    assert len(train) + len(val) == len(tiny_arrays)
    assert not set(train.instance.tolist()) & set(val.instance.tolist())
    assert split_by_instance(tiny_arrays, 0.0, seed=0)[1] is None
    base = trivial_baselines(tiny_arrays)
    assert 0.5 <= base["seg_acc_majority"] <= 1


def test_tiny_model_overfits_a_handful_of_frames(tiny_arrays, tiny_config):
    trainer = Trainer(tiny_config, tiny_arrays, progress=False)
    losses = [s["total"] for s in trainer.fit()]
    assert np.mean(losses[-5:]) < losses[0] / 10
    row = trainer.record()
    assert row["step"] == tiny_config.max_steps


def test_pose_term_joins_the_training_loss_at_pose_start_step(tiny_arrays, tiny_config):
    config = dataclasses.replace(tiny_config, pose_weight=2.0, pose_start_step=3, max_steps=5)
    losses = Trainer(config, tiny_arrays, progress=False).fit()
    assert ["pose" in s for s in losses] == [False, False, False, True, True]
    late = losses[3]
    assert late["total"] > 2.0 * late["pose"] > 0  # the weighted term is part of the total


def test_history_row_is_measured_apart_from_writing(tmp_path, tiny_arrays, tiny_config):
    """Scenario: measuring a row writes nothing and resets the running losses; the row's flat form is the
    CSV row (train_/val_ prefixes, pose keys as they are) and the CSV takes the union of the rows' columns."""
    trainer = Trainer(dataclasses.replace(tiny_config, max_steps=2), tiny_arrays, tiny_arrays, tmp_path / "run", progress=False)
    trainer.train_step()
    row = trainer.measure()
    assert isinstance(row, HistoryRow) and row.step == 1 and set(row.train) >= {"total"} and "total" in row.val
    assert trainer.history == [] and not (tmp_path / "run" / "history.csv").exists() and trainer._acc_n == 0
    with pytest.raises(dataclasses.FrozenInstanceError):
        row.step = 2
    with pytest.raises(TypeError):
        row.val["total"] = 0.0
    flat = HistoryRow(step=3, elapsed_s=1.5, lr=0.1, train={"total": 2.0}, val={"total": 1.0}, pose={"pose_score": 4.0}).to_dict()
    assert flat == {"step": 3, "elapsed_s": 1.5, "lr": 0.1, "train_total": 2.0, "val_total": 1.0, "pose_score": 4.0}
    assert HistoryRow(step=3, elapsed_s=0.0, lr=0.1, val={"total": 1.0}).selection_score(pose=False) == 1.0
    assert HistoryRow(step=3, elapsed_s=0.0, lr=0.1, val={"total": 1.0}).selection_score(pose=True) is None
    write_history_csv([{"step": 1, "a": 1.0}, {"step": 2, "b": 2.0}], tmp_path / "h.csv")
    assert (tmp_path / "h.csv").read_text().splitlines() == ["step,a,b", "1,1.0,", "2,,2.0"]


def test_init_weights_starts_from_a_trained_network_and_refuses_another_structure(tmp_path, tiny_arrays, prismatic_arrays,
                                                                                 tiny_config):
    cfg = dataclasses.replace(tiny_config, max_steps=3, checkpoint_every=3)
    trained = Trainer(cfg, tiny_arrays, None, tmp_path / "a", progress=False)
    trained.fit()
    started = Trainer(dataclasses.replace(cfg, init_weights=str(tmp_path / "a" / "last.pt"), seed=7), tiny_arrays,
                      progress=False)
    fresh = Trainer(dataclasses.replace(cfg, seed=7), tiny_arrays, progress=False)
    for name, p in trained.model.state_dict().items():
        torch.testing.assert_close(started.model.state_dict()[name], p)
    assert any(not torch.equal(fresh.model.state_dict()[n], p) for n, p in trained.model.state_dict().items())
    assert started.step == 0 and started.init_sha256 is not None
    with pytest.raises(ValueError, match="init_weights.*parts"):
        Trainer(dataclasses.replace(cfg, init_weights=str(tmp_path / "a" / "last.pt")), prismatic_arrays, progress=False)
    with pytest.raises(ValueError, match="init_weights.*network"):
        Trainer(dataclasses.replace(cfg, width=0.25, init_weights=str(tmp_path / "a" / "last.pt")), tiny_arrays,
                progress=False)
    # a network without input normals starts one with them: its weights, the normals' at zero
    grown = Trainer(dataclasses.replace(cfg, input_normals=True, init_weights=str(tmp_path / "a" / "last.pt")), tiny_arrays,
                    progress=False).model.state_dict()
    w_plain, w_grown = trained.model.state_dict()["backbone.sa1.mlp.0.weight"], grown["backbone.sa1.mlp.0.weight"]
    assert torch.count_nonzero(w_grown[:, 3:6]) == 0
    torch.testing.assert_close(torch.cat([w_grown[:, :3], w_grown[:, 6:]], dim=1), w_plain)
    torch.testing.assert_close(grown["backbone.sa2.mlp.0.weight"], trained.model.state_dict()["backbone.sa2.mlp.0.weight"])
    # another structure with init_match "matching": the backbone copied, the part-sized heads start afresh
    other = Trainer(dataclasses.replace(cfg, init_weights=str(tmp_path / "a" / "last.pt"), init_match="matching"),
                    prismatic_arrays, progress=False)
    theirs, ours = trained.model.state_dict(), other.model.state_dict()
    same = [n for n in ours if n in theirs and ours[n].shape == theirs[n].shape]
    assert any(n.startswith("backbone.") for n in same) and len(same) < len(ours)
    for n in same:
        torch.testing.assert_close(ours[n], theirs[n])
    assert other.init_record["copied_parameters"] == len(same) and other.init_record["parameters"] == len(ours)
    with pytest.raises(ValueError, match="init_match"):
        dataclasses.replace(cfg, init_match="some")


def test_fine_tuned_weights_keep_their_parent_and_its_training_time(tmp_path, tiny_arrays, tiny_config):
    from ancsh.cli.training import copy_training_log
    from ancsh.learned.network.weights import export_weights, load_network, training_seconds
    from ancsh.outputs import file_sha256

    cfg = dataclasses.replace(tiny_config, max_steps=3, checkpoint_every=3, val_every=3)
    parent = Trainer(cfg, tiny_arrays, tiny_arrays, tmp_path / "a", progress=False)
    parent.fit()
    parent_file = export_weights(tmp_path / "a" / "last.pt", tmp_path / "w" / "parent.pt")
    copy_training_log(tmp_path / "a", parent_file, {})
    parent_sha = file_sha256(parent_file)
    assert load_network(parent_file).lineage is None
    assert training_seconds(parent_file) == pytest.approx(parent.elapsed_s, abs=0.1)

    child_cfg = dataclasses.replace(cfg, init_weights=str(parent_file), max_steps=2, checkpoint_every=2)
    child = Trainer(child_cfg, tiny_arrays, tiny_arrays, tmp_path / "b", progress=False)
    child.fit()
    # the parent file is replaced after the run started: a resumed run still names the original
    export_weights(tmp_path / "b" / "last.pt", parent_file)
    assert file_sha256(parent_file) != parent_sha
    resumed = Trainer(dataclasses.replace(child_cfg, max_steps=4), tiny_arrays, tiny_arrays, tmp_path / "b", progress=False)
    resumed.load_checkpoint(tmp_path / "b" / "last.pt")
    resumed.fit()
    child_file = export_weights(tmp_path / "b" / "last.pt", tmp_path / "w" / "child.pt")
    copy_training_log(tmp_path / "b", child_file, {})
    lineage = load_network(child_file).lineage
    assert lineage["sha256"] == parent_sha and lineage["step"] == 3
    assert lineage["train_s"] == pytest.approx(parent.elapsed_s, abs=0.1)
    assert training_seconds(child_file) == pytest.approx(resumed.elapsed_s + parent.elapsed_s, abs=0.2)


def test_checkpoint_round_trip_and_resume_repeat_the_same_steps(tmp_path, tiny_arrays, tiny_config):
    cfg = dataclasses.replace(tiny_config, max_steps=6, batch_size=2, checkpoint_every=3)
    straight = Trainer(cfg, tiny_arrays, tiny_arrays, tmp_path / "a", progress=False)
    ref = [s["total"] for s in straight.fit()]

    first = Trainer(cfg, tiny_arrays, tiny_arrays, tmp_path / "b", progress=False)
    part1 = [s["total"] for s in first.fit(max_steps=3)]
    resumed = Trainer(cfg, tiny_arrays, tiny_arrays, tmp_path / "b", progress=False)
    resumed.load_checkpoint(tmp_path / "b" / "last.pt")
    assert resumed.step == 3
    part2 = [s["total"] for s in resumed.fit()]
    np.testing.assert_allclose(part1 + part2, ref, rtol=1e-5)
    assert [r["step"] for r in resumed.history] == [3, 6]
    for name in ("history.csv", "curves.png", "config.json", "best.pt", "last.pt"):
        assert (tmp_path / "b" / name).is_file()
    other = Trainer(dataclasses.replace(cfg, width=0.25), tiny_arrays, progress=False)
    with pytest.raises(ValueError, match="width"):
        other.load_checkpoint(tmp_path / "b" / "last.pt")


def test_trainer_rejects_mismatched_inputs(tiny_arrays, tiny_config):
    with pytest.raises(ValueError, match="num_points"):
        Trainer(dataclasses.replace(tiny_config, num_points=128), tiny_arrays, progress=False)
    with pytest.raises(ValueError, match="config"):
        Trainer({"width": 1}, tiny_arrays, progress=False)


def _pose_frames(seed=11, count=2):
    from ancsh.model.canonical import ancsh_ground_truth
    from ancsh.model.synthetic import random_articulated_model, sample_frame
    from ancsh.solvers.types import Observation

    rng = np.random.default_rng(seed)
    model = random_articulated_model(rng, num_parts=2, joint_types="revolute")
    frames = []
    for _ in range(count):
        fr = sample_frame(model, rng, points_per_part=40)
        frames.append((Observation(fr.points_cam), ancsh_ground_truth(model, fr.q, fr.T_cam_base, fr.points_cam, fr.part_labels)))
    return frames


def test_pose_validation_runs_the_full_pipeline_and_reports_failures_as_data(tiny_arrays, tiny_config):
    """Scenario: an untrained network on two frames of a two-part revolute object: the provider's output
    goes through exact_reduced fits; fits that fail (a part without points) are counted, not raised."""
    from ancsh.learned.training.train import PoseValidation

    trainer = Trainer(dataclasses.replace(tiny_config, max_steps=2), tiny_arrays, progress=False)
    scores = PoseValidation(_pose_frames()).evaluate(trainer.pose_network())
    assert set(scores) == {"pose_failures", "pose_rot_deg", "pose_axis_deg", "pose_state_err", "pose_score"}
    assert 0 <= scores["pose_failures"] <= 2
    if scores["pose_failures"] < 2:
        assert scores["pose_score"] == pytest.approx(scores["pose_rot_deg"] + scores["pose_axis_deg"])
    else:
        assert scores["pose_score"] == np.inf
    with pytest.raises(ValueError, match="frames"):
        PoseValidation([])


def test_best_checkpoint_follows_the_pose_score_not_the_validation_loss(tmp_path, tiny_arrays, tiny_config):
    """Scenario: a pose validation whose score is best at the first of three validations; best.pt holds
    that step whatever the validation loss does."""
    from ancsh.learned.training.train import PoseValidation
    from ancsh.learned.network.weights import load_network

    class Scripted(PoseValidation):
        def __init__(self, scores):
            super().__init__(_pose_frames(count=1))
            self.scores = list(scores)

        def evaluate(self, network):
            assert network.model is trainer.model
            return {"pose_score": self.scores.pop(0)}

    cfg = dataclasses.replace(tiny_config, max_steps=6, val_every=2, pose_val_every=2)
    trainer = Trainer(cfg, tiny_arrays, tiny_arrays, tmp_path / "run", progress=False, pose_val=Scripted([3.0, 5.0, 4.0]))
    trainer.fit()
    assert [r["pose_score"] for r in trainer.history] == [3.0, 5.0, 4.0]
    assert trainer.model.training and trainer.best_val == 3.0
    assert load_network(tmp_path / "run" / "best.pt").step == 2
    with pytest.raises(ValueError, match="pose_val"):
        Trainer(cfg, tiny_arrays, progress=False, pose_val=[])
    with pytest.raises(ValueError, match="pose_val_every"):
        TrainConfig(pose_val_every=-1)


def test_ablation_report_compares_pose_validation_at_equal_steps(tmp_path, tiny_config):
    """`bench learned-ablation`: each run's pose-validation history, side by side by step."""
    from ancsh.studies.ablation import ablation, write_ablation_report

    for name, scores in (("a", {500: 12.5, 1000: 10.25}), ("b", {500: 12.5, 1500: 30.0})):
        run = tmp_path / name
        run.mkdir()
        dataclasses.replace(tiny_config, pose_weight=0.0 if name == "a" else 10.0).to_json(run / "config.json")
        rows = [HistoryRow(step=s, elapsed_s=float(s), lr=1e-3, val={"npcs_err": 0.05}, pose={"pose_score": v}).to_dict()
                for s, v in scores.items()]
        write_history_csv(rows, run / "history.csv")
    result = ablation({"a": tmp_path / "a", "b": tmp_path / "b"}, frames=1)  # no checkpoints: histories only
    assert result["rows"] == [] and [c["step"] for c in result["curves"]["b"]] == [500, 1500]
    text = write_ablation_report(result, tmp_path / "abl.md", command="test").read_text()
    assert "| 1000 | 10.25 (0.050) |  |" in text and "| 1500 |  | 30.00 (0.050) |" in text


def test_ablation_baseline_row_is_the_start_weights_on_the_same_frames(tmp_path, tiny_config):
    """`bench learned-ablation --baseline`: the weights a fine-tune started from, first, on the runs' test frames."""
    from ancsh.studies.ablation import ablation, write_ablation_report
    from ancsh.studies.table1 import evaluate_category, summarize

    run = tmp_path / "a"
    run.mkdir()
    dataclasses.replace(tiny_config, category="laptop").to_json(run / "config.json")
    write_history_csv([HistoryRow(step=5, elapsed_s=5.0, lr=1e-3, val={"npcs_err": 0.05}).to_dict()], run / "history.csv")
    result = ablation({"a": run}, frames=2, seed=3, baseline="builtin")
    [start] = result["rows"]  # the run has no checkpoint: the baseline row only
    ref = summarize(evaluate_category("laptop", frames=2, methods=("exact_reduced",), seed=3, progress=False))
    assert start["run"] == "start" and start["checkpoint"] == "shipped" and start["trained_steps"] is None
    assert start["rot_deg"] == ref["methods"]["exact_reduced"]["rot_deg"]["mean"]
    text = write_ablation_report(result, tmp_path / "abl.md", command="test").read_text()
    assert "| start | - | - | shipped (" in text
    with pytest.raises(ValueError, match="baseline"):
        ablation({"a": run}, frames=1, baseline=str(tmp_path / "missing.pt"))
