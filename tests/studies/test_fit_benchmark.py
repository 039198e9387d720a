"""``ancsh bench fit`` on a tiny configuration: runs in-process and writes its report files."""

import argparse
import json

import numpy as np
import pytest

from ancsh.cli.bench import fit as bench_cli
from ancsh.studies import fit as bench


def test_registers_a_fit_parser():
    parser = argparse.ArgumentParser()
    bench_cli.register(parser.add_subparsers())
    args = parser.parse_args(["fit", "--quick", "--levels", "none,high"])
    assert args.func is bench_cli.run and args.quick and args.levels == "none,high"


def test_quick_path_writes_markdown_and_json(tmp_path, capsys):
    """Through the real command line (``ancsh bench fit``), in-process."""
    from ancsh.cli import main

    out = tmp_path / "results" / "fit.md"
    assert main(["bench", "fit", "--quick", "--json", "--frames", "1", "--categories", "laptop", "--methods", "official",
                 "--official-hypotheses", "20", "--out", str(out)]) == 0
    text = out.read_text()
    assert "ancsh bench fit --quick --json --frames 1 --categories laptop --methods official" in text
    assert "| laptop | official | 100% |" in text
    # the translation section (issue 13 item 7): what the metric measures, with a scale column
    assert "## Translation error and the scale" in text and "docs/results/fit_translation.md" in text
    assert "| method | trans | scale error | rot (deg) |" in text
    payload = json.loads(out.with_suffix(".json").read_text())
    assert payload["config"]["levels"] == ["none", "realistic"]
    assert {r["level"] for r in payload["summary"]} == {"none", "realistic"}
    assert payload["overall"]["realistic"][0]["method"] == "official"
    nf = payload["headline"]["noise_free"]["official"]
    assert nf["failed"] == 0 and max(nf["rot_rad"], nf["trans"], nf["scale_rel"]) < 1e-6
    assert "wrote" in capsys.readouterr().out


def test_surface_frames_fallback_and_summary():
    config = bench.BenchConfig(categories=("oven",), frames_per_category=1, levels=("none", "high"), num_points=150,
                               official_hypotheses=10, methods=("official",), rendered=False)
    frames = bench.load_frames(config)
    assert [f.source for f in frames] == ["surface"]
    report = bench.run_benchmark(config, frames=frames)
    rows = bench.summarize(report)
    assert [(r["level"], r["method"]) for r in rows] == [("none", "official"), ("high", "official")]
    none, high = rows
    assert none["rot_deg"][0] < 1e-6 and high["rot_deg"][0] > none["rot_deg"][0]
    assert none["ms_median"] > 0 and none["ms_p90"] >= none["ms_median"]
    head = bench.headline(report)
    assert head["level"] == "high" and np.isnan(head.get("speedup", np.nan))


def test_config_errors():
    with pytest.raises(ValueError, match="levels"):
        bench.BenchConfig(levels=("medium",))
    with pytest.raises(ValueError, match="frames_per_category"):
        bench.BenchConfig(frames_per_category=0)
    with pytest.raises(ValueError, match="categories: unknown"):
        bench.load_frames(bench.BenchConfig(categories=("toaster",)))
    with pytest.raises(ValueError, match="methods: unknown"):
        bench.available_methods(bench.BenchConfig(methods=("magic",)))


def test_headline_compares_translation_part_by_part():
    from ancsh.studies.fit.report import _translation_by_part

    def rec(method, trans, rot):
        return {"method": method, "level": "realistic", "ok": True, "category": "laptop",
                "parts": [{"name": "base", "trans": trans[0], "rot_deg": rot[0]},
                          {"name": "display", "trans": trans[1], "rot_deg": rot[1]}]}

    recs = [rec("exact", (0.01, 0.004), (2.0, 2.0)), rec("per_part", (0.012, 0.005), (3.0, 4.0)),
            rec("official", (0.011, 0.006), (2.5, 2.5))]
    table, met = _translation_by_part(recs, "realistic", "exact", ["per_part", "official"])
    assert met and table["laptop/base"]["per_part"] == {"trans": 0.012, "rot_deg": 3.0}
    recs[1]["parts"][1]["trans"] = 0.003  # per-part's display translation lower than the exact fit's
    assert not _translation_by_part(recs, "realistic", "exact", ["per_part", "official"])[1]


def test_exact_config_reaches_the_exact_methods_only(tmp_path, capsys):
    """``--exact-config``: the exact formulations fit with those FitConfig fields (the NPCS biases move their
    result), the others with the defaults; the command line in the report re-runs it; bad values are refused."""
    from ancsh.cli import main

    config = bench.BenchConfig(categories=("laptop",), frames_per_category=1, levels=("realistic",), num_points=300,
                               methods=("per_part/umeyama", "exact_reduced/lm"))
    from dataclasses import replace

    biased = replace(config, exact_config={"npcs_bias_weight": 0.02, "npcs_scale_bias": False})  # not the default's
    assert biased.exact_config == (("npcs_bias_weight", 0.02), ("npcs_scale_bias", False))
    frames = bench.load_frames(config)
    plain_recs = bench.run_benchmark(config, frames=frames)["records"]
    biased_recs = bench.run_benchmark(biased, frames=frames)["records"]
    by = lambda recs, m: [(r["parts"], r["joints"]) for r in recs if r["method"] == m]  # noqa: E731
    assert by(plain_recs, "per_part/umeyama") == by(biased_recs, "per_part/umeyama")
    assert by(plain_recs, "exact_reduced/lm") != by(biased_recs, "exact_reduced/lm")
    out = tmp_path / "fit.md"
    assert main(["bench", "fit", "--frames", "1", "--categories", "laptop", "--levels", "realistic", "--methods",
                 "exact_reduced/lm", "--exact-config", '{"npcs_bias_weight": 0.02}', "--out", str(out)]) == 0
    assert """--exact-config '{"npcs_bias_weight": 0.02}'""" in out.read_text()
    for bad, why in (("[1]", "expected a JSON object"), ("{x", "not JSON"), ('{"bogus": 1}', "exact_config")):
        capsys.readouterr()
        assert main(["bench", "fit", "--quick", "--exact-config", bad, "--out", str(tmp_path / "x.md")]) == 2
        assert why in capsys.readouterr().err


def test_quick_says_it_is_not_the_verdict_in_the_page_and_on_stdout(tmp_path, capsys):
    """Issue 63: ``--quick`` stays quick and marks itself as not the verdict (the page's head and stdout); the per-part
    table of the default fit against the official scheme is there, with the previous objective beside it."""
    from ancsh.cli import main

    out = tmp_path / "fit.md"
    assert main(["bench", "fit", "--quick", "--frames", "1", "--categories", "laptop", "--methods",
                 f"{bench.DEFAULT_METHOD},{bench.PREVIOUS_METHOD},official", "--official-hypotheses", "20",
                 "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    head = out.read_text().split("## Targets")[0]
    assert "NOT THE VERDICT" in head and "--quick" in head and "NOT THE VERDICT" in stdout
    text = out.read_text()
    assert "## The default fit against the official scheme, per part" in text
    assert "| laptop | base |" in text and "| laptop | display |" in text
    assert "rot previous" in text and "official / default" in text


def _verdict_records(frames, default_rot=2.0):
    recs = []
    for f in range(frames):
        for method, rot, trans, ms in ((bench.DEFAULT_METHOD, default_rot, 0.004, 10.0),
                                       (bench.PREVIOUS_METHOD, 2.2, 0.006, 8.0), ("official", 2.5, 0.005, 1000.0)):
            recs.append({"method": method, "level": "realistic", "ok": True, "category": "laptop", "frame": f,
                         "time_ms": ms, "parts": [{"name": "base", "trans": trans, "rot_deg": rot},
                                                  {"name": "display", "trans": trans, "rot_deg": rot}]})
    return {"records": recs, "methods": [bench.DEFAULT_METHOD, bench.PREVIOUS_METHOD, "official"]}


def test_the_verdict_needs_its_frames_and_every_part_below_in_rotation_and_translation():
    v = bench.verdict(_verdict_records(bench.VERDICT_FRAMES))
    assert v["is_verdict"] and v["met"] and (v["below"], v["parts_total"]) == (2, 2)
    assert v["speed"]["all"]["official_over_default"] == pytest.approx(100.0)
    assert v["speed"]["all"]["default_over_previous"] == pytest.approx(1.25)
    assert bench.verdict_line(v).startswith("Verdict: met")
    assert not bench.verdict(_verdict_records(bench.VERDICT_FRAMES), quick=True)["is_verdict"]
    few = bench.verdict(_verdict_records(bench.VERDICT_FRAMES - 1))
    assert not few["is_verdict"] and bench.verdict_line(few).startswith("NOT THE VERDICT")
    worse = bench.verdict(_verdict_records(bench.VERDICT_FRAMES, default_rot=2.6))  # rotation above the official's
    assert worse["is_verdict"] and not worse["met"] and worse["below"] == 0
    assert "NOT met" in bench.verdict_line(worse)
    assert bench.verdict({"records": [], "methods": []}) is None
    changed = dict(_verdict_records(bench.VERDICT_FRAMES), config={"exact_config": [["npcs_bias_weight", 0.02]]})
    assert not bench.verdict(changed)["is_verdict"] and "--exact-config" in bench.verdict_line(bench.verdict(changed))


def test_the_full_run_has_the_verdicts_frames_and_the_previous_objective_method():
    assert bench.FULL.frames_per_category >= bench.VERDICT_FRAMES and bench.QUICK.frames_per_category < bench.VERDICT_FRAMES
    names = [m.name for m in bench.available_methods(bench.BenchConfig(categories=("laptop",)))]
    assert bench.DEFAULT_METHOD in names and bench.PREVIOUS_METHOD in names
    from ancsh.solvers.fit import FORMULATIONS

    assert bench.DEFAULT_METHOD == f"exact_reduced/{FORMULATIONS['exact_reduced'].solvers[0]}"  # fit's own default
    assert bench.PREVIOUS_METHOD == f"{bench.DEFAULT_METHOD}:previous"


def test_speed_section_gives_mean_and_median_ratios_per_category():
    from ancsh.studies.fit.speed import speed_by_category, speed_lines

    recs = [{"category": c, "level": "realistic", "method": m, "time_ms": t}
            for c, times in (("oven", {"official": [100.0, 300.0, 200.0], "exact_reduced/lm": [1.0, 1.0, 4.0]}),
                             ("box", {"exact_reduced/lm": [2.0]}))
            for m, ts in times.items() for t in ts]
    report = {"records": recs + [dict(recs[0], level="none", time_ms=1e6)],
              "methods": ["exact_reduced/lm", "official"]}
    rows = speed_by_category(report, "realistic")
    assert [(r["category"], r["method"]) for r in rows] == [("box", "exact_reduced/lm"), ("oven", "exact_reduced/lm")]
    box, oven = rows
    assert "ratio_mean" not in box and box["ms_mean"] == 2.0
    assert oven["ms_mean"] == 2.0 and oven["ms_median"] == 1.0 and oven["frames"] == 3
    assert oven["ratio_mean"] == pytest.approx(100.0) and oven["ratio_median"] == pytest.approx(200.0)
    text = "\n".join(speed_lines(report, "realistic"))
    assert "## Speed per category (`realistic`)" in text and "| oven | exact_reduced/lm | 3 | 2.00 | 1.00 | 200.0 | 100 | 200 |" in text
    assert speed_lines({"records": [], "methods": []}, "realistic") == []
