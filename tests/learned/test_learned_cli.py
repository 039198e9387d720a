"""``ancsh train`` end to end on a few rendered frames, resume, export; the provider on real frames."""

import json
import subprocess
import sys

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.solvers.types import Correspondences, Observation


def test_help_does_not_import_torch():
    code = "import sys; from ancsh.cli import build_parser; build_parser(); print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


@pytest.fixture(scope="module")
def laptop_shards(tmp_path_factory):
    from ancsh.data.generate import GenerationConfig, generate_dataset

    out = tmp_path_factory.mktemp("laptop")
    generate_dataset(GenerationConfig(category="laptop", split="train", shard_size=3, num_points=64), 6, out, progress=False)
    return out


@pytest.mark.slow
def test_train_command_trains_resumes_and_exports(tmp_path, laptop_shards, capsys):
    cfg = {"num_points": 64, "width": 0.125, "npoints": [32, 8], "nsamples": [8, 8], "batch_size": 2,
           "max_steps": 2, "val_every": 2, "checkpoint_every": 2, "val_fraction": 0.2}
    (tmp_path / "c.json").write_text(json.dumps(cfg))
    run = tmp_path / "run"
    args = ["train", "--category", "laptop", "--config", str(tmp_path / "c.json"), "--data", str(laptop_shards),
            "--out", str(run), "--no-progress"]
    assert main(args) == 0
    assert main(args) == 2  # refuses to overwrite a run without --resume
    assert "--resume" in capsys.readouterr().err
    weights = tmp_path / "w.pt"
    assert main(["train", "--category", "laptop", "--resume", "--max-steps", "3", "--data", str(laptop_shards),
                 "--out", str(run), "--no-progress", "--test-data", str(laptop_shards), "--export", str(weights)]) == 0
    rows = (run / "history.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["2", "3"]
    metrics = json.loads((run / "test_metrics.json").read_text())
    assert {"seg_acc", "npcs_err", "seg_acc_majority", "npcs_err_zero"} <= set(metrics)
    assert weights.is_file()
    for suffix in ("_config.json", "_history.csv", "_curves.png", "_test_metrics.json"):
        assert (tmp_path / f"w{suffix}").is_file()


@pytest.mark.slow
def test_provider_on_rendered_frames_matches_the_ground_truth_structure(tmp_path, laptop_shards):
    from ancsh.data.dataset import read_frames
    from ancsh.learned.network.config import TrainConfig
    from ancsh.learned.training.data import arrays_from_dataset
    from ancsh.learned.inference.provider import LearnedProvider
    from ancsh.learned.training.train import Trainer

    arrays = arrays_from_dataset(laptop_shards)
    cfg = TrainConfig(num_points=64, width=0.125, npoints=(32, 8), nsamples=(8, 8))
    ck = Trainer(cfg, arrays, None, tmp_path, progress=False).save_checkpoint(tmp_path / "last.pt")
    provider = LearnedProvider(ck)
    frame = read_frames(laptop_shards)[0]
    corr = provider.correspond(Observation(frame.points))
    assert corr.structure_key() == Correspondences.from_ground_truth(frame.gt).structure_key()
    assert corr.num_points == len(frame.points)
    assert np.all(np.isfinite(corr.joint_pivots_naocs))


@pytest.mark.slow
def test_export_confirms_the_checkpoints_on_all_validation_frames(tmp_path, laptop_shards, capsys):
    from ancsh.learned.network.config import TrainConfig
    from ancsh.learned.training.data import arrays_from_dataset
    from ancsh.learned.training.train import PoseValidation, split_by_instance
    from ancsh.learned.network.weights import load_network

    cfg = {"num_points": 64, "width": 0.125, "npoints": [32, 8], "nsamples": [8, 8], "batch_size": 2, "max_steps": 2,
           "val_every": 1, "checkpoint_every": 1, "val_fraction": 0.4, "seed": 4}
    (tmp_path / "c.json").write_text(json.dumps(cfg))
    run = tmp_path / "run"
    assert main(["train", "--category", "laptop", "--config", str(tmp_path / "c.json"), "--data", str(laptop_shards),
                 "--out", str(run), "--no-progress"]) == 0
    weights = tmp_path / "w.pt"
    capsys.readouterr()
    assert main(["export", "--run", str(run), "--data", str(laptop_shards), "--out", str(weights),
                 "--test-data", str(laptop_shards)]) == 0
    assert "<- export" in capsys.readouterr().out
    selection = json.loads((tmp_path / "w_test_metrics.json").read_text())["selection"]
    rows = selection["candidates"]
    assert [r["checkpoint"] for r in rows] == [str(run / "best.pt"), str(run / "last.pt")]
    # every frame of the run's validation instances, split as in training (the config's seed)
    config = TrainConfig.from_json(run / "config.json")
    arrays = arrays_from_dataset(laptop_shards, config.num_points, seed=config.seed)
    _, val = split_by_instance(arrays, config.val_fraction, config.seed)
    frames = np.flatnonzero(np.isin(arrays.instance, np.unique(val.instance)))
    assert 0 < len(frames) < len(arrays) and all(r["frames"] == len(frames) for r in rows)
    # the scores are those of PoseValidation on exactly those frames, and the lower one is exported
    last = load_network(run / "last.pt")
    expected = PoseValidation.from_dataset(laptop_shards, frames, seed=config.seed).evaluate(last)
    assert rows[1]["pose_score"] == pytest.approx(expected["pose_score"])
    chosen = min(rows, key=lambda r: r["pose_score"])
    assert selection["chosen"] == chosen["checkpoint"]
    shipped = load_network(weights)
    assert shipped.step == chosen["step"]
    assert shipped.metrics["selection"]["chosen"] == chosen["checkpoint"] and "seg_acc" in shipped.metrics
    assert json.loads((run / "selection.json").read_text())["chosen"] == chosen["checkpoint"]
    # a weights file among the candidates is scored like a checkpoint; when it wins no weights are written, but the
    # run's selection.json records its scores
    again = tmp_path / "again.pt"
    assert main(["export", "--run", str(run), "--data", str(laptop_shards), "--out", str(again),
                 "--checkpoints", str(weights)]) == 0
    assert "nothing exported" in capsys.readouterr().out and not again.exists()
    lost = json.loads((run / "selection.json").read_text())
    assert lost["chosen"] == str(weights) and [r["checkpoint"] for r in lost["candidates"]] == [str(weights)]
    assert "--checkpoints" in lost["command"]
    assert main(["export", "--run", str(tmp_path / "missing"), "--data", str(laptop_shards), "--out", str(weights)]) == 2
    assert "--run" in capsys.readouterr().err
    # an existing export is kept without --overwrite and replaced with it
    before = weights.read_bytes()
    args = ["export", "--run", str(run), "--data", str(laptop_shards), "--out", str(weights), "--checkpoints",
            str(run / "last.pt")]
    assert main(args) == 2 and weights.read_bytes() == before
    assert main([*args, "--overwrite"]) == 0
    assert load_network(weights).step == load_network(run / "last.pt").step
    assert json.loads((tmp_path / "w_test_metrics.json").read_text())["selection"]["chosen"] == str(run / "last.pt")


def test_export_keeps_an_existing_weights_file_without_overwrite(tmp_path, capsys):
    """``ancsh export --out`` naming an existing weights file (or a file beside it that the export writes) refuses
    before any scoring, names ``--out`` and ``--overwrite``, and leaves every file as it was."""
    from ancsh.learned.network.config import TrainConfig

    run = tmp_path / "run"
    run.mkdir()
    TrainConfig().to_json(run / "config.json")
    (run / "history.csv").write_text("step\n1\n")
    weights = tmp_path / "w.pt"
    weights.write_bytes(b"shipped weights")
    args = ["export", "--run", str(run), "--data", str(tmp_path / "no_shards"), "--out", str(weights)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"--out: {weights}" in err and "--overwrite" in err and "Traceback" not in err
    assert weights.read_bytes() == b"shipped weights"
    weights.unlink()
    (tmp_path / "w_history.csv").write_text("an earlier export's history\n")  # a file the export would replace
    assert main(args) == 2
    assert f"--out: {tmp_path / 'w_history.csv'}" in capsys.readouterr().err
    assert (tmp_path / "w_history.csv").read_text() == "an earlier export's history\n" and not weights.exists()
    assert main([*args, "--overwrite"]) == 2  # past the check: the run's missing checkpoints are what stops it now
    assert "--run: " in capsys.readouterr().err


def test_validation_frame_indices_spreads_evenly_over_the_validation_instances():
    from ancsh.learned.training.select import choose, validation_frame_indices

    instance = np.array([0, 1, 1, 2, 0, 1, 2, 2, 1])
    assert validation_frame_indices(instance, [1]).tolist() == [1, 2, 5, 8]
    assert validation_frame_indices(instance, [1, 2], 3).tolist() == [1, 5, 8]
    assert validation_frame_indices(instance, [1], 10).tolist() == [1, 2, 5, 8]
    with pytest.raises(ValueError, match="count"):
        validation_frame_indices(instance, [1], 0)
    rows = [{"pose_score": 3.0}, {"pose_score": 2.0}, {"pose_score": 2.0}]
    assert choose(rows) is rows[1]
