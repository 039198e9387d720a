"""ancsh bench scenes (ancsh.studies.scenes): predict with and without a mask on rendered scenes, and without the object."""

import json

from ancsh.cli import main


def test_the_benchmark_runs_every_mode_on_each_scene_and_writes_its_command(tmp_path, capsys):
    out = tmp_path / "scenes.md"
    assert main(["bench", "scenes", "--categories", "laptop", "--frames", "2", "--out", str(out), "--quiet"]) == 0
    data = json.loads(out.with_suffix(".json").read_text())
    assert data["command"] == f"ancsh bench scenes --categories laptop --frames 2 --out {out}"
    modes = sorted((r["frame"], r["mode"]) for r in data["records"])
    assert modes == [(0, "auto"), (0, "empty"), (0, "mask"), (1, "auto"), (1, "empty"), (1, "mask")]
    for r in data["records"]:
        assert (r["mask_iou"] is not None) == (r["mode"] == "auto")
        assert (r["rot_deg"] is not None) == (r["ok"] and r["mode"] != "empty")
    masked = [r for r in data["records"] if r["mode"] == "mask"]
    assert all(r["ok"] for r in masked)  # with its mask the laptop is fitted
    assert "| laptop |" in out.read_text()
    assert main(["bench", "scenes", "--categories", "chair", "--frames", "1", "--out", str(out)]) == 2
    assert "--categories: no shipped weights for ['chair']" in capsys.readouterr().err
