"""The fit-translation study: its tables from known records, its variants, and one real frame through it."""

import numpy as np
import pytest

from ancsh.cli.bench.fit_translation import main
from ancsh.studies.fit_translation import measure, tables


def _record(method, level, cat, trans, rot=1.0):
    part = dict(name="p", rot=rot, trans=trans, scale_rel=0.01, signed_scale=-0.01, centroid_trans=trans / 2, lever=0.3)
    return dict(cat=cat, frame=0, level=level, method=method, ok=True, parts=[part, dict(part, trans=3 * trans)])


def test_tables_average_parts_and_frames_per_method_and_level():
    recs = [_record("a", "low", "laptop", 0.01), _record("a", "low", "laptop", 0.03), _record("b", "low", "laptop", 0.1),
            dict(cat="laptop", frame=1, level="low", method="b", ok=False)]
    lines = tables(recs)
    assert lines[0] == "\n## low: all parts mean"
    # method a: parts 0.01, 0.03 and 0.03, 0.09 -> mean 0.04; per part 0.02 and 0.06
    assert "| a | 1.00 | 0.0400 | 0.0100 | 0.0100 | -0.0100 |" in lines  # centroid: 0.005, 0.015 in both parts
    assert "| laptop | a | 0.0200, 0.0600 | 0.0100, 0.0100 | 1.00, 1.00 | -0.0100, -0.0100 |" in lines
    assert any(line.startswith("| b | 1.00 | 0.2000 |") for line in lines)  # the failed fit is left out


def test_an_unknown_variant_is_refused():
    with pytest.raises(ValueError, match="variant"):
        measure(1, ("laptop",), variant="nope")


@pytest.mark.slow
def test_one_frame_through_the_reverse_variant(tmp_path, capsys):
    out = tmp_path / "recs.json"
    assert main(["measure", "--variant", "reverse", "--frames", "1", "--categories", "laptop", "--out", str(out)]) == 0
    assert main(["tables", str(out)]) == 0
    text = capsys.readouterr().out
    assert "## high: all parts mean" in text and "| exact reverse scale |" in text
    import json

    recs = json.loads(out.read_text())
    assert {r["level"] for r in recs} == {"low", "realistic", "high"} and all(r["ok"] for r in recs)
    gt = [p["trans"] for r in recs if r["method"] == "gt_refit reverse" for p in r["parts"]]
    assert np.all(np.isfinite(gt)) and max(gt) < 0.1  # the oracle's true inliers: a good fit


def test_the_sources_variant_switches_off_one_corruption_at_a_time():
    from dataclasses import asdict

    from ancsh.studies.fit_translation import LEVEL_INDEX, _levels

    levels = _levels("sources")
    real = asdict(levels["realistic"])
    changed = {name: {k for k, v in asdict(c).items() if v != real[k]} for name, c in levels.items()}
    assert changed == {"realistic": set(), "realistic_no_flips": {"flip_fraction"},
                       "realistic_no_outliers": {"outlier_fraction"}, "realistic_no_warp": {"npcs_warp"},
                       "realistic_exact_joints": {"axis_sigma_deg", "pivot_sigma", "naocs_sigma"},
                       "realistic_no_npcs_noise": {"npcs_sigma"}}
    assert all(v == 0 for name, c in levels.items() for k, v in asdict(c).items() if k in changed[name])
    assert {LEVEL_INDEX[name] for name in levels} == {LEVEL_INDEX["realistic"]}  # one stream: only the knob differs


def test_evaluate_with_sets_the_fit_defaults_inside_its_block_and_refuses_bad_fields(capsys):
    import ancsh.solvers
    from ancsh.cli.bench.fit_translation import fit_config_defaults
    from ancsh.solvers.fit import FitConfig

    from ancsh.solvers.formulations import DEFAULT_OBJECTIVE

    from ancsh.learned.inference.provider import LearnedProvider

    own = LearnedProvider.fit_config
    with fit_config_defaults({"npcs_bias_weight": 0.02, "npcs_scale_bias": False}):
        c = ancsh.solvers.FitConfig()
        assert (c.npcs_bias_weight, c.npcs_scale_bias, c.npcs_stretch_bias) == (0.02, False, False)
        assert ancsh.solvers.FitConfig(npcs_bias_weight=0.1).npcs_bias_weight == 0.1  # the caller's field wins
        stub = type("Stub", (), {"category": "laptop"})()  # the networks' fits: their objective, then the defaults
        assert LearnedProvider.fit_config(stub) == FitConfig.default_for("learned", "laptop", npcs_bias_weight=0.02,
                                                                         npcs_scale_bias=False)
        assert LearnedProvider.fit_config(stub, npcs_bias_weight=0.1).npcs_bias_weight == 0.1
    assert ancsh.solvers.FitConfig is FitConfig and LearnedProvider.fit_config is own
    assert FitConfig().npcs_bias_weight == DEFAULT_OBJECTIVE.npcs_bias_weight
    for bad, says in (("{nope", "not JSON|Expecting"), ("[1]", "JSON object"), ('{"no_such_field": 1}', "no_such_field"),
                      ('{"npcs_scale_bias": false, "npcs_stretch_bias": true}', "needs the NPCS scale biases")):
        with pytest.raises(SystemExit) as e:
            main(["evaluate-with", bad, "evaluate", "--help"])
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert "fit_config:" in err and any(s in err for s in says.split("|")), err
    assert ancsh.solvers.FitConfig is FitConfig


def test_the_stretch_variant_sets_the_linear_biases_beside_the_default_and_per_part_fits():
    from dataclasses import asdict

    from ancsh.studies.fit_translation import _levels, _methods

    methods = _methods("stretch")
    stretched = [m for m in methods if "stretch" in m]
    assert {"per_part", "exact (default)", "exact npcs_bias+scale 0.01"} <= set(methods) and len(stretched) == 4
    closure = {name: methods[name].__closure__ for name in stretched}
    configs = [c.cell_contents for cells in closure.values() for c in cells if type(c.cell_contents).__name__ == "FitConfig"]
    assert len(configs) == 4 and all(c.npcs_stretch_bias and c.npcs_scale_bias and c.npcs_bias_weight > 0 for c in configs)
    levels = _levels("stretch")
    real = asdict(levels["realistic"])
    assert set(levels) == {"realistic", "realistic_no_npcs_noise"}
    assert {k for k, v in asdict(levels["realistic_no_npcs_noise"]).items() if v != real[k]} == {"npcs_sigma"}
