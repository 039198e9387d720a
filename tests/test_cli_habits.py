"""Command-line habits: an example in every --help, no overwriting of committed results by default,
clear errors (naming the option or file) instead of tracebacks, non-zero exits on failure."""

import argparse
import errno
import json

import numpy as np
import pytest

from ancsh.cli import build_parser, main
from ancsh.outputs import DOCS_RESULTS, RESULTS_ROOT, fresh_output_dir, report_path


def _commands(parser, prefix=()):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield (*prefix, name), sub
                yield from _commands(sub, (*prefix, name))


def test_every_command_help_shows_an_example():
    commands = list(_commands(build_parser()))
    assert len(commands) >= 12
    for name, sub in commands:
        assert "example:\n  ancsh " in sub.format_help(), " ".join(name)


@pytest.mark.parametrize("argv", [["evaluate", "--category", "laptop"], ["evaluate-cad"], ["bench", "fit"],
                                  ["bench", "uncertainty"]])
def test_report_commands_do_not_default_to_the_committed_results(argv):
    args = build_parser().parse_args(argv)
    assert args.out is None and args.update_docs is False


def test_report_paths_are_fresh_unless_docs_are_asked_for(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    a = report_path(None, update_docs=False, docs_name="cad_fitting.md", command="evaluate-cad")
    b = report_path(None, update_docs=False, docs_name="cad_fitting.md", command="evaluate-cad")
    assert a.parent != b.parent and a.parent.parent == b.parent.parent == RESULTS_ROOT and a.parent.is_dir()
    assert report_path(None, update_docs=True, docs_name="x.md", command="c") == DOCS_RESULTS / "x.md"
    assert report_path("mine.md", update_docs=True, docs_name="x.md", command="c").name == "mine.md"
    assert fresh_output_dir("evaluate-laptop").name.startswith("evaluate-laptop-")


@pytest.mark.slow
def test_evaluate_writes_a_fresh_folder_with_the_version(tmp_path, monkeypatch, capsys):
    from ancsh import __version__

    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", "--category", "laptop", "--frames", "1", "--formulations", "per_part", "--no-progress"]) == 0
    (folder,) = (tmp_path / RESULTS_ROOT).iterdir()
    assert folder.name.startswith("evaluate-laptop-") and not (tmp_path / "docs").exists()
    data = json.loads((folder / "laptop.json").read_text())
    assert data["ancsh_version"] == __version__ and len(data["settings"]["weights_sha256"]) == 64


@pytest.mark.parametrize("argv, option", [
    (["evaluate", "--category", "laptop", "--threads", "0"], "--threads"),
    (["evaluate", "--category", "laptop", "--time-limit-min", "0"], "--time-limit-min"),
    (["evaluate", "--category", "laptop", "--frames", "-1"], "--frames"),
    (["evaluate-cad", "--frames", "-1"], "--frames"),
    (["demo", "--frame", "-1", "--categories", "laptop"], "--frame"),
    (["bench", "render", "--width", "4", "--height", "4", "--frames", "1", "--categories", "laptop"], "--width"),
])
def test_bad_numbers_name_the_option(argv, option, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert option in err and "Traceback" not in err
    assert not (tmp_path / RESULTS_ROOT).exists()  # refused before anything was written


@pytest.mark.parametrize("value", ["0", "-1", "nan"])
def test_train_refuses_a_time_limit_that_is_not_positive(value, tmp_path, capsys):
    """It used to train a step and stop, silently."""
    with pytest.raises(SystemExit) as exc:
        main(["train", "--category", "laptop", "--data", str(tmp_path), "--out", str(tmp_path / "run"),
              "--time-limit-min", value])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--time-limit-min: expected a positive number" in err
    assert not (tmp_path / "run").exists()


@pytest.fixture
def depth_files(tmp_path):
    K = {"fx": 8.0, "fy": 8.0, "cx": 4.0, "cy": 3.0, "width": 8, "height": 6}
    (tmp_path / "K.json").write_text(json.dumps(K))
    np.save(tmp_path / "d.npy", np.full((6, 8), 1.0))
    return tmp_path


def test_bad_input_files_are_named(depth_files, capsys):
    d = depth_files
    base = ["predict", "--depth", str(d / "d.npy"), "--category", "laptop"]
    (d / "mask.png").write_text("not an image")
    assert main(base + ["--intrinsics", str(d / "K.json"), "--mask", str(d / "mask.png")]) == 2
    assert "mask: " in (err := capsys.readouterr().err) and "mask.png" in err and "Traceback" not in err
    (d / "K525.json").write_text(json.dumps({"fx": "525", "fy": 8.0, "cx": 4.0, "cy": 3.0, "width": 8, "height": 6}))
    assert main(base + ["--intrinsics", str(d / "K525.json")]) == 2
    assert "fx: expected a JSON number" in (err := capsys.readouterr().err) and "K525.json" in err
    (d / "broken.json").write_text('{"fx": 8.0,')
    urdf = d / "hinge.urdf"
    urdf.write_text(
        "<robot name='h'><link name='a'><visual><geometry><box size='.1 .1 .1'/></geometry></visual></link>"
        "<joint name='j' type='revolute'><parent link='a'/><child link='b'/><axis xyz='0 0 1'/>"
        "<limit lower='0' upper='1'/></joint>"
        "<link name='b'><visual><origin xyz='.1 0 0'/><geometry><box size='.1 .1 .1'/></geometry></visual></link></robot>")
    assert main(["fit-cad", "--urdf", str(urdf), "--depth", str(d / "d.npy"), "--intrinsics", str(d / "broken.json")]) == 2
    assert "broken.json" in (err := capsys.readouterr().err) and "not valid JSON" in err


def test_an_unwritable_out_is_a_clear_error(depth_files, capsys):
    d = depth_files
    (d / "file").write_text("x")
    code = main(["predict", "--depth", str(d / "d.npy"), "--intrinsics", str(d / "K.json"), "--category", "laptop",
                 "--no-isolate", "--out", str(d / "file" / "r.json")])
    err = capsys.readouterr().err
    assert code == 2 and "file" in err and "Traceback" not in err


def test_predict_outputs_replace_a_symlink_instead_of_writing_through_it(depth_files, capsys):
    """A symlinked --out / --png inside the output folder points at another folder's files: they stay untouched."""
    d = depth_files
    other = d / "other"
    other.mkdir()
    (other / "keep.json").write_text("keep")
    (other / "keep.png").write_text("keep")
    out = d / "out"
    out.mkdir()
    (out / "r.json").symlink_to(other / "keep.json")
    (out / "r.png").symlink_to(other / "keep.png")
    main(["predict", "--depth", str(d / "d.npy"), "--intrinsics", str(d / "K.json"), "--category", "laptop",
          "--no-isolate", "--out", str(out / "r.json"), "--png", str(out / "r.png")])
    assert (other / "keep.json").read_text() == "keep" and (other / "keep.png").read_text() == "keep"
    assert not (out / "r.json").is_symlink() and json.loads((out / "r.json").read_text())["category"] == "laptop"
    assert not (out / "r.png").is_symlink() and (out / "r.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("argv", [
    ["predict", "--depth", "d.npy", "--intrinsics", "K.json", "--category", "laptop"],
    ["track", "--depth", "frames", "--intrinsics", "K.json", "--category", "laptop"],
    ["evaluate", "--category", "laptop"],
    ["demo"],
    ["fit-cad", "--urdf", "x.urdf", "--depth", "d.npy", "--intrinsics", "K.json"],
    ["bench", "fit"],
    ["bench", "tracking"],
    ["bench", "uncertainty"],
])
def test_a_negative_seed_is_refused_naming_the_option(argv, capsys):
    """`track --seed -1` used to stop with numpy's "expected non-negative integer", naming no option."""
    with pytest.raises(SystemExit) as exc:
        main(argv + ["--seed", "-1"])
    assert exc.value.code == 2 and "--seed: expected a non-negative integer, got -1" in capsys.readouterr().err


def test_predict_refuses_weights_of_another_category(depth_files, capsys):
    """--category laptop with the drawer's network used to fit four parts and call them a laptop."""
    from ancsh.learned.inference.predict import predict_depth
    from ancsh.learned.network.weights import weights_path

    d = depth_files
    code = main(["predict", "--depth", str(d / "d.npy"), "--intrinsics", str(d / "K.json"), "--category", "laptop",
                 "--no-isolate", "--weights", str(weights_path("drawer")), "--out", str(d / "r.json")])
    err = capsys.readouterr().err
    assert code == 2 and "holds a drawer network, not a laptop one" in err and "Traceback" not in err
    assert not (d / "r.json").exists()
    with pytest.raises(ValueError, match="holds a drawer network, not a laptop one"):
        predict_depth(np.full((6, 8), 1.0), _intrinsics(d), "laptop", weights=weights_path("drawer"), isolate=False)


def test_evaluate_checks_the_real_split_before_the_procedural_one(tmp_path, monkeypatch, capsys):
    """A catalog without real test objects of the category used to fail only after the whole procedural run."""
    import ancsh.studies.table1 as table1

    catalog = tmp_path / "catalog.json"
    catalog.write_text(json.dumps({"version": 1, "command": "", "objects": [], "rejected": []}))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(table1, "evaluate_category", lambda *a, **k: pytest.fail("the procedural split was evaluated"))
    assert main(["evaluate", "--category", "laptop", "--frames", "2", "--real", str(catalog)]) == 2
    assert "--real: the catalog" in (err := capsys.readouterr().err) and "no real test object of 'laptop'" in err
    assert not (tmp_path / RESULTS_ROOT).exists()


def test_an_unwritable_picture_format_is_refused_before_the_fit(depth_files, monkeypatch, capsys):
    """--png p.xyz used to be refused only after the whole fit."""
    import ancsh.learned.inference.predict as predict

    d = depth_files
    monkeypatch.setattr(predict, "predict_depth", lambda *a, **k: pytest.fail("fitted before checking --png"))
    assert main(["predict", "--depth", str(d / "d.npy"), "--intrinsics", str(d / "K.json"), "--category", "laptop",
                 "--png", str(d / "p.xyz")]) == 2
    assert "--png: cannot write a .xyz picture" in (err := capsys.readouterr().err) and ".png" in err
    assert main(["fit-cad", "--urdf", str(d / "K.json"), "--depth", str(d / "d.npy"), "--intrinsics", str(d / "K.json"),
                 "--png", str(d / "p.xyz")]) == 2
    assert "--png: cannot write a .xyz picture" in capsys.readouterr().err


def test_track_refuses_zero_points(depth_files, capsys):
    """track --points 0 used to mark every frame lost."""
    with pytest.raises(SystemExit) as exc:
        main(["track", "--depth", str(depth_files), "--intrinsics", str(depth_files / "K.json"), "--category", "laptop",
              "--points", "0"])
    assert exc.value.code == 2 and "--points: expected a positive integer, got 0" in capsys.readouterr().err


def test_a_folder_prediction_goes_past_a_subfolder_and_a_dangling_link(depth_files, capsys):
    d = depth_files
    frames = d / "frames"
    frames.mkdir()
    np.save(frames / "a.npy", np.full((6, 8), 1.0))
    (frames / "b.npy").mkdir()  # a folder named like an image: not an image
    (frames / "c.npy").symlink_to(d / "gone.npy")  # a dangling link: an error for that entry only
    code = main(["predict", "--depth", str(frames), "--intrinsics", str(d / "K.json"), "--category", "laptop",
                 "--no-isolate", "--out", str(d / "out")])
    out = capsys.readouterr().out
    assert code == 1 and "a.npy: " in out and "c.npy: error:" in out and "b.npy" not in out
    assert (d / "out" / "a.json").is_file() and not (d / "out" / "c.json").exists()


def test_a_broken_train_config_names_its_file(tmp_path, capsys):
    config = tmp_path / "broken_config.json"
    config.write_text("{ not json")
    assert main(["train", "--category", "laptop", "--config", str(config), "--data", str(tmp_path),
                 "--out", str(tmp_path / "run")]) == 2
    assert "config: " in (err := capsys.readouterr().err) and "broken_config.json is not valid JSON" in err
    config.write_text("[1, 2]")
    assert main(["train", "--category", "laptop", "--config", str(config), "--data", str(tmp_path),
                 "--out", str(tmp_path / "run")]) == 2
    assert "must hold a JSON object" in capsys.readouterr().err


def _intrinsics(folder):
    from ancsh.data.images import read_intrinsics

    return read_intrinsics(folder / "K.json")


def test_continuous_joints_are_reported_within_a_turn():
    from ancsh.model.articulated import ArticulatedModel, Joint, JointType, Part
    from ancsh.cli.cad import _wrapped_states

    joints = (Joint("wheel", JointType.REVOLUTE, "a", "b", axis=[0, 0, 1], pivot=[0, 0, 0], lower=-np.inf, upper=np.inf),
              Joint("lid", JointType.REVOLUTE, "a", "c", axis=[0, 0, 1], pivot=[0, 0, 0], lower=0.0, upper=50.0))
    model = ArticulatedModel((Part("a"), Part("b"), Part("c")), joints, name="m")
    q = _wrapped_states(model, [np.radians(2687.0), 46.9])
    assert np.degrees(q[0]) == pytest.approx(2687.0 - 7 * 360.0)  # 167 deg
    assert q[1] == 46.9  # a limited joint keeps its value


def test_a_full_disk_during_generation_says_so_and_keeps_complete_shards(tmp_path, monkeypatch, capsys):
    """The shard is built in memory and written in one plain write: a full disk fails that write (before: a
    segfault inside HDF5's close), the shards written before stay, no temporary file is left."""
    import os
    import stat

    import ancsh.data.dataset as dataset

    real_fsync, calls = os.fsync, []

    def full_on_second_shard(fd):
        if stat.S_ISREG(os.fstat(fd).st_mode):  # a shard's file (the folder is synced too)
            calls.append(fd)
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_fsync(fd)

    monkeypatch.setattr(dataset.os, "fsync", full_on_second_shard)
    out = tmp_path / "ds"
    code = main(["data", "generate", "--category", "laptop", "--frames", "2", "--shard-size", "1", "--points", "64",
                 "--width", "160", "--height", "120", "--workers", "1", "--quiet", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "No space left on device" in err and "laptop_train_00001.h5" in err and "resume" in err
    assert "Traceback" not in err
    assert sorted(p.name for p in out.iterdir()) == ["laptop_train_00000.h5"]
    assert len(dataset.FrameDataset(out)) == 1




def test_an_unwritable_report_names_its_path_not_a_temporary_file(tmp_path, monkeypatch, capsys):
    """``bench render --out`` in a folder that cannot be written: the message names the report's path."""
    import os

    import ancsh.outputs as outputs

    locked = tmp_path / "locked"
    locked.mkdir()
    target = locked / "render.md"

    def refuse(*args, **kwargs):  # as a read-only folder does (root may write anywhere: simulate it)
        raise PermissionError(13, os.strerror(13), str(locked / ".render.md.abc.tmp"))

    monkeypatch.setattr(outputs.tempfile, "mkstemp", refuse)
    with pytest.raises(OSError) as err:
        outputs.write_bytes_atomically(target, b"x")
    assert err.value.filename == str(target) and ".tmp" not in str(err.value)
    assert main(["bench", "render", "--frames", "2", "--out", str(target)]) == 2
    msg = capsys.readouterr().err
    assert f"cannot read or write {target}: Permission denied" in msg and ".tmp" not in msg
