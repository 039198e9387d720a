"""ancsh evaluate: the NAOCS baseline, statistics, the paper tables, and the --quick report."""

import dataclasses
import json

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.data.procedural import CATEGORY_INFO, PAPER_CATEGORIES
from ancsh.evaluation import evaluate_fit
from ancsh.studies import table1 as ev
from ancsh.studies.table1.statistics import AXIS_FLIP_DEG, axis_tail
from ancsh.solvers.types import Correspondences, Observation


@pytest.mark.parametrize("category", ["laptop", "eyeglasses"])
def test_naocs_baseline_recovers_ground_truth_from_ground_truth_naocs(category):
    gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=2))
    frame = gen.frame(0)
    gt = frame.gt
    corr = Correspondences.from_ground_truth(gt)
    obs = Observation(frame.points)
    for naocs in (None, gt.naocs):  # per-part maps of corr, or the per-point NAOCS
        r = ev.fit_naocs(obs, corr, naocs=naocs, rng=0)
        assert r.ok and r.formulation == "naocs" and r.boxes_cam == ()
        rec = evaluate_fit(r, gt, frame.part_names, frame.joint_names)
        for p in rec.parts:
            assert p.rot_deg < 1e-5 and p.trans < 1e-8 and p.scale_rel < 1e-8 and np.isnan(p.iou)
        for j in rec.joints:
            assert j.state_err < 1e-5 and j.axis_deg < 1e-5 and not j.line_dist > 1e-8
    # the baseline's input: NAOCS coordinates with identity NPCS -> NAOCS maps
    nc = ev.naocs_correspondences(corr)
    np.testing.assert_allclose(nc.npcs, gt.naocs, atol=1e-12)
    assert np.all(nc.npcs_scale == 1) and np.all(nc.npcs_translation == 0)
    with pytest.raises(ValueError, match="naocs"):
        ev.naocs_correspondences(corr, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="key"):
        ev.fit_method("nope", obs, corr)


def test_paper_tables_match_the_categories():
    for category in PAPER_CATEGORIES:
        info = CATEGORY_INFO[category]
        M, K = len(info.part_names), len(info.joint_names)
        for row in ev.PAPER_TABLE1[category].values():
            for name, values in row.items():
                assert len(values) == (M if name in ev.PART_METRICS else K), (category, name)
        for row in ev.PAPER_TABLE2[category].values():
            for values in row.values():
                assert len(values) == K


def _record(visibility, rot, ok=True, axis_deg=1.0):
    parts = [{"name": f"p{j}", "rot_deg": r, "trans": 0.1 * r, "scale_rel": 0.0, "iou": 0.5} for j, r in enumerate(rot)]
    joints = [{"name": "j0", "type": "revolute", "state_err": rot[1] - rot[0], "axis_deg": axis_deg, "line_dist": float("nan")}]
    return {"visibility": visibility, "network_ms": 1.0, "generate_ms": 1.0,
            "methods": {"per_part": {"ok": ok, "parts": parts if ok else [], "joints": joints if ok else [], "fit_ms": 2.0}}}


def test_axis_tail_counts_wrong_axes_apart_from_the_rest():
    """Frames above the threshold are counted per joint; the rest's mean leaves them and NaN out."""
    values = np.array([[1.0, 50.0], [3.0, np.nan], [89.0, 2.0], [45.0, 4.0]])
    tail = axis_tail(values)
    assert tail == {"threshold_deg": AXIS_FLIP_DEG, "over": [1, 1], "frames": [4, 3],
                    "mean_within": [pytest.approx((1 + 3 + 45) / 3), pytest.approx(3.0)]}
    assert axis_tail(np.full((2, 1), 90.0))["mean_within"] == [None]
    assert axis_tail(values, threshold_deg=0.5)["over"] == [4, 3]
    with pytest.raises(ValueError, match="values"):
        axis_tail(np.ones(3))
    recs = [_record([0.5, 0.5], [1.0, 2.0], axis_deg=a) for a in (2.0, 4.0, 88.0)] + [
        _record([0.5, 0.5], [1.0, 2.0], ok=False, axis_deg=120.0)]
    evaluation = {"category": "x", "records": recs, "timing": {"wall_s": 1.0},
                  "settings": {"methods": ["per_part"], "part_names": ["p0", "p1"], "joint_names": ["j0"]}}
    row = ev.summarize(evaluation)["methods"]["per_part"]
    assert row["axis_tail"]["over"] == [1] and row["axis_tail"]["frames"] == [3]  # the failed fit left out
    assert row["axis_tail"]["mean_within"] == [pytest.approx(3.0)] and row["axis_deg"]["mean"] == [pytest.approx(94 / 3)]


def test_error_budget_recovers_a_known_npcs_rotation_and_matches_the_fit():
    from ancsh.geometry import axis_angle_matrix, geodesic_angle, umeyama
    from ancsh.learned.inference.provider import Prediction

    frame = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=3)).frame(0)
    gt = frame.gt
    N, M = gt.npcs.shape[0], len(gt.T_cam_npcs)
    rng = np.random.default_rng(0)
    angles = np.radians([4.0, 11.0])
    npcs = rng.normal(size=(N, M, 3))  # junk for the points of the other part
    for j, a in enumerate(angles):  # part j's points: true NPCS rotated by a known angle and shifted
        m = gt.part_labels == j
        npcs[m, j] = gt.npcs[m] @ axis_angle_matrix(rng.normal(size=3), a).T + 0.05
    seg = np.eye(M)[gt.part_labels]
    seg[:10] = np.eye(M)[1 - gt.part_labels[:10]]  # 10 points mislabelled
    pred = Prediction(seg_prob=seg, npcs=npcs, scale=None, translation=None, assoc_prob=np.ones((N, 2)), joint=np.zeros((N, 7)))
    b = ev.npcs_error_budget(pred, gt)
    assert b["seg_acc"] == pytest.approx(1 - 10 / N)
    for j, p in enumerate(b["parts"]):
        assert p["npcs_rot_deg"] == pytest.approx(np.degrees(angles[j]), abs=1e-6)
        assert p["npcs_resid"] < 1e-9 and p["npcs_err"] > 0.05
        # the orientation error is the rotation error of an Umeyama fit of the predicted NPCS to the points
        m = gt.part_labels == j
        fit = umeyama(npcs[m, j], frame.points[m])
        err = np.degrees(geodesic_angle(fit.rotation, gt.T_cam_npcs[j].rotation))
        assert err == pytest.approx(p["npcs_rot_deg"], abs=1e-5)
    few = dataclasses.replace(gt, part_labels=np.where(np.arange(N) < 3, 1, 0))  # part 1 has 3 points
    assert np.isnan(ev.npcs_error_budget(pred, few)["parts"][1]["npcs_rot_deg"])


def test_summary_means_medians_failures_and_occlusion_bins():
    recs = [_record([0.12, 0.9], [1.0, 2.0]), _record([0.13, 0.9], [3.0, 10.0]),
            _record([0.42, 0.9], [5.0, 6.0]), _record([0.42, 0.9], [99.0, 99.0], ok=False)]
    evaluation = {"category": "x", "records": recs, "timing": {"wall_s": 1.0},
                  "settings": {"methods": ["per_part"], "part_names": ["p0", "p1"], "joint_names": ["j0"]}}
    s = ev.summarize(evaluation)
    row = s["methods"]["per_part"]
    assert row["failures"] == 1 and row["frames"] == 4
    np.testing.assert_allclose(row["rot_deg"]["mean"], [3.0, 6.0])
    np.testing.assert_allclose(row["rot_deg"]["median"], [3.0, 6.0])
    np.testing.assert_allclose(row["iou"]["mean"], [50.0, 50.0])
    np.testing.assert_allclose(row["state_err"]["mean"], [(1 + 7 + 1) / 3])
    assert row["line_dist"]["mean"] == [None]  # no finite value
    occ = s["occlusion"]["parts"][0]
    b = int(np.digitize(0.12, ev.OCCLUSION_EDGES)) - 1
    assert occ["counts"][b] == 2 and occ["per_part"]["rot_deg"][b] == pytest.approx(2.0)
    b2 = int(np.digitize(0.42, ev.OCCLUSION_EDGES)) - 1
    assert occ["counts"][b2] == 2 and occ["per_part"]["rot_deg"][b2] == pytest.approx(5.0)  # failure left out


def test_report_json_reads_back_with_one_line_per_frame_entry(tmp_path):
    """Scenario: a report dict with NaN, numpy numbers and per-frame arrays: the file reads back with
    json.loads (NaN as null), nested settings one item a line, each per-frame entry on one line."""
    data = {"category": "x", "settings": {"frames": np.int64(2), "names": ["a", "b"], "empty": {}},
            "summary": {"rot_deg": {"mean": [1.5, float("nan")]}},
            "per_frame": {"instance": ["i0", "i1"], "per_part": {"rot_deg": [[1.0, 2.0], None]}}}
    path = ev.write_json(tmp_path / "r.json", data, one_line=("per_frame",))
    text = path.read_text()
    back = json.loads(text)
    assert back == ev.json_safe(data) and list(back) == ["category", "settings", "summary", "per_frame"]
    assert back["summary"]["rot_deg"]["mean"] == [1.5, None] and back["settings"]["frames"] == 2
    assert text == json.dumps(ev.json_safe({k: v for k, v in data.items() if k != "per_frame"}), indent=1)[:-2] + (
        ',\n "per_frame": {\n  "instance": ["i0", "i1"],\n  "per_part": {"rot_deg": [[1.0, 2.0], null]}\n }\n}\n')
    with pytest.raises(ValueError, match="one_line"):
        ev.write_json(tmp_path / "bad.json", data, one_line=("category",))


def test_quick_evaluation_writes_the_report(tmp_path):
    """Both refinements in one run: every method's row, on the same network output."""
    code = main(["evaluate", "--category", "laptop", "--quick", "--frames", "2", "--out", str(tmp_path), "--no-progress",
                 "--refine", "template", "network"])
    assert code == 0
    md = (tmp_path / "laptop.md").read_text()
    evaluated = ev.METHODS
    for label in [m.label for m in evaluated.values()] + ["paper: NPCS", "paper: NAOCS", "paper: ANCSH",
                                                           "Table 2", "Direct voting", "voted joints in NAOCS", "--frames 2",
                                                           "--refine template network", "category-template refinement: kept on",
                                                           "refinement network: `laptop_refine.pt`"]:
        assert label in md
    data = json.loads((tmp_path / "laptop.json").read_text())
    assert data["settings"]["frames"] == 2 and set(data["summary"]["methods"]) == set(evaluated)
    for row in data["summary"]["methods"].values():
        assert len(row["rot_deg"]["mean"]) == 2 and len(row["state_err"]["mean"]) == 1
    assert data["summary"]["methods"]["naocs"]["iou"]["mean"] == [None, None]  # no boxes for NAOCS
    assert data["paper"]["table1"]["ANCSH"]["rot_deg"] == [6.7, 4.3]
    assert list(data) == ["category", "command", "date", "ancsh_version", "settings", "summary", "paper", "per_frame"]
    assert set(data["per_frame"]) == {"instance", "visibility", *evaluated} and len(data["per_frame"]["instance"]) == 2
    for key in evaluated:  # per-frame axis errors, one per joint, and their tail in the summary and in Table 2
        axes = data["per_frame"][key]["axis_deg"]
        assert len(axes) == 2 and all(a is None or len(a) == 1 for a in axes)
        assert sum(data["summary"]["methods"][key]["axis_tail"]["frames"]) == sum(a is not None for a in axes)
    assert "Axis over 45°: frames (mean of the rest, °)" in md
    assert (tmp_path / "laptop_occlusion.png").stat().st_size > 0


def test_missing_weights_name_the_available_ones(monkeypatch, tmp_path):
    import ancsh.learned.network.weights as weights

    monkeypatch.setattr(weights, "WEIGHTS_DIR", tmp_path)
    with pytest.raises(FileNotFoundError, match="no shipped weights for 'laptop'; available: none"):
        ev.evaluate_category("laptop", frames=1, progress=False)
    with pytest.raises(ValueError, match="methods"):
        ev.evaluate_category("laptop", frames=1, methods=("bogus",), progress=False)
    with pytest.raises(ValueError, match="refine: expected None, one of"):
        ev.evaluate_category("laptop", frames=1, refine=("template", "icp"), progress=False)
    with pytest.raises(ValueError, match="category"):
        ev.evaluate_category("toaster", frames=1, progress=False)


def test_real_split_is_evaluated_beside_the_procedural_one(tmp_path, make_oven_urdf):
    """`evaluate --real`: the real test objects of a catalog are rendered instead of the procedural
    instances, and the report puts both splits side by side with their ratio."""
    from ancsh.data.catalog import Catalog, write_catalog
    from ancsh.data.importer import assign_splits, import_object

    objs = [import_object(make_oven_urdf(tmp_path / f"oven_{i}"), "oven") for i in range(2)]
    catalog = write_catalog(Catalog(tuple(assign_splits(objs))), tmp_path / "catalog.json")
    kw = dict(frames=2, methods=("per_part", "exact_reduced"), progress=False)
    proc = ev.evaluate_category("oven", **kw)
    real = ev.evaluate_category("oven", real=str(catalog), **kw)
    assert proc["settings"]["split"] == "procedural" and real["settings"]["split"] == "real"
    assert {r["instance"] for r in real["records"]} <= {o.name for o in objs}
    assert not {r["instance"] for r in proc["records"]} & {o.name for o in objs}
    text = ev.write_real_report(proc, ev.summarize(proc), real, ev.summarize(real), tmp_path / "out", command="test").read_text()
    assert "oven_0" in text and "| ANCSH-exact reduced (ours) | door |" in text and "x |" in text
    both = ev.write_report(proc, ev.summarize(proc), tmp_path / "both", command="test",
                           real=(real, ev.summarize(real)))["md"].read_text()
    assert "## The real test split beside the procedural one" in both and "| ANCSH-exact reduced (ours) | door |" in both
    alone = ev.write_report(proc, ev.summarize(proc), tmp_path / "alone", command="test")["md"].read_text()
    assert "real test split" not in alone
    # the JSON keeps the real split's summary, and the targets read both splits back from it
    from ancsh.studies.targets import collect_targets, target_lines

    rows, missing = collect_targets(tmp_path / "both")
    assert [r.category for r in rows] == ["oven"] and "laptop" in missing and "oven" not in missing
    (row,) = rows
    sp, sr = ev.summarize(proc), ev.summarize(real)
    assert row.rot_deg == pytest.approx(sp["methods"]["exact_reduced"]["rot_deg"]["mean"])
    assert row.real_rot_deg == pytest.approx(sr["methods"]["exact_reduced"]["rot_deg"]["mean"])
    assert row.real_ratio == pytest.approx(np.divide(row.real_rot_deg, row.rot_deg))
    assert row.paper_rot_deg == tuple(ev.PAPER_TABLE1["oven"]["ANCSH"]["rot_deg"]) and not row.stale
    assert row.real_frames == real["settings"]["frames"]
    (alone_row,), _ = collect_targets(tmp_path / "alone")
    assert alone_row.real_rot_deg is None and alone_row.real_ratio is None and alone_row.real_met is None
    md = target_lines(rows, missing, {"oven": (10.0, 5.0)})
    assert "| oven | base, door |" in md[2] and "10 + 5 |" in md[2] and "| current |" in md[2]
    assert "| 10 + 5 (+ 7) |" in target_lines(rows, missing, {"oven": (10.0, 5.0, 7.0)})[2]  # with its refiner's minutes
    with pytest.raises(ValueError, match="no real test object"):
        ev.evaluate_category("laptop", real=str(catalog), **kw)


def test_training_instances_are_evaluated_and_set_beside_the_test_ones(tmp_path):
    from ancsh.studies.train_test_gap import gap_rows, run_gap, write_gap_report

    with pytest.raises(ValueError, match="instances"):
        ev.evaluate_category("laptop", frames=1, methods=("exact_reduced",), instances="val", progress=False)
    results = run_gap(["laptop"], frames=2, real_frames=0, seed=3, progress=False)
    assert [(r["split"], r["instances"]) for r in results] == [("procedural", "test"), ("procedural", "train")]
    test, train = results
    assert train["settings"]["instances"] == "train" and test["settings"]["instances"] == "test"
    assert train["settings"]["test_instances"] > test["settings"]["test_instances"]  # 200 training, 20 test objects
    train_names = {FrameGenerator(GenerationConfig(category="laptop", split="train", seed=3)).frame(i).instance
                   for i in range(2)}
    test_names = {FrameGenerator(GenerationConfig(category="laptop", split="test", seed=3)).frame(i).instance
                  for i in range(2)}
    assert not train_names & test_names
    rows = gap_rows(results)
    assert len(rows) == 3 and "training instances" in rows[0] and "test / training" in rows[2]
    rot_tr = train["summary"]["methods"]["exact_reduced"]["rot_deg"]["mean"]
    rot_te = test["summary"]["methods"]["exact_reduced"]["rot_deg"]["mean"]
    assert rows[2].split("|")[5].strip() == " / ".join(f"{a / b:.2f}" for a, b in zip(rot_te, rot_tr))
    path = write_gap_report(results, tmp_path / "gap.md", command="ancsh bench train-test-gap")
    data = json.loads(path.with_suffix(".json").read_text())
    assert [r["instances"] for r in data["results"]] == ["test", "train"] and len(data["results"][1]["npcs_rot_deg"]) == 2


def test_the_real_split_can_be_every_imported_object(tmp_path):
    from ancsh.data.catalog import load_catalog
    from ancsh.data.paths import shared_data_dir

    if not (shared_data_dir() / "partnet_mobility").is_dir():
        pytest.skip("shared PartNet-Mobility data not available")
    catalog = load_catalog()
    every = {o.name for o in catalog.instances("laptop")}
    test = {o.name for o in catalog.instances("laptop", "test")}
    assert test < every  # the builtin catalog has laptops in both splits
    code = main(["evaluate", "--category", "laptop", "--frames", "2", "--formulations", "exact_reduced", "--real",
                 "builtin", "--real-all", "--out", str(tmp_path), "--no-progress"])
    assert code == 0
    real = json.loads((tmp_path / "laptop.json").read_text())
    md = (tmp_path / "laptop_real.md").read_text()
    assert "every imported object (train and test" in md and "--real-all" in md
    with pytest.raises(ValueError, match="real_split"):
        ev.evaluate_category("laptop", frames=1, real_split="all", progress=False)
    assert main(["evaluate", "--category", "laptop", "--frames", "1", "--real-all", "--out", str(tmp_path / "x")]) == 2
    assert real["settings"]["frames"] == 2
