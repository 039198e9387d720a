"""What is loaded cannot run code: weights files and checkpoints are read with ``weights_only=True``;
bad files are refused with an error naming the option and the file, never a traceback."""

import dataclasses
import os

import pytest
import torch

from ancsh.cli import main
from ancsh.learned.training.train import Trainer
from ancsh.learned.network.weights import WEIGHTS_DIR, available_weights, load_network, read_torch_file


class _Payload:
    """Unpickling this would create the file ``target`` (it must never happen)."""

    def __init__(self, target):
        self.target = str(target)

    def __reduce__(self):
        return (os.mkdir, (self.target,))


@pytest.fixture
def crafted(tmp_path):
    """A ``.pt`` that looks like a weights file but whose pickle calls ``os.mkdir`` when loaded unsafely."""
    target = tmp_path / "pwned"
    path = tmp_path / "evil.pt"
    torch.save({"format": 1, "config": {}, "num_parts": 2, "revolute": [True], "state_dict": _Payload(target)}, path)
    return path, target


def test_crafted_pickle_weights_are_refused_and_run_nothing(crafted, tmp_path, capsys):
    path, target = crafted
    with pytest.raises(ValueError, match=r"weights: .*evil.pt is not a plain weights file.*refused"):
        load_network(path)
    assert not target.exists()
    _depth_files(tmp_path)
    code = main(["predict", "--depth", str(tmp_path / "d.npy"), "--intrinsics", str(tmp_path / "K.json"),
                 "--category", "laptop", "--weights", str(path)])
    assert code == 2 and not target.exists()


def test_crafted_checkpoint_is_refused_on_resume(crafted, tiny_arrays, tiny_config):
    path, target = crafted
    trainer = Trainer(tiny_config, tiny_arrays, progress=False)
    with pytest.raises(ValueError, match="--resume: .*refused"):
        trainer.load_checkpoint(path)
    assert not target.exists()


def test_truncated_and_garbage_checkpoints_get_a_clear_error(tmp_path, tiny_arrays, tiny_config):
    cfg = dataclasses.replace(tiny_config, max_steps=1)
    trainer = Trainer(cfg, tiny_arrays, None, tmp_path / "run", progress=False)
    good = trainer.save_checkpoint(tmp_path / "run" / "last.pt").read_bytes()
    (tmp_path / "truncated.pt").write_bytes(good[: len(good) // 2])
    with pytest.raises(ValueError, match=r"--resume: .*truncated.pt is not a readable torch file"):
        trainer.load_checkpoint(tmp_path / "truncated.pt")
    (tmp_path / "garbage.pt").write_bytes(b"step=12\nnot a checkpoint\n" * 10)
    with pytest.raises(ValueError, match=r"--resume: .*garbage.pt"):
        trainer.load_checkpoint(tmp_path / "garbage.pt")
    torch.save({"config": cfg.to_dict(), "step": "twelve"}, tmp_path / "partial.pt")
    with pytest.raises(ValueError, match=r"--resume: .*partial.pt lacks the entries"):
        trainer.load_checkpoint(tmp_path / "partial.pt")
    with pytest.raises(ValueError, match=r"weights: .*garbage.pt"):
        load_network(tmp_path / "garbage.pt")


def _depth_files(folder):
    import json

    import numpy as np

    np.save(folder / "d.npy", np.full((8, 8), 1.0))
    (folder / "K.json").write_text(json.dumps({"fx": 8.0, "fy": 8.0, "cx": 4.0, "cy": 4.0, "width": 8, "height": 8}))


def test_weights_option_with_a_non_checkpoint_names_the_file(tmp_path, capsys):
    _depth_files(tmp_path)
    (tmp_path / "notes.pt").write_text("these are my notes\n")
    code = main(["predict", "--depth", str(tmp_path / "d.npy"), "--intrinsics", str(tmp_path / "K.json"),
                 "--category", "laptop", "--weights", str(tmp_path / "notes.pt")])
    err = capsys.readouterr().err
    assert code == 2 and "notes.pt" in err and "Traceback" not in err


@pytest.mark.parametrize("name", available_weights())
def test_shipped_weights_load_safely(name):
    data = read_torch_file(WEIGHTS_DIR / f"{name}.pt", argument="weights", required=("state_dict", "config"))
    assert all(isinstance(v, torch.Tensor) for v in data["state_dict"].values())
