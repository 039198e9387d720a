"""The learned provider's category-template refinement option (LearnedProvider(refine=...), predict_depth(refine=...))."""

import numpy as np
import pytest

from ancsh.data.templates import refine_default
from ancsh.learned.provider import LearnedProvider
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
