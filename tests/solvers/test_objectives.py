"""Issue 63 item 1: the default objective of the fits, chosen in one table (``DEFAULT_OBJECTIVES``) with its figures.

No figure or weight is stored here: every expectation is read from the table itself."""

from __future__ import annotations

from dataclasses import replace

import pytest

from ancsh.solvers import FitConfig
from ancsh.solvers.formulations import (
    DEFAULT_OBJECTIVE, DEFAULT_OBJECTIVES, OBJECTIVES, PREVIOUS_OBJECTIVE, Objective, default_objective,
    provider_fit_config,
)

_OBJECTIVE_FIELDS = tuple(PREVIOUS_OBJECTIVE.fields())


def _objective_of(config: FitConfig) -> dict:
    return {k: getattr(config, k) for k in _OBJECTIVE_FIELDS}


def test_the_plain_default_is_the_tables_any_provider_entry():
    """``FitConfig()`` -- what ``fit`` uses without a config, and ``bench fit``'s default method -- has the objective
    the table names for any provider's correspondences."""
    chosen = DEFAULT_OBJECTIVES["any"]["*"].objective
    assert DEFAULT_OBJECTIVE is chosen and default_objective() is chosen
    assert _objective_of(FitConfig()) == chosen.fields()
    assert FitConfig().objective is chosen
    assert FitConfig.default_for("any", "laptop") == FitConfig()  # one entry for every category


@pytest.mark.parametrize("provider, category", [(p, c) for p, table in DEFAULT_OBJECTIVES.items() for c in table])
def test_each_entry_is_what_its_provider_and_category_get_and_says_why(provider, category):
    choice = DEFAULT_OBJECTIVES[provider][category]
    assert isinstance(choice.objective, Objective) and choice.objective.name in OBJECTIVES
    assert len(choice.measured) > 80  # its figures and command
    config = FitConfig.default_for(provider, None if category == "*" else category)
    assert _objective_of(config) == choice.objective.fields()
    assert config.objective is choice.objective
    others = replace(FitConfig(), **choice.objective.fields())
    assert config == others  # only the objective differs from the defaults


def test_an_unlisted_category_gets_its_providers_star_entry_and_bad_names_are_refused():
    assert default_objective("learned", "no_such_category") is DEFAULT_OBJECTIVES["learned"]["*"].objective
    with pytest.raises(ValueError, match="provider: expected one of"):
        default_objective("no_such_provider")
    with pytest.raises(ValueError, match="objective: expected one of"):
        FitConfig.with_objective("no_such_objective")


def test_the_previous_objective_stays_reachable_and_the_paper_has_no_npcs_biases():
    previous = FitConfig.previous()
    assert _objective_of(previous) == PREVIOUS_OBJECTIVE.fields() and previous.objective is PREVIOUS_OBJECTIVE
    assert FitConfig.with_objective("previous", tol=1e-9) == replace(previous, tol=1e-9)
    paper = FitConfig.paper()
    assert paper.npcs_bias_weight == 0.0 and not paper.npcs_scale_bias and not paper.npcs_stretch_bias
    assert paper.naocs_prior_weight == 0.0


def test_the_bias_switches_follow_the_bias_weight_unless_set():
    """Unset (``None``), the scale and stretch switches are the default objective's where the NPCS biases are on and
    off where ``npcs_bias_weight`` is 0; set on without the biases they are refused, as before."""
    off = FitConfig(npcs_bias_weight=0.0)
    assert (off.npcs_scale_bias, off.npcs_stretch_bias) == (False, False)
    on = FitConfig(npcs_bias_weight=2 * DEFAULT_OBJECTIVE.npcs_bias_weight + 0.01)
    assert (on.npcs_scale_bias, on.npcs_stretch_bias) == (DEFAULT_OBJECTIVE.npcs_scale_bias,
                                                          DEFAULT_OBJECTIVE.npcs_stretch_bias)
    rotations = FitConfig(npcs_scale_bias=False)
    assert rotations.npcs_stretch_bias is False
    with pytest.raises(ValueError, match="npcs_scale_bias: needs the NPCS biases"):
        FitConfig(npcs_bias_weight=0.0, npcs_scale_bias=True)
    with pytest.raises(ValueError, match="npcs_stretch_bias: needs the NPCS scale biases"):
        FitConfig(npcs_scale_bias=False, npcs_stretch_bias=True)


def test_a_providers_fit_config_is_its_own_where_it_has_one():
    class Learned:
        def fit_config(self, **overrides):
            return FitConfig.default_for("learned", "laptop", **overrides)

    assert provider_fit_config(object(), box_extents="unit_diagonal") == FitConfig(box_extents="unit_diagonal")
    assert provider_fit_config(Learned(), tol=1e-9) == FitConfig.default_for("learned", "laptop", tol=1e-9)


def test_the_tracker_resolves_its_fits_config_from_the_provider_or_the_tracked_entry():
    from ancsh.tracking.config import TrackerConfig, with_provider_fit

    class Learned:
        def fit_config(self, **overrides):
            return FitConfig.default_for("learned", "laptop", **overrides)

    assert TrackerConfig().fit is None
    assert with_provider_fit(TrackerConfig(), object()).fit == FitConfig.default_for("tracked")
    assert with_provider_fit(TrackerConfig(), Learned()).fit == FitConfig.default_for("learned", "laptop")
    mine = FitConfig(tol=1e-9)
    assert with_provider_fit(TrackerConfig(fit=mine), Learned()).fit is mine  # a given config is kept
