"""``ancsh bench cad-auto``: outcomes, totals and the report (from records built here), its argument checks."""

import json

import pytest

from ancsh.cli import main
from ancsh.studies.cad.auto_start import (OUTCOMES, AutoStartConfig, outcome, summarise_auto_start,
                                          write_auto_start_report)
from ancsh.studies.report import Provenance


def _results(outcomes_by_object):
    records, agreement, objects = [], {}, []
    for name, outs in outcomes_by_object.items():
        category = name.rsplit("_", 1)[0]
        objects.append({"name": name, "category": category, "parts": ["base", "lid"], "joints": [["j", "revolute"]]})
        for seed, o in enumerate(outs):
            success, correct = o in ("right", "wrong_success"), o in ("right", "refused_correct")
            records.append({"object": name, "category": category, "seed": seed,
                            "status": "success" if success else "large_residual", "message": "", "correct": correct,
                            "outcome": outcome(success, correct),
                            "ad_over_diameter": [0.0 if correct else 0.5], "rmse": 1e-6, "inlier_ratio": 1.0,
                            "time_s": 1.0, "q": [0.1], "q_true": [0.1]})
        agreement[name] = len(set(outs)) == 1
    return {"records": records, "agreement": agreement, "objects": objects, "skipped": [],
            "config": {"per_category": 1, "seeds": [0, 1, 2], "points": 3000, "noise": False, "image_size": [320, 240],
                       "ad_threshold": 0.1}}


def test_outcome_of_every_status_and_correctness():
    assert [outcome(s, c) for s in (True, False) for c in (True, False)] == list(OUTCOMES)


def test_totals_and_report_count_what_the_records_say(tmp_path):
    results = _results({"laptop_1": ["right", "wrong_success", "right"], "box_2": ["refused_wrong"] * 3})
    s = summarise_auto_start(results)
    assert s["total"] == {"right": 2, "wrong_success": 1, "refused_correct": 0, "refused_wrong": 3}
    assert s["agree"] == 1 and s["objects"] == 2 and s["per_category"]["laptop"]["wrong_success"] == 1
    before = {**_results({"laptop_1": ["wrong_success"] * 3}), "command": "ancsh bench cad-auto --old"}
    path = write_auto_start_report(results, tmp_path / "r.md", Provenance("ancsh bench cad-auto --out r.md"),
                                   before=before)
    text = path.read_text()
    assert "ancsh bench cad-auto --out r.md" in text and "ancsh bench cad-auto --old" in text
    assert "| this run | 6 | 2 | 1 | 0 | 3 | 1 of 2 | 1.0 |" in text and "| 3 | 0 | 3 | 0 | 0 | 1 of 1 | 1.0 |" in text
    data = json.loads(path.with_suffix(".json").read_text())
    assert data["summary"]["total"] == s["total"] and data["before"]["summary"]["total"]["wrong_success"] == 3


def test_bad_settings_are_refused(tmp_path, capsys):
    with pytest.raises(ValueError, match="per_category"):
        AutoStartConfig(per_category=0)
    with pytest.raises(ValueError, match="seeds"):
        AutoStartConfig(seeds=())
    bad = tmp_path / "x.json"
    bad.write_text("[1, 2]")
    assert main(["bench", "cad-auto", "--before", str(bad), "--out", str(tmp_path / "r.md")]) == 2
    assert "--before" in capsys.readouterr().err
    assert main(["bench", "cad-auto", "--data", str(tmp_path / "none"), "--out", str(tmp_path / "r.md")]) == 2
