"""Frame generation: determinism, view rejection, resumable sharded datasets, the CLI."""

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.data.dataset import FIELDS, CorruptShardError, FrameDataset, ShardReader, read_arrays
from ancsh.data.generate import FrameGenerator, FrameRejected, GenerationConfig, frame_seed, generate_dataset
from ancsh.data.noise import DepthNoise
from ancsh.data.render import Intrinsics

SMALL = Intrinsics.kinect(160, 120)


def config(**kw):
    base = dict(category="laptop", intrinsics=SMALL, num_points=64, shard_size=3, min_part_pixels=5)
    base.update(kw)
    return GenerationConfig(**base)


def assert_same_arrays(a: dict, b: dict):
    assert set(a) == set(b)
    for k in a:
        if a[k].dtype == object:
            assert list(a[k]) == list(b[k]), k
        else:
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_frames_are_a_function_of_seed_and_index():
    cfg = config()
    a = FrameGenerator(cfg)
    b = FrameGenerator(cfg)
    fa = a.frame(5)
    b.frame(2)  # other frames generated first must not matter
    fb = b.frame(5)
    np.testing.assert_array_equal(fa.points, fb.points)
    np.testing.assert_array_equal(fa.gt.npcs, fb.gt.npcs)
    assert fa.seed == fb.seed == frame_seed(cfg.seed, 5)
    other = FrameGenerator(config(seed=1)).frame(5)
    assert not np.array_equal(other.points, fa.points)
    assert frame_seed(0, 1) != frame_seed(1, 0)


def test_kept_depth_is_the_image_the_points_come_from():
    from ancsh.data.render import backproject

    gen = FrameGenerator(config())
    plain, kept = gen.frame(3), gen.frame(3, keep_depth=True)
    assert plain.depth is None
    np.testing.assert_array_equal(kept.points, plain.points)  # same frame, same draws
    assert kept.depth.shape == (SMALL.height, SMALL.width)
    cloud = backproject(kept.depth, SMALL)
    # every sampled point is one of the image's back-projected pixels
    d = np.min(np.linalg.norm(kept.points[:, None, :] - cloud[None, :, :], axis=2), axis=1)
    assert d.max() < 1e-12


def test_accepted_views_show_every_part():
    cfg = config(category="eyeglasses", min_part_pixels=20, min_part_fraction=0.05)
    gen = FrameGenerator(cfg)
    for i in range(4):
        fr = gen.frame(i)
        assert np.all(fr.part_pixels >= 20)
        assert np.all(fr.part_pixels >= 0.05 * fr.part_pixels.sum())
        assert fr.points.shape == (64, 3) and set(np.unique(fr.gt.part_labels)) <= set(range(3))
        assert fr.instance == f"eyeglasses_{fr.instance_seed}"


def test_impossible_views_are_reported():
    gen = FrameGenerator(config(min_part_pixels=10**6, max_attempts=3))
    with pytest.raises(FrameRejected, match="3 attempts"):
        gen.frame(0)


def test_config_errors(tmp_path):
    with pytest.raises(ValueError, match="category"):
        GenerationConfig(category="toaster")
    with pytest.raises(ValueError, match="exactly one"):
        GenerationConfig()
    with pytest.raises(ValueError, match="split"):
        GenerationConfig(category="laptop", split="val")
    with pytest.raises(ValueError, match="shard_size"):
        GenerationConfig(category="laptop", shard_size=0)
    with pytest.raises(ValueError, match="noise"):
        GenerationConfig(category="laptop", noise=None)
    with pytest.raises(FileNotFoundError, match="urdf"):
        GenerationConfig(urdf=str(tmp_path / "nothing.urdf"))
    with pytest.raises(ValueError, match="frames"):
        generate_dataset(config(), 0, tmp_path)


class Interrupt(Exception):
    pass


def test_resume_after_interruption_gives_the_same_dataset(tmp_path):
    cfg = config(noise=DepthNoise(random_dropout=0.05))
    frames = 8  # shards of 3, 3, 2 frames
    ref = generate_dataset(cfg, frames, tmp_path / "ref", progress=False)
    assert ref.written == (0, 1, 2) and ref.frames_generated == frames

    out = tmp_path / "run"

    def stop_after_first(shard, path):
        if shard == 0:
            raise Interrupt

    with pytest.raises(Interrupt):
        generate_dataset(cfg, frames, out, progress=False, on_shard=stop_after_first)
    assert [p.name for p in sorted(out.iterdir())] == ["laptop_train_00000.h5"]
    # what a killed writer leaves: a temporary file, and a truncated shard from another writer
    (out / "laptop_train_00001.h5.tmp999").write_bytes(b"partial")
    (out / "laptop_train_00002.h5").write_bytes(ref.paths[2].read_bytes()[:1000])

    report = generate_dataset(cfg, frames, out, progress=False)
    assert report.skipped == (0,) and report.written == (1, 2)
    assert [s for s, _ in report.replaced] == [2] and "damaged" in report.replaced[0][1]
    assert report.frames_generated == 5
    assert not list(out.glob("*.tmp*"))
    assert_same_arrays(read_arrays(out), read_arrays(tmp_path / "ref"))

    again = generate_dataset(cfg, frames, out, progress=False)  # nothing left to do
    assert again.skipped == (0, 1, 2) and again.frames_generated == 0

    # a larger dataset reuses the complete shards and redoes the short last one
    more = generate_dataset(cfg, 10, out, progress=False)
    assert more.skipped == (0, 1) and more.written == (2, 3)
    assert len(FrameDataset(out)) == 10


def test_other_settings_in_the_same_directory_are_refused(tmp_path):
    generate_dataset(config(), 6, tmp_path, progress=False)  # two shards
    with pytest.raises(ValueError, match="other settings \\(differing: seed\\)"):
        generate_dataset(config(seed=3), 6, tmp_path, progress=False)
    with pytest.raises(ValueError, match="beyond the requested 3 frames"):
        generate_dataset(config(), 3, tmp_path, progress=False)
    report = generate_dataset(config(seed=3), 3, tmp_path, progress=False, overwrite=True)
    assert report.written == (0,) and ShardReader(report.paths[0]).config["seed"] == 3
    assert len(FrameDataset(tmp_path)) == 3


@pytest.mark.slow
def test_worker_processes_produce_the_same_frames(tmp_path):
    cfg = config(shard_size=4)
    one = generate_dataset(cfg, 8, tmp_path / "one", progress=False)
    two = generate_dataset(cfg, 8, tmp_path / "two", workers=2, progress=False)
    assert two.written == (0, 1)
    assert_same_arrays(read_arrays(tmp_path / "one"), read_arrays(tmp_path / "two"))
    assert one.frames_generated == two.frames_generated == 8


# --- command line ----------------------------------------------------------------------
def test_cli_generate_and_show(tmp_path, capsys):
    out = tmp_path / "ds"
    code = main(["data", "generate", "--category", "oven", "--split", "test", "--frames", "3", "--workers", "1",
                 "--shard-size", "2", "--width", "160", "--height", "120", "--points", "64", "--no-noise",
                 "--out", str(out), "--quiet"])
    assert code == 0
    assert "3 frames generated" in capsys.readouterr().out
    ds = FrameDataset(out)
    assert len(ds) == 3 and ds[0].category == "oven" and ds[0].intrinsics == SMALL
    assert ShardReader(ds.readers[0].path).config["noise"]["enabled"] is False
    png = tmp_path / "view.png"
    assert main(["data", "show", str(out), "--frame", "2", "--out", str(png)]) == 0
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    assert main(["data", "show", str(out), "--frame", "3", "--out", str(png)]) == 2
    assert "out of range" in capsys.readouterr().err


def test_cli_generates_with_the_real_frames_noise(tmp_path, capsys):
    args = ["data", "generate", "--category", "laptop", "--split", "test", "--frames", "1", "--workers", "1",
            "--width", "160", "--height", "120", "--points", "64", "--quiet"]
    assert main([*args, "--real-frames-noise", "--out", str(tmp_path / "ds")]) == 0
    ds = FrameDataset(tmp_path / "ds")
    assert DepthNoise(**ShardReader(ds.readers[0].path).config["noise"]) == DepthNoise.real_frames()
    assert main([*args, "--real-frames-noise", "--no-noise", "--out", str(tmp_path / "no")]) == 2
    assert "--real-frames-noise: not with --no-noise" in capsys.readouterr().err


def test_cli_error_paths(tmp_path, capsys):
    code = main(["data", "generate", "--category", "toaster", "--frames", "5", "--out", str(tmp_path)])
    assert code == 2 and "no convention for 'toaster'" in capsys.readouterr().err
    for bad in ("0", "-3", "many"):
        with pytest.raises(SystemExit) as exc:
            main(["data", "generate", "--category", "laptop", "--frames", bad])
        assert exc.value.code == 2
        assert "--frames" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["data", "generate", "--frames", "5"])  # neither --category nor --urdf
    assert "--category" in capsys.readouterr().err
    assert main(["data", "show", str(tmp_path / "missing.h5")]) == 2
    assert "missing.h5" in capsys.readouterr().err
    (tmp_path / "bad.h5").write_bytes(b"\x89HDF\r\n\x1a\n truncated")
    assert main(["data", "show", str(tmp_path / "bad.h5")]) == 2
    assert "bad.h5" in capsys.readouterr().err
    assert issubclass(CorruptShardError, ValueError)


def test_cli_refuses_real_objects_the_catalog_does_not_have(tmp_path, capsys):
    from ancsh.data.catalog import load_catalog

    import json

    from ancsh.data.catalog import builtin_catalog_path

    catalog = load_catalog(None)  # the shipped catalog: its eyeglasses are all test objects
    assert catalog.instances("eyeglasses", "test") and not catalog.instances("eyeglasses", "train")
    out = tmp_path / "ds"
    args = ["data", "generate", "--split", "train", "--frames", "2", "--out", str(out), "--quiet"]
    assert main([*args, "--real", "builtin", "--category", "eyeglasses"]) == 2
    err = capsys.readouterr().err
    assert "--real" in err and "no eyeglasses object in the train split" in err and "all in the test split" in err
    boxes = json.loads(builtin_catalog_path().read_text())  # a catalog of boxes only: it has no drawer
    boxes["objects"] = [o for o in boxes["objects"] if o["category"] == "box"]
    (tmp_path / "boxes.json").write_text(json.dumps(boxes))
    assert main([*args, "--real", str(tmp_path / "boxes.json"), "--category", "drawer"]) == 2
    assert "it has no drawer object" in capsys.readouterr().err
    assert not out.exists()  # nothing was generated


def test_bench_render_prints_rates(capsys, tmp_path):
    assert main(["bench", "render", "--frames", "2", "--categories", "laptop", "--width", "160", "--height", "120",
                 "--out", str(tmp_path / "r.md")]) == 0
    out = capsys.readouterr().out
    assert "laptop" in out and "fr/s" in out
    text = (tmp_path / "r.md").read_text()
    assert "Measured on" in text and "not checked (this run measured 160x120 frames)" in text and "2-core" not in text
    assert main(["bench", "render", "--frames", "1", "--categories", "toaster"]) == 2
    assert "toaster" in capsys.readouterr().err


def test_render_target_verdict_states_what_was_measured():
    from ancsh.studies.render import render_target_verdict

    assert render_target_verdict({"laptop": 60.0, "oven": 40.0}, 640, 480).endswith("met here by 1 of 2 categories (laptop).")
    assert render_target_verdict({"laptop": 60.0}, 640, 480).endswith("met here by 1 of 1 categories.")
    assert render_target_verdict({"laptop": 10.0}, 640, 480).endswith("met here by 0 of 1 categories.")


def test_every_field_documented():
    import ancsh.data.dataset as dataset

    for key in FIELDS:
        assert key in dataset.__doc__, key


# --- real objects ----------------------------------------------------------------------
def _shared_objects():
    from ancsh.data.paths import shared_objects

    try:
        return shared_objects()
    except (FileNotFoundError, ValueError):
        return []


@pytest.mark.parametrize("path", _shared_objects(), ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_shared_object_renders(path):
    """Every URDF object of the shared data renders; those with a mesh on every part give
    full frames with consistent ground truth, the others a clear error."""
    from ancsh.data.render import ModelRenderer, sample_viewpoint
    from ancsh.data.urdf import load_urdf

    model = load_urdf(path)
    q = model.random_states(0)
    view = ModelRenderer(model, visibility_samples=64).render(q, sample_viewpoint(None, 0, model, q), SMALL)
    assert (view.part_ids >= 0).sum() > 50
    gen = FrameGenerator(config(category=None, urdf=str(path), min_part_fraction=0.0, min_part_pixels=1))
    if any(p.mesh is None for p in model.parts):
        with pytest.raises(ValueError, match="have no mesh"):
            gen.frame(0)
        return
    fr = gen.frame(0)
    sel = fr.gt.part_labels == fr.gt.part_labels[0]
    j = int(fr.gt.part_labels[0])
    np.testing.assert_allclose(fr.gt.T_cam_npcs[j].apply(fr.gt.npcs[sel]), fr.points[sel], atol=1e-9)
    assert fr.instance_seed == -1 and fr.category == (model.category or "urdf")


def test_cli_generate_from_urdf(tmp_path, capsys):
    laptops = [p for p in _shared_objects() if p.parent.name.startswith("laptop")]
    if not laptops:
        pytest.skip("no shared laptop object")
    out = tmp_path / "urdf"
    code = main(["data", "generate", "--urdf", str(laptops[0]), "--frames", "2", "--workers", "1", "--width", "160",
                 "--height", "120", "--points", "32", "--out", str(out), "--quiet"])
    assert code == 0, capsys.readouterr().err
    ds = FrameDataset(out)
    assert len(ds) == 2 and ds[0].instance_seed == -1 and ds.readers[0].source == f"urdf:{laptops[0]}"
    assert ds.readers[0].path.name == f"{laptops[0].parent.name}_urdf_00000.h5"


@pytest.mark.slow
def test_killed_generator_resumes_to_the_same_dataset(tmp_path):
    """SIGKILL a real `ancsh data generate` process after its first shard, then resume."""
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "killed"
    args = ["--category", "laptop", "--frames", "40", "--shard-size", "2", "--points", "64", "--workers", "1",
            "--width", "320", "--height", "240", "--seed", "4", "--quiet"]
    proc = subprocess.Popen([sys.executable, "-m", "ancsh", "data", "generate", *args, "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while not (out / "laptop_train_00000.h5").exists():
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline
            time.sleep(0.01)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    done = sorted(p.name for p in out.glob("*.h5"))
    assert 1 <= len(done) < 20
    assert main(["data", "generate", *args, "--out", str(out)]) == 0
    assert not list(out.glob("*.tmp*"))
    assert main(["data", "generate", *args, "--out", str(tmp_path / "clean")]) == 0
    assert_same_arrays(read_arrays(out), read_arrays(tmp_path / "clean"))


def test_cli_reports_objects_without_acceptable_views(tmp_path, capsys):
    doors = [p for p in _shared_objects() if p.parent.name == "doors"]
    if doors:  # a door's frame link has no mesh: no ANCSH ground truth
        code = main(["data", "generate", "--urdf", str(doors[0]), "--frames", "1", "--workers", "1", "--out",
                     str(tmp_path), "--quiet"])
        assert code == 2 and "have no mesh" in capsys.readouterr().err
    code = main(["data", "generate", "--category", "laptop", "--frames", "1", "--workers", "1", "--width", "64",
                 "--height", "48", "--min-part-pixels", "5000", "--out", str(tmp_path / "never"), "--quiet"])
    assert code == 1 and "no view of" in capsys.readouterr().err


def test_cli_generate_into_a_file_names_out(tmp_path, capsys):
    out = tmp_path / "taken.txt"
    out.write_text("not a dataset")
    assert main(["data", "generate", "--category", "oven", "--frames", "1", "--out", str(out), "--quiet"]) == 2
    assert f"--out: {out} is a file, not a folder" in capsys.readouterr().err
    assert out.read_text() == "not a dataset"
