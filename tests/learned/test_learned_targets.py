"""The learned-accuracy targets read back from evaluation reports (`ancsh weights --reports`)."""

import json

import numpy as np
import pytest

from ancsh.data.procedural import GENERATOR_VERSION
from ancsh.learned.evaluate import PAPER_TABLE1
from ancsh.learned.targets import REAL_RATIO_GOAL, collect_targets, target_lines


def _report(category, rot, axis, sha, *, real_rot=None, paper=True):
    """A minimal `ancsh evaluate` report of the documented schema (docs/REPORT_SCHEMAS.md)."""
    summary = {"methods": {"exact_reduced": {"rot_deg": {"mean": list(rot)}, "axis_deg": {"mean": list(axis)}}}}
    data = {
        "category": category,
        "settings": {"part_names": [f"p{i}" for i in range(len(rot))], "joint_names": [f"j{k}" for k in range(len(axis))],
                     "frames": 7, "weights_sha256": sha, "generator_version": GENERATOR_VERSION},
        "summary": summary,
        "paper": {"table1": PAPER_TABLE1.get(category) if paper else None},
    }
    if real_rot is not None:
        data["real"] = {"settings": {"frames": 3},
                        "summary": {"methods": {"exact_reduced": {"rot_deg": {"mean": list(real_rot)}}}}}
    return data


def test_rows_compare_with_the_paper_and_the_real_split(tmp_path):
    from ancsh.learned.weights import weights_path
    from ancsh.outputs import file_sha256

    paper = PAPER_TABLE1["laptop"]["ANCSH"]
    rng = np.random.default_rng(3)
    under = [p * rng.uniform(0.5, 0.9) for p in paper["rot_deg"]]  # every part beats the paper
    real = [u * rng.uniform(1.0, REAL_RATIO_GOAL) for u in under]
    sha = file_sha256(weights_path("laptop"))
    (tmp_path / "laptop.json").write_text(json.dumps(_report("laptop", under, [paper["axis_deg"][0] * 2], sha,
                                                             real_rot=real)))
    (tmp_path / "oven.json").write_text(json.dumps(_report("oven", [9.0, 9.0], [1.0], "0" * 64)))
    rows, missing = collect_targets(tmp_path)
    by = {r.category: r for r in rows}
    lap, oven = by["laptop"], by["oven"]
    assert lap.paper_ratio == pytest.approx(np.divide(under, paper["rot_deg"]))
    assert lap.rotation_met is True and lap.axis_met is False and lap.real_met is True and not lap.stale
    assert lap.real_ratio == pytest.approx(np.divide(real, under)) and lap.real_frames == 3
    assert oven.rotation_met is False and oven.real_ratio is None and oven.stale
    assert "drawer" in missing and "laptop" not in missing
    old = _report("laptop", under, [1.0], sha)
    del old["settings"]["generator_version"]  # a report from before the generator recorded its version
    (tmp_path / "laptop.json").write_text(json.dumps(old))
    old_row = {r.category: r for r in collect_targets(tmp_path)[0]}["laptop"]
    assert "generator version not recorded" in old_row.stale
    md = "\n".join(target_lines(rows, missing, {}))
    assert "stale: other weights" in md and "| current |" in md and "(met)" in md and "**not met**" in md and "No report for: " in md


def test_bad_reports_are_named(tmp_path):
    with pytest.raises(ValueError, match="reports_dir"):
        collect_targets(tmp_path / "nowhere")
    (tmp_path / "laptop.json").write_text("{not json")
    with pytest.raises(ValueError, match="laptop.json"):
        collect_targets(tmp_path)
    broken = _report("laptop", [1.0, 1.0], [1.0], "0" * 64)
    del broken["summary"]["methods"]["exact_reduced"]
    (tmp_path / "laptop.json").write_text(json.dumps(broken))
    with pytest.raises(ValueError, match="laptop.json: no exact_reduced rot_deg"):
        collect_targets(tmp_path)


def test_weights_command_adds_the_targets_section(tmp_path):
    from ancsh.cli import main

    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "oven.json").write_text(json.dumps(_report("oven", [9.0, 9.0], [1.0], "0" * 64)))
    out = tmp_path / "weights.md"
    assert main(["weights", "--reports", str(reports), "--out", str(out)]) == 0
    text = out.read_text()
    assert f"ancsh weights --reports {reports} --out {out}" in text
    section = text.split("## Table 1 targets")[1]
    assert "| oven | p0, p1 | 7 (0) | 9.00 / 9.00 |" in section and "stale: other weights" in section
