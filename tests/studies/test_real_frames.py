"""Real-frame folders (ancsh.data.real_frames) and the real-frame benchmark (ancsh bench real-frames), on rendered
frames laid out as real ones: a held-out laptop with its measured opening, and a frame of nothing but a floor."""

import json

import numpy as np
import pytest
from PIL import Image

from ancsh.cli import main
from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.data.real_frames import load_real_frame
from ancsh.data.render import Intrinsics


def _write_frame(folder, depth, intr, objects, **extra):
    folder.mkdir(parents=True)
    Image.fromarray(np.round(depth * 1000).astype(np.uint16)).save(folder / "depth.png")
    (folder / "K.json").write_text(json.dumps(intr.to_json()))
    truth = {"schema": "real-frame-truth/1", "objects": objects, **extra}
    (folder / "truth.json").write_text(json.dumps(truth))
    return folder


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    root = tmp_path_factory.mktemp("real_frames")
    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
    frame = gen.frame(2)
    _, renderer = gen.instance(frame.instance_index)
    depth = renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth
    mask = depth > 0
    laptop = _write_frame(root / "laptop_frame", depth, frame.intrinsics,
                          [{"category": "laptop", "mask": "mask_laptop.png", "joint_state_deg": float(np.degrees(frame.joint_states_abs[0])),
                            "uncertainty_deg": 0.0}])
    Image.fromarray(mask.astype(np.uint8) * 255).save(laptop / "mask_laptop.png")
    intr = Intrinsics()
    v = np.arange(intr.height)[:, None] * np.ones((1, intr.width))
    floor = 1.0 / (0.4 + 0.0015 * v)  # a floor tilted away from the camera, 0.7..2.5 m
    negative = _write_frame(root / "floor_only", floor, intr, [])
    return laptop, negative, frame


def test_a_folder_reads_with_its_objects_and_bad_folders_name_what_is_wrong(frames, tmp_path):
    laptop, negative, frame = frames
    f = load_real_frame(laptop)
    assert f.name == "laptop_frame" and not f.negative and f.rgb is None
    assert f.objects[0].category == "laptop" and f.objects[0].mask.sum() == np.count_nonzero(f.depth > 0)
    assert load_real_frame(negative).negative
    depth = np.full((48, 64), 1.0)
    small = Intrinsics(fx=60, fy=60, cx=32, cy=24, width=64, height=48)
    bad = _write_frame(tmp_path / "schema", depth, small, [], schema="real-frame-truth/2")
    with pytest.raises(ValueError, match="schema"):
        load_real_frame(bad)
    bad = _write_frame(tmp_path / "escape", depth, small, [{"category": "laptop", "mask": "../mask.png"}])
    with pytest.raises(ValueError, match=r"objects\[0\]\.mask: expected a file name inside"):
        load_real_frame(bad)
    bad = _write_frame(tmp_path / "size", depth, Intrinsics(fx=60, fy=60, cx=32, cy=24, width=640, height=480), [])
    with pytest.raises(ValueError, match="depth: .* is 64x48 pixels, the intrinsics say 640x480"):
        load_real_frame(bad)
    bad = _write_frame(tmp_path / "objects", depth, small, {"category": "laptop"})
    with pytest.raises(ValueError, match="objects: expected a list"):
        load_real_frame(bad)


def test_the_benchmark_runs_each_mode_and_judges_the_negative_frame(frames, tmp_path, capsys):
    laptop, negative, frame = frames
    out = tmp_path / "report" / "real_frames.md"
    assert main(["bench", "real-frames", str(laptop), str(negative), "--categories", "laptop", "--out", str(out),
                 "--quiet"]) == 0
    data = json.loads(out.with_suffix(".json").read_text())
    assert data["command"].startswith("ancsh bench real-frames ")
    recs = {(r["frame"], r["mode"]): r for r in data["records"]}
    assert set(recs) == {("laptop_frame", "mask"), ("laptop_frame", "auto"), ("laptop_frame", "pixel"), ("floor_only", "auto")}
    for r in data["records"]:
        assert r["exit_code"] == (0 if r["ok"] else 1)
    assert recs[("laptop_frame", "mask")]["mask_iou"] is None and recs[("laptop_frame", "mask")]["timings_ms"]["isolate"] == 0
    for mode in ("auto", "pixel"):  # the only thing in view: isolation finds it
        assert recs[("laptop_frame", mode)]["mask_iou"] > 0.9
    truth = np.degrees(frame.joint_states_abs[0])
    r = recs[("laptop_frame", "mask")]
    assert r["ok"] and abs(r["joint_state"][0] - truth) == pytest.approx(r["joint_state_error_deg"]) and r["joint_state_error_deg"] < 15
    assert not recs[("floor_only", "auto")]["ok"]  # nothing but a floor: no laptop
    text = out.read_text()
    assert "| floor_only | laptop | auto |" in text and "none of any category (negative)" in text
    timed = {(t["frame"], t["category"]): t["ms"] for t in data["isolation_ms"]}  # isolation timed alone, per frame
    assert set(timed) == {("laptop_frame", "laptop"), ("floor_only", "laptop")}
    assert all(len(ms) == 5 and min(ms) > 0 for ms in timed.values()) and "## Isolation time" in text
    assert (out.parent / "real_frames_laptop_frame.png").stat().st_size > 0
    assert (out.parent / "real_frames_floor_only.png").stat().st_size > 0


def test_a_network_under_test_replaces_the_shipped_one_and_is_named(frames, tmp_path, capsys):
    from ancsh.learned.network.weights import weights_path
    from ancsh.outputs import file_sha256

    _, negative, _ = frames
    shipped = weights_path("laptop")
    out = tmp_path / "under_test" / "real_frames.md"
    assert main(["bench", "real-frames", str(negative), "--categories", "laptop", "--weights", f"laptop={shipped}",
                 "--out", str(out), "--quiet"]) == 0
    data = json.loads(out.with_suffix(".json").read_text())
    assert data["weights"]["laptop"]["sha256"] == file_sha256(shipped)
    assert f"--weights laptop={shipped}" in data["command"] and "Networks under test" in out.read_text()
    for bad, why in ((["--weights", "laptop"], "CATEGORY=FILE"), (["--weights", f"laptop={tmp_path / 'none.pt'}"], "no such file"),
                     (["--weights", f"laptop={shipped}", "--weights", f"laptop={shipped}"], "given twice")):
        capsys.readouterr()
        assert main(["bench", "real-frames", str(negative), *bad, "--out", str(tmp_path / "x.md"), "--quiet"]) == 2
        assert why in capsys.readouterr().err


def test_another_refinement_than_auto_is_run_and_named(frames, tmp_path, capsys):
    """``--refine CATEGORY=OPTION``: that category's runs refine with OPTION (the network's pass shows in the notes),
    the report names it; bad values and --update-docs are refused."""
    laptop, negative, _ = frames
    out = tmp_path / "refined" / "real_frames.md"
    assert main(["bench", "real-frames", str(laptop), "--refine", "laptop=network", "--out", str(out), "--quiet"]) == 0
    data = json.loads(out.with_suffix(".json").read_text())
    assert data["refine"] == {"laptop": "network"} and "--refine laptop=network" in data["command"]
    assert "Refinements other than `--refine auto`" in out.read_text()
    assert any(n.startswith("refinement network:") for r in data["records"] for n in r.get("notes", []))
    for bad, why in ((["--refine", "laptop=icp"], "expected template, network or none"),
                     (["--refine", "laptop=none", "--refine", "laptop=network"], "given twice"),
                     (["--refine", "laptop=none", "--update-docs"], "not with --update-docs")):
        capsys.readouterr()
        assert main(["bench", "real-frames", str(negative), *bad, "--quiet"] + ([] if "--update-docs" in bad else
                                                                               ["--out", str(tmp_path / "x.md")])) == 2
        assert why in capsys.readouterr().err


def test_seeds_run_every_prediction_again_and_report_their_agreement(frames, tmp_path):
    laptop, _, _ = frames
    out = tmp_path / "seeds" / "real_frames.md"
    assert main(["bench", "real-frames", str(laptop), "--seeds", "0", "1", "--out", str(out), "--quiet"]) == 0
    data = json.loads(out.with_suffix(".json").read_text())
    assert "--seeds 0 1" in data["command"]
    assert sorted(a["mode"] for a in data["agreement"]) == ["auto", "mask", "pixel"]
    assert all(len(a["statuses"]) == 2 and len(a["states"]) == 2 for a in data["agreement"])
    assert "## The same answer at every seed" in out.read_text()
