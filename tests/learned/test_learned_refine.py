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
    assert p.refines("auto") == (refine_default("laptop") is not None)
    assert LearnedProvider("laptop", refine="template").refines()
    with pytest.raises(ValueError, match="refine"):
        p.refines("always")
    assert refine_default("no_such_category") is None
    assert p.refine_choice("auto") == refine_default("laptop") and p.refine_choice("network") == "network"


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


def _report(tmp_path, category, *, rot, rot_refined, state, state_refined, sha=None, generator=None, network=None,
            real=None, refiner_sha=None):
    """A minimal ``ancsh evaluate`` report (the fields defaults_from_reports reads). ``network``: the refinement
    network's ``(rot, state)`` row; ``real``: the real split's ``{method: (rot, state)}``."""
    import json

    from ancsh.learned.network.weights import weights_path
    from ancsh.outputs import file_sha256

    def row(r, st):
        return {"rot_deg": {"mean": r}, "state_err": {"mean": st}}

    methods = {"exact_reduced": row(rot, state), "template": row(rot_refined, state_refined)}
    if network is not None:
        methods["network"] = row(*network)
    from ancsh.data.procedural import generator_version

    settings = {"frames": 500, "weights_sha256": sha or file_sha256(weights_path(category)),
                "generator_version": generator_version(category) if generator is None else generator,
                "refiner_sha256": refiner_sha or (file_sha256(weights_path(category, "refine"))
                                                  if weights_path(category, "refine").is_file() else None)}
    report = {"command": f"ancsh evaluate --category {category}", "settings": settings, "summary": {"methods": methods}}
    if real is not None:
        report["real"] = {"settings": {}, "summary": {"methods": {k: row(*v) for k, v in real.items()}}}
    (tmp_path / f"{category}.json").write_text(json.dumps(report))


def test_refine_defaults_follow_the_rule_on_current_reports_only(tmp_path):
    """Scenario: reports where the template, the network, both or neither pass the rule, on both splits; stale
    reports and a refiner other than the shipped one choose nothing; the installed file reads back per category."""
    import json

    from ancsh.studies.refinement import defaults_from_reports, install_defaults

    _report(tmp_path, "laptop", rot=[4.0, 4.0], rot_refined=[3.0, 3.5], state=[1.0], state_refined=[1.04])
    _report(tmp_path, "oven", rot=[4.0, 4.0], rot_refined=[3.0, 4.1], state=[1.0], state_refined=[0.9],
            network=([2.5, 3.5], [1.0]))  # template: a part worse; network: helps
    _report(tmp_path, "drawer", rot=[3.0] * 4, rot_refined=[2.0] * 4, state=[0.02] * 3,
            state_refined=[0.02, 0.0211, 0.02])
    _report(tmp_path, "eyeglasses", rot=[4.0] * 3, rot_refined=[3.0] * 3, state=[1.0] * 2, state_refined=[1.0] * 2,
            sha="0" * 64)
    _report(tmp_path, "microwave", rot=[4.0] * 2, rot_refined=[3.0] * 2, state=[1.0], state_refined=[1.0], generator=1)
    # both help on the procedural split, the network more; the network raises the real split's mean rotation
    _report(tmp_path, "safe", rot=[5.0, 5.0], rot_refined=[4.5, 4.5], state=[5.0], state_refined=[5.0],
            network=([4.0, 4.0], [4.0]),
            real={"exact_reduced": ([5.0, 6.0], [6.0]), "template": ([5.0, 5.9], [6.0]), "network": ([4.0, 7.5], [5.0])})
    # both help on both splits: the lower procedural mean rotation wins
    _report(tmp_path, "washing_machine", rot=[5.0, 5.0], rot_refined=[4.5, 4.5], state=[5.0], state_refined=[5.0],
            network=([4.0, 4.9], [4.0]),
            real={"exact_reduced": ([5.0, 6.0], [6.0]), "template": ([5.0, 5.9], [6.0]), "network": ([4.0, 6.0], [5.0])})
    _report(tmp_path, "box", rot=[5.0, 5.0], rot_refined=[6.0, 6.0], state=[5.0], state_refined=[5.0],
            network=([4.0, 4.0], [4.0]), refiner_sha="1" * 64)  # the network rows of another refiner
    cats = ["laptop", "oven", "drawer", "eyeglasses", "microwave", "safe", "washing_machine", "box", "no_report"]
    got = {d.category: d for d in defaults_from_reports(tmp_path, cats)}
    assert got["laptop"].choice == "template" and got["laptop"].on and got["laptop"].frames == 500
    assert got["laptop"].refined["template"]["rot_deg"] == (3.0, 3.5) and "network" not in got["laptop"].refined
    assert got["oven"].choice == "network" and "template: some part's rotation not lower" in got["oven"].reason
    assert got["drawer"].choice is None and "state" in got["drawer"].reason  # one joint 5.5 % worse
    assert got["eyeglasses"].choice is None and "stale" in got["eyeglasses"].reason  # other weights
    assert got["microwave"].choice is None and "generator" in got["microwave"].reason  # frames of an older generator
    assert got["safe"].choice == "template" and "real split the mean rotation rose" in got["safe"].refined["network"]["reason"]
    assert got["washing_machine"].choice == "network" and "network has the lower mean rotation" in got["washing_machine"].reason
    assert got["box"].choice is None and "another refiner" in got["box"].refined["network"]["reason"]
    assert not got["no_report"].on and got["no_report"].report is None
    path = install_defaults(list(got.values()), "ancsh bench refine-defaults", tmp_path / "defaults.json")
    data = json.loads(path.read_text())
    assert data["categories"] == {"laptop": "template", "oven": "network", "drawer": None, "eyeglasses": None,
                                  "microwave": None, "safe": "template", "washing_machine": "network", "box": None,
                                  "no_report": None}
    assert data["evidence"]["laptop"]["command"] == "ancsh evaluate --category laptop"
    # evidence the reports do not hold vetoes a refinement that passes the rule: the other one, or none, is chosen
    vetoed = {d.category: d for d in defaults_from_reports(tmp_path, ["oven", "washing_machine"], {
        ("oven", "network"): "worse on real sensor frames", ("washing_machine", "network"): "worse on real sensor frames"})}
    assert vetoed["oven"].choice is None and "vetoed: worse on real sensor frames" in vetoed["oven"].refined["network"]["reason"]
    assert vetoed["washing_machine"].choice == "template"
    with pytest.raises(ValueError, match="vetoes"):
        defaults_from_reports(tmp_path, ["oven"], {("oven", "icp"): "why"})
    with pytest.raises(ValueError, match="reports_dir"):
        defaults_from_reports(tmp_path / "missing")


def test_apply_refinement_says_what_the_result_rests_on():
    """Scenario: one rendered laptop frame refined three ways: none keeps the fit and its correspondences; the
    network's accepted pass brings its own correspondences and prediction; the template keeps the network's."""
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.learned.inference.provider import apply_refinement

    fr = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0)).frame(1)
    obs = Observation(fr.points)
    p = LearnedProvider("laptop", refine="network")
    inf = p.infer(obs)
    res = fit(obs, inf.correspondences, "exact_reduced", rng=0)
    none = apply_refinement(p, obs, inf.correspondences, inf.prediction, res, refine="none")
    assert none.result is res and none.correspondences is inf.correspondences and none.kind is None and none.note is None
    net = apply_refinement(p, obs, inf.correspondences, inf.prediction, res, rng=0)
    assert net.kind == "network" and net.result is not res and net.correspondences is not inf.correspondences
    assert net.prediction is not inf.prediction and net.note.startswith("refinement network: kept")
    tpl = apply_refinement(p, obs, inf.correspondences, inf.prediction, res, refine="template", rng=0)
    assert tpl.correspondences is inf.correspondences and tpl.note.startswith("category-template refinement")
    assert tpl.kind == ("template" if "kept" in tpl.note.split("(")[0] and "not kept" not in tpl.note else None)
