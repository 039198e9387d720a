"""ancsh bench scenes (ancsh.studies.scenes): predict with and without a mask on rendered scenes, and without the object."""

import json

from ancsh.cli import main


def test_the_benchmark_runs_every_mode_on_each_scene_and_writes_its_command(tmp_path, capsys):
    out = tmp_path / "scenes.md"
    assert main(["bench", "scenes", "--categories", "laptop", "--frames", "2", "--stress-frames", "0", "--out", str(out), "--quiet"]) == 0
    data = json.loads(out.with_suffix(".json").read_text())
    assert data["command"] == f"ancsh bench scenes --categories laptop --frames 2 --stress-frames 0 --out {out}"
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


def test_the_report_counts_wrong_successes_and_is_written_again_from_its_records(tmp_path, capsys):
    from ancsh.studies.scenes import WRONG_MASK_IOU, WRONG_ROTATION_DEG, wrong_success

    base = {"ok": True, "mode": "auto", "mask_iou": 0.9, "rot_deg": 3.0}
    assert not wrong_success(base)
    assert wrong_success(base | {"mask_iou": WRONG_MASK_IOU - 0.01})  # something else isolated
    assert wrong_success(base | {"rot_deg": WRONG_ROTATION_DEG + 1})  # far off
    assert not wrong_success(base | {"ok": False, "rot_deg": None, "mask_iou": 0.0})  # no success, nothing wrong
    assert wrong_success(base | {"mode": "mask", "mask_iou": None, "rot_deg": 45.0})
    assert not wrong_success(base | {"mode": "mask", "mask_iou": None})
    # a measured report's records, one auto success made wrong by hand: the report written again counts it and keeps
    # the measuring run's command, date and machine
    out = tmp_path / "measured.md"
    assert main(["bench", "scenes", "--categories", "laptop", "--frames", "1", "--stress-frames", "0", "--out", str(out), "--quiet"]) == 0
    data = json.loads(out.with_suffix(".json").read_text())
    auto = next(r for r in data["records"] if r["mode"] == "auto")
    auto.update(ok=True, status="success", mask_iou=0.1, rot_deg=5.0)
    records = tmp_path / "records.json"
    records.write_text(json.dumps(data))
    again = tmp_path / "again.md"
    assert main(["bench", "scenes", "--records", str(records), "--out", str(again)]) == 0
    text = again.read_text()
    assert "| laptop | 1/1 (0) | 1/1 (1) |" in text
    assert f"Command: `{data['command']}`" in text and f"Date: {data['date']};" in text
    assert f"written again from the records by `ancsh bench scenes --records {records} --out {again}`" in text
    assert json.loads(again.with_suffix(".json").read_text())["records"] == data["records"]
    assert main(["bench", "scenes", "--records", str(records), "--frames", "3", "--out", str(again)]) == 2
    assert "--records: the records hold their own categories" in capsys.readouterr().err
    assert main(["bench", "scenes", "--records", str(tmp_path / "none.json"), "--out", str(again)]) == 2
    assert "is not the JSON of an `ancsh bench scenes` report" in capsys.readouterr().err
    # the runs of one command on other categories (two processes on two cores) merge into one report
    other = json.loads(json.dumps(data))
    other["command"] = data["command"].replace("--categories laptop", "--categories box")
    other["settings"]["categories"] = ["box"]
    for r in other["records"]:
        r["category"] = "box"
    second = tmp_path / "box.json"
    second.write_text(json.dumps(other))
    merged = tmp_path / "merged.md"
    assert main(["bench", "scenes", "--records", str(records), str(second), "--out", str(merged)]) == 0
    text = merged.read_text()
    assert "| laptop | 1/1 (0) | 1/1 (1) |" in text and "| box | 1/1 (0) | 1/1 (1) |" in text
    assert f"Command: `{data['command']}; {other['command']}`" in text
    out_data = json.loads(merged.with_suffix(".json").read_text())
    assert out_data["records"] == data["records"] + other["records"]
    assert out_data["settings"]["categories"] == ["laptop", "box"]
    assert main(["bench", "scenes", "--records", str(records), str(records), "--out", str(merged)]) == 2
    assert "laptop measured in two runs" in capsys.readouterr().err
    other["settings"]["frames"] = 5
    second.write_text(json.dumps(other))
    assert main(["bench", "scenes", "--records", str(records), str(second), "--out", str(merged)]) == 2
    assert "other settings" in capsys.readouterr().err


def test_the_stress_scenes_are_keyed_by_object_and_matched_by_mask(tmp_path):
    """One pair scene: every run has one record per scene object (two), auto at both seeds; the report has its
    section; the matching counts a returned mask by its IoU with each object."""
    import numpy as np

    from ancsh.studies.stress_scenes import FOUND_IOU, match_objects

    out = tmp_path / "scenes.md"
    real = tmp_path / "real.json"  # a real-frames report's records: one object found with its mask only, a negative
    real.write_text(json.dumps({"command": "ancsh bench real-frames", "date": "today", "records": [
        {"truth_category": "laptop", "mode": "mask", "ok": True, "joint_state_error_deg": 2.5},
        {"truth_category": "laptop", "mode": "auto", "ok": False}, {"truth_category": "laptop", "mode": "pixel", "ok": False},
        {"truth_category": None, "mode": "auto", "ok": False}]}))
    assert main(["bench", "scenes", "--categories", "laptop", "--frames", "1", "--stress-frames", "1", "--seeds", "0",
                 "1", "--real-frames", str(real), "--out", str(out), "--quiet"]) == 0
    assert "| real frames | 1/1 | 0/1 | 0/1 | 0/1 | 2.5 |" in out.read_text()
    assert main(["bench", "scenes", "--records", str(out.with_suffix(".json")), "--real-frames", str(tmp_path / "x.json"),
                 "--out", str(tmp_path / "again.md")]) == 2
    stress = json.loads(out.with_suffix(".json").read_text())["stress"]
    recs = [r for r in stress["records"] if r["object"] is not None]
    assert {r["kind"] for r in stress["records"]} == {"pair"}
    keys = sorted((r["mode"], r["seed"], r["object"]) for r in recs)
    assert keys == [("auto", 0, 0), ("auto", 0, 1), ("auto", 1, 0), ("auto", 1, 1), ("hint", 0, 0), ("hint", 0, 1),
                    ("mask", 0, 0), ("mask", 0, 1)]
    assert all((r["rot_deg"] is not None) == (r["found"] and r["mask_iou"] is not None) for r in recs if r["mode"] == "auto")
    assert "## Stress scenes" in out.read_text() and "| laptop |" in out.read_text().split("## Stress scenes")[1]
    from ancsh.studies.stress_scenes import STAGES

    assert all(r["stage"] in STAGES for r in recs if r["mode"] == "auto")  # where each object was lost
    assert all(r["stage"] in ("right", "wrong fit") for r in recs if r["mode"] == "auto" and r["found"])
    assert "Where the objects are lost" in out.read_text() and "| all | 2 |" in out.read_text()
    a = np.zeros((10, 10), bool)
    a[:, :5] = True
    b = ~a
    half = np.zeros_like(a)
    half[:, :3] = True
    matched, unmatched, merged = match_objects([half, np.ones_like(a), None], [True, True, False], [a, b])
    assert matched == {0: (0, 0.6), 1: (1, 0.5)} and FOUND_IOU <= 0.5 and unmatched == [2] and merged == {0, 1}


def test_loss_stage_says_where_an_object_was_lost_from_the_isolation():
    """Each stage of ``loss_stage`` on a hand-made isolation: the object is columns 0-3 of a 10 x 10 image."""
    import numpy as np

    from ancsh.data.isolate import Cluster, Isolation
    from ancsh.studies.stress_scenes import STAGES, loss_stage

    obj = np.zeros((10, 10), bool)
    obj[:, :4] = True

    def isolation(labels, verified=()):
        n = int(labels.max()) + 1
        clusters = tuple(Cluster(1, 0.5, (0.0, 0.0), True) for _ in range(n))
        return Isolation(labels == 0, labels, clusters, 0, order=tuple(range(n)), verified=tuple(verified))

    whole = np.full((10, 10), -1)
    whole[:, :4] = 0  # one segment that is the object
    assert loss_stage(isolation(whole), obj, True, False) == ("right", None)
    assert loss_stage(isolation(whole), obj, True, True) == ("wrong fit", None)
    assert loss_stage(isolation(whole), obj, False, False) == ("segment not fitted", None)
    refused = isolation(whole, [{"segment": 0, "status": "not_this_category"}])
    assert loss_stage(refused, obj, False, False) == ("segment refused", "not_this_category")
    passed = isolation(whole, [{"segment": 0, "status": "success"}])
    assert loss_stage(passed, obj, False, False) == ("segment passed, not returned", None)
    larger = np.zeros((10, 10), dtype=np.int64)  # the object inside a segment 2.5 times its size: IoU 0.4
    assert loss_stage(isolation(larger), obj, False, False) == ("no segment: in a larger one", None)
    pieces = np.full((10, 10), -1)
    pieces[:4, :4], pieces[4:7, :4], pieces[7:, :4] = 0, 1, 2  # three pieces, none half of it
    assert loss_stage(isolation(pieces), obj, False, False) == ("no segment: cut up or removed", None)
    none = np.full((10, 10), -1)  # nothing left: taken for a support plane
    assert loss_stage(Isolation(np.zeros((10, 10), bool), none), obj, False, False)[0] == "no segment: cut up or removed"
    assert {"right", "wrong fit", "segment refused"} <= set(STAGES)
