"""The learned-accuracy targets read back from evaluation reports (`ancsh weights --reports`)."""

import json

import numpy as np
import pytest

from ancsh.data.procedural import generator_version
from ancsh.studies.table1 import PAPER_TABLE1
from ancsh.studies.targets import (
    REAL_RATIO_GOAL, TRAINING_BUDGET_MIN, budget_projection, collect_targets, limit_lines, roll_gains, target_lines, train_test_ratios,
)


def _report(category, rot, axis, sha, *, real_rot=None, paper=True, refined_rot=None, network=None):
    """A minimal `ancsh evaluate` report of the documented schema (docs/REPORT_SCHEMAS.md); ``network``: the
    refinement network's ``(rot, axis)`` row."""
    summary = {"methods": {"exact_reduced": {"rot_deg": {"mean": list(rot)}, "axis_deg": {"mean": list(axis)}}}}
    if refined_rot is not None:  # `ancsh evaluate --refine template`
        summary["methods"]["template"] = {"rot_deg": {"mean": list(refined_rot)}, "axis_deg": {"mean": list(axis)}}
    if network is not None:  # `ancsh evaluate --refine network`
        summary["methods"]["network"] = {"rot_deg": {"mean": list(network[0])}, "axis_deg": {"mean": list(network[1])}}
    data = {
        "category": category,
        "settings": {"part_names": [f"p{i}" for i in range(len(rot))], "joint_names": [f"j{k}" for k in range(len(axis))],
                     "frames": 7, "weights_sha256": sha, "generator_version": generator_version(category)},
        "summary": summary,
        "paper": {"table1": PAPER_TABLE1.get(category) if paper else None},
    }
    if real_rot is not None:
        data["real"] = {"settings": {"frames": 3},
                        "summary": {"methods": {"exact_reduced": {"rot_deg": {"mean": list(real_rot)}}}}}
    return data


def test_rows_compare_with_the_paper_and_the_real_split(tmp_path):
    from ancsh.learned.network.weights import weights_path
    from ancsh.outputs import file_sha256

    paper = PAPER_TABLE1["laptop"]["ANCSH"]
    rng = np.random.default_rng(3)
    under = [p * rng.uniform(0.5, 0.9) for p in paper["rot_deg"]]  # every part beats the paper
    real = [u * rng.uniform(1.0, REAL_RATIO_GOAL) for u in under]
    sha = file_sha256(weights_path("laptop"))
    (tmp_path / "laptop.json").write_text(json.dumps(_report("laptop", under, [paper["axis_deg"][0] * 2], sha,
                                                             real_rot=real)))
    oven_paper = PAPER_TABLE1["oven"]["ANCSH"]["rot_deg"]
    refined = [oven_paper[0] * 0.5, oven_paper[1] * 1.5]  # the template-refined row: one part under the paper
    net_rot, net_axis = [oven_paper[0] * 0.9, oven_paper[1] * 0.8], [PAPER_TABLE1["oven"]["ANCSH"]["axis_deg"][0] * 3]
    (tmp_path / "oven.json").write_text(json.dumps(_report("oven", [9.0, 9.0], [1.0], "0" * 64, refined_rot=refined,
                                                           network=(net_rot, net_axis))))
    rows, missing = collect_targets(tmp_path)
    by = {r.category: r for r in rows}
    lap, oven = by["laptop"], by["oven"]
    assert lap.refined_rot_deg is None and lap.refined_met is None and lap.network_rot_deg is None and lap.network_met is None
    assert oven.network_ratio == pytest.approx([0.9, 0.8]) and oven.network_met is True
    assert oven.network_axis_deg == pytest.approx(net_axis)
    assert oven.refined_ratio == pytest.approx([0.5, 1.5]) and oven.refined_met is False
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
    assert f"| {refined[0]:.2f} / {refined[1]:.2f}, 0.5 / 1.5x (**not met**) |" in md and "- (no `--refine template` row)" in md
    assert f"| {net_rot[0]:.2f} / {net_rot[1]:.2f}, 0.9 / 0.8x (met); axis {net_axis[0]:.2f}, 3.0x |" in md
    assert "- (no `--refine network` row)" in md


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
    limits = text.split("## What limits the targets")[1]
    assert "| oven | " in limits and "| laptop | " not in limits  # one row per category with a report


def _target_row(category, rot):
    from ancsh.studies.targets import TargetRow

    paper = PAPER_TABLE1[category]["ANCSH"]
    return TargetRow(category, tuple(f"p{i}" for i in range(len(rot))), ("j0",), 10, tuple(rot), (1.0,),
                     tuple(paper["rot_deg"]), tuple(paper["axis_deg"]), 0, None, "0" * 64, None)


def test_budget_projection_follows_the_runs_own_power_laws():
    rng = np.random.default_rng(11)
    b_pose, b_npcs, own, parent = -rng.uniform(0.2, 0.6), -rng.uniform(0.1, 0.4), 40.0, 30.0
    minutes = np.linspace(5.0, own, 6)
    pose = [{"minutes": float(t), "score": float(20.0 * t ** b_pose)} for t in minutes]  # an exact power law
    paper = PAPER_TABLE1["oven"]["ANCSH"]["rot_deg"]
    rot = [p * k for p, k in zip(paper, (3.0, 2.0))]  # the worst part is 3x the paper's
    weights_row = {"train_min": own, "parent_min": parent, "curve": {"exponent": b_npcs}, "pose_curve": pose}
    proj = budget_projection(_target_row("oven", rot), weights_row, roll_gain=0.4)
    left = TRAINING_BUDGET_MIN - own - parent
    assert proj.needed == pytest.approx(1 / 3) and proj.left_min == pytest.approx(left) and proj.roll_gain == 0.4
    assert proj.pose_exponent == pytest.approx(b_pose)
    assert proj.pose_factor == pytest.approx(((own + left) / own) ** b_pose)
    assert proj.npcs_factor == pytest.approx(((own + left) / own) ** b_npcs)
    assert proj.reachable is (min(proj.pose_factor, proj.npcs_factor) <= 1 / 3)
    # a flat pose curve projects no gain; a spent budget projects none either
    flat = dict(weights_row, pose_curve=[{"minutes": float(t), "score": 9.0} for t in minutes], curve=None)
    assert budget_projection(_target_row("oven", rot), flat).pose_factor == pytest.approx(1.0)
    spent = dict(weights_row, parent_min=TRAINING_BUDGET_MIN)
    p_spent = budget_projection(_target_row("oven", rot), spent)
    assert p_spent.left_min == 0 and p_spent.npcs_factor == pytest.approx(1.0) and p_spent.reachable is False
    met = budget_projection(_target_row("oven", [p * 0.5 for p in paper]), weights_row)
    assert met.needed == pytest.approx(2.0) and met.reachable is True
    md = "\n".join(limit_lines([p_spent, met]))
    assert "**projected not to reach it**" in md and "met already" in md
    # the shipped refiner's and the unshipped runs' minutes are spent budget too
    both = budget_projection(_target_row("oven", rot), weights_row, unshipped_min=50.0, refiner_min=100.0)
    assert both.left_min == pytest.approx(left - 150.0)


def test_roll_gains_keep_only_rows_measured_on_the_shipped_weights(tmp_path):
    from ancsh.learned.network.weights import weights_path
    from ancsh.outputs import file_sha256

    sha = file_sha256(weights_path("laptop"))
    rows = {"laptop": {"category": "laptop", "weights_sha256": sha, "gain_mean": 0.93},
            "oven": {"category": "oven", "weights_sha256": "0" * 64, "gain_mean": 0.3},  # other weights
            "aug": {"category": "laptop", "weights_sha256": sha, "gain_mean": 0.5},  # not labelled by its category
            "laptop: ground truth": {"category": "laptop", "weights_sha256": None, "gain_mean": 1.0}}
    path = tmp_path / "roll_equivariance.json"
    path.write_text(json.dumps({"rows": rows}))
    assert roll_gains(path) == {"laptop": 0.93}
    assert roll_gains(tmp_path / "none.json") == {}
    path.write_text("[1")
    with pytest.raises(ValueError, match="roll_equivariance.json"):
        roll_gains(path)


def test_train_test_ratios_average_parts_of_the_shipped_weights_procedural_rows(tmp_path):
    from ancsh.learned.network.weights import weights_path
    from ancsh.outputs import file_sha256

    sha = file_sha256(weights_path("laptop"))
    row = lambda cat, split, inst, rot, w=sha: {"category": cat, "split": split, "instances": inst,  # noqa: E731
                                                "weights_sha256": w, "rot_deg": rot}
    results = [row("laptop", "procedural", "test", [4.0, 3.0]), row("laptop", "procedural", "train", [2.0, 3.0]),
               row("laptop", "real", "test", [9.0, 9.0]), row("laptop", "real", "train", [1.0, 1.0]),  # real: not read
               row("oven", "procedural", "test", [4.0, 4.0], "0" * 64), row("oven", "procedural", "train", [2.0, 2.0], "0" * 64),
               row("drawer", "procedural", "test", [3.0] * 4, file_sha256(weights_path("drawer")))]  # no training row
    path = tmp_path / "train_test_gap.json"
    path.write_text(json.dumps({"results": results}))
    assert train_test_ratios(path) == {"laptop": pytest.approx(1.5)}  # mean of 2.0 and 1.0
    assert train_test_ratios(tmp_path / "none.json") == {}
    path.write_text("{}")
    with pytest.raises(ValueError, match="train_test_gap.json"):
        train_test_ratios(path)


def test_unshipped_runs_spend_the_budget(tmp_path):
    """Minutes of runs that were not shipped are read from the ledger and count as spent."""
    from ancsh.studies.targets import unshipped_minutes

    ledger = tmp_path / "unshipped.json"
    ledger.write_text(json.dumps({"runs": [{"category": "oven", "minutes": 30}, {"category": "oven", "minutes": 12.5},
                                           {"category": "drawer", "minutes": 5}]}))
    assert unshipped_minutes(ledger) == {"oven": 42.5, "drawer": 5.0}
    assert unshipped_minutes(tmp_path / "absent.json") == {}
    rot = [4.0, 5.0]
    row = {"train_min": 60.0, "parent_min": 100.0, "curve": None, "pose_curve": []}
    plain = budget_projection(_target_row("oven", rot), row)
    spent = budget_projection(_target_row("oven", rot), row, unshipped_min=42.5)
    assert plain.left_min == pytest.approx(TRAINING_BUDGET_MIN - 160.0)
    assert spent.left_min == pytest.approx(TRAINING_BUDGET_MIN - 202.5)
    ledger.write_text(json.dumps({"runs": [{"category": "oven"}]}))
    with pytest.raises(ValueError, match="runs\\[0\\]"):
        unshipped_minutes(ledger)
    ledger.write_text(json.dumps({"runs": [{"category": "oven", "minutes": -1}]}))
    with pytest.raises(ValueError, match="minutes"):
        unshipped_minutes(ledger)


def test_a_refiners_minutes_are_its_lineage_beyond_the_first_stage():
    from ancsh.studies.targets import refiner_minutes

    rows = [dict(kind="ancsh", refiner=False, category="oven", train_min=20.0, parent_min=200.0),
            dict(kind="ancsh", refiner=True, category="oven", train_min=130.0, parent_min=220.0),  # from the first stage
            dict(kind="ancsh", refiner=False, category="wm", train_min=40.0, parent_min=165.0),
            dict(kind="ancsh", refiner=True, category="wm", train_min=68.0, parent_min=362.0),  # from an earlier refiner
            dict(kind="direct_voting", refiner=False, category="wm", train_min=15.0, parent_min=0.0)]
    assert refiner_minutes(rows) == pytest.approx({"oven": 130.0, "wm": 68.0 + 362.0 - 205.0})
    # the wm first stage fine-tuned again (30 more minutes) after its refiner: the refiner's lineage holds the earlier 205
    rows[2] = dict(rows[2], train_min=30.0, parent_min=205.0)
    assert refiner_minutes(rows)["wm"] == pytest.approx(68.0 + 362.0 - 235.0)  # without the ledger entry: 30 lost
    assert refiner_minutes(rows, {"wm": 205.0}) == pytest.approx({"oven": 130.0, "wm": 68.0 + 362.0 - 205.0})


def test_refiner_roots_are_read_from_the_ledger(tmp_path):
    from ancsh.studies.targets import refiner_roots

    ledger = tmp_path / "unshipped.json"
    assert refiner_roots(ledger) == {}
    ledger.write_text(json.dumps({"runs": []}))
    assert refiner_roots(ledger) == {}
    ledger.write_text(json.dumps({"runs": [], "refiner_first_stage_min": {"wm": 204.5}}))
    assert refiner_roots(ledger) == {"wm": 204.5}
    for bad, match in (({"wm": "x"}, "refiner_first_stage_min.wm"), ({"wm": -1}, ">= 0"), ([1], "expected")):
        ledger.write_text(json.dumps({"runs": [], "refiner_first_stage_min": bad}))
        with pytest.raises(ValueError, match=match):
            refiner_roots(ledger)
