"""``ancsh train`` guards: Ctrl-C checkpoints and exits cleanly, a full disk while checkpointing says so and
keeps the previous checkpoint, shards or runs of another category are refused."""

import errno
import json

import pytest
import torch

from ancsh.cli import main
from ancsh.learned.training.train import Trainer

CFG = {"num_points": 64, "width": 0.125, "npoints": [32, 8], "nsamples": [8, 8], "batch_size": 2,
       "max_steps": 4, "val_every": 2, "checkpoint_every": 100, "val_fraction": 0.2}


@pytest.fixture(scope="module")
def shards(tmp_path_factory):
    from ancsh.data.generate import GenerationConfig, generate_dataset
    from ancsh.data.render import Intrinsics

    out = {}
    for category in ("laptop", "eyeglasses"):
        folder = tmp_path_factory.mktemp(category)
        generate_dataset(GenerationConfig(category=category, split="train", shard_size=3, num_points=64,
                                          intrinsics=Intrinsics.kinect(160, 120), min_part_pixels=5), 6, folder,
                         progress=False)
        out[category] = folder
    return out


def _args(tmp_path, data, run, category="laptop"):
    (tmp_path / "c.json").write_text(json.dumps(CFG))
    return ["train", "--category", category, "--config", str(tmp_path / "c.json"), "--data", str(data),
            "--out", str(run), "--no-progress"]


def test_ctrl_c_saves_a_checkpoint_and_exits_130(tmp_path, shards, monkeypatch, capsys):
    step = Trainer.train_step

    def interrupted(self):
        if self.step == 2:
            raise KeyboardInterrupt
        return step(self)

    monkeypatch.setattr(Trainer, "train_step", interrupted)
    run = tmp_path / "run"
    assert main(_args(tmp_path, shards["laptop"], run)) == 130
    assert "--resume" in capsys.readouterr().err
    assert torch.load(run / "last.pt", weights_only=True)["step"] == 2


def test_full_disk_while_checkpointing_says_no_space_and_keeps_the_old_checkpoint(tmp_path, shards, monkeypatch, capsys):
    run = tmp_path / "run"
    assert main(_args(tmp_path, shards["laptop"], run)) == 0
    before = (run / "last.pt").read_bytes()

    import os

    import ancsh.outputs as outputs

    real_fdopen = os.fdopen

    class FullDisk:  # the checkpoint's file, on a disk with no space left
        def __init__(self, f):
            self.f = f

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

        def write(self, data):
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(outputs.os, "fdopen", lambda fd, mode="r", *a, **k: FullDisk(real_fdopen(fd, mode, *a, **k)))
    code = main(["train", "--category", "laptop", "--resume", "--max-steps", "6", "--data", str(shards["laptop"]),
                 "--out", str(run), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and "No space left on device" in err and "checkpoint" in err and "Traceback" not in err
    assert (run / "last.pt").read_bytes() == before and not list(run.glob("*.tmp")) and not list(run.glob(".*.tmp"))


def test_shards_of_another_category_are_refused(tmp_path, shards, capsys):
    assert main(_args(tmp_path, shards["eyeglasses"], tmp_path / "run")) == 2
    err = capsys.readouterr().err
    assert "--data" in err and "'eyeglasses'" in err and not (tmp_path / "run").exists()


def test_resume_with_another_category_is_refused_and_keeps_the_run(tmp_path, shards, capsys):
    run = tmp_path / "run"
    assert main(_args(tmp_path, shards["laptop"], run)) == 0
    config = (run / "config.json").read_text()
    code = main(["train", "--category", "eyeglasses", "--resume", "--data", str(shards["eyeglasses"]), "--out", str(run),
                 "--no-progress"])
    assert code == 2 and "--category" in capsys.readouterr().err
    assert (run / "config.json").read_text() == config


def test_a_damaged_shard_is_named_and_left_out(tmp_path, shards, capsys):
    import shutil

    data = tmp_path / "data"
    shutil.copytree(shards["laptop"], data)
    (data / "zz_damaged.h5").write_bytes(b"not hdf5")
    assert main(_args(tmp_path, data, tmp_path / "run")) == 0
    captured = capsys.readouterr()
    assert "zz_damaged.h5" in captured.err and "training frames" in captured.out
    for shard in data.glob("*.h5"):
        shard.write_bytes(b"x")
    assert main(_args(tmp_path, data, tmp_path / "run2")) == 2
    assert "no intact shard" in capsys.readouterr().err


def test_exporting_weights_to_a_folder_that_refuses_writes_is_an_os_error_naming_the_file(tmp_path, shards, monkeypatch):
    import ancsh.outputs as outputs
    from ancsh.learned.network.weights import export_weights

    run = tmp_path / "run"
    assert main(_args(tmp_path, shards["laptop"], run)) == 0

    def read_only(*a, **k):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(outputs.tempfile, "mkstemp", read_only)
    with pytest.raises(OSError, match=r"could not write the weights .*w.pt: Read-only file system") as exc:
        export_weights(run / "last.pt", tmp_path / "ro" / "w.pt")
    assert exc.value.errno == errno.EROFS


def test_a_cache_holding_python_objects_is_refused_naming_the_file(tmp_path):
    """``train --resume`` on a run folder whose ``.npz`` holds an object array: the message names the file."""
    import numpy as np

    from ancsh.learned.training.data import TrainingArrays, read_npz

    bad = tmp_path / "arrays.npz"
    np.savez(bad, points=np.array([{"a": 1}], dtype=object))
    with pytest.raises(ValueError, match=r"arrays.npz: not a training-array cache of ancsh .*delete it to rebuild it"):
        TrainingArrays.load(bad)
    with pytest.raises(ValueError, match=r"arrays.npz: not a neighbourhood cache"):
        read_npz(bad, "neighbourhood cache")
    other = tmp_path / "other.npz"
    np.savez(other, something=np.zeros(3))
    with pytest.raises(ValueError, match=r"other.npz: not a training-array cache of ancsh \(no \["):
        TrainingArrays.load(other)
