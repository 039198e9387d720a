"""The learned provider's category-template refinement option (LearnedProvider(refine=...), predict_depth(refine=...))."""

import numpy as np
import pytest

from ancsh.data.templates import refine_default
from ancsh.learned.inference.provider import LearnedProvider
from ancsh.solvers import Observation, fit


def test_refine_option_is_checked_and_resolved():
    with pytest.raises(ValueError, match="refine"):
        LearnedProvider("laptop", refine="icp")
    p = LearnedProvider("laptop")
    assert p.refine_option is None and not p.refines()
    assert p.refines("template") and not p.refines("none") and not p.refines(None)
    assert p.refines("auto") == refine_default("laptop")
    assert LearnedProvider("laptop", refine="template").refines()
    with pytest.raises(ValueError, match="refine"):
        p.refines("always")
    assert refine_default("no_such_category") is False


def test_refine_off_returns_none_and_on_returns_a_fit_at_least_as_well_scored():
    from ancsh.data.generate import FrameGenerator, GenerationConfig

    fr = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0)).frame(0)
    obs = Observation(fr.points)
    p = LearnedProvider("laptop", refine="template")
    corr = p.correspond(obs)
    res = fit(obs, corr, "exact_reduced", rng=0)
    assert p.refine(obs, corr, res, refine="none") is None
    out = p.refine(obs, corr, res, rng=0)
    assert out.result.ok and out.template
    assert (out.accepted and out.score_refined < out.score_input) or (not out.accepted and out.result is res)
    assert np.all(np.isfinite(out.result.joint_states))


def _report(tmp_path, category, *, rot, rot_refined, state, state_refined, sha=None, generator=None):
    """A minimal ``ancsh evaluate`` report (the fields defaults_from_reports reads)."""
    import json

    from ancsh.learned.network.weights import weights_path
    from ancsh.outputs import file_sha256

    summary = {"methods": {"exact_reduced": {"rot_deg": {"mean": rot}, "state_err": {"mean": state}},
                           "template": {"rot_deg": {"mean": rot_refined}, "state_err": {"mean": state_refined}}}}
    from ancsh.data.procedural import generator_version

    settings = {"frames": 500, "weights_sha256": sha or file_sha256(weights_path(category)),
                "generator_version": generator_version(category) if generator is None else generator}
    (tmp_path / f"{category}.json").write_text(json.dumps({"command": f"ancsh evaluate --category {category}",
                                                            "settings": settings, "summary": summary}))


def test_refine_defaults_follow_the_rule_on_current_reports_only(tmp_path):
    import json

    from ancsh.studies.refinement import defaults_from_reports, install_defaults

    _report(tmp_path, "laptop", rot=[4.0, 4.0], rot_refined=[3.0, 3.5], state=[1.0], state_refined=[1.04])
    _report(tmp_path, "oven", rot=[4.0, 4.0], rot_refined=[3.0, 4.1], state=[1.0], state_refined=[0.9])
    _report(tmp_path, "drawer", rot=[3.0] * 4, rot_refined=[2.0] * 4, state=[0.02] * 3,
            state_refined=[0.02, 0.0211, 0.02])
    _report(tmp_path, "eyeglasses", rot=[4.0] * 3, rot_refined=[3.0] * 3, state=[1.0] * 2, state_refined=[1.0] * 2,
            sha="0" * 64)
    _report(tmp_path, "microwave", rot=[4.0] * 2, rot_refined=[3.0] * 2, state=[1.0], state_refined=[1.0], generator=1)
    got = {d.category: d for d in defaults_from_reports(tmp_path, ["laptop", "oven", "drawer", "eyeglasses", "safe",
                                                                   "microwave"])}
    assert got["laptop"].on and got["laptop"].frames == 500 and got["laptop"].rot_deg_refined == (3.0, 3.5)
    assert not got["oven"].on and "rotation" in got["oven"].reason  # a part got worse
    assert not got["drawer"].on and "state" in got["drawer"].reason  # one joint 5.5 % worse
    assert not got["eyeglasses"].on and "stale" in got["eyeglasses"].reason  # other weights
    assert not got["safe"].on and got["safe"].report is None  # no report
    assert not got["microwave"].on and "generator" in got["microwave"].reason  # frames of an older generator
    path = install_defaults(list(got.values()), "ancsh bench refine-defaults", tmp_path / "defaults.json")
    data = json.loads(path.read_text())
    assert data["categories"] == {"laptop": True, "oven": False, "drawer": False, "eyeglasses": False, "safe": False,
                                  "microwave": False}
    assert data["evidence"]["laptop"]["command"] == "ancsh evaluate --category laptop"
    with pytest.raises(ValueError, match="reports_dir"):
        defaults_from_reports(tmp_path / "missing")
