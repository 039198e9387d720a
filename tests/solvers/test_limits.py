"""Joint ranges as physics: bounds on the states, and ``joint_at_limit`` where the data pull a state past them."""

from dataclasses import replace

import numpy as np
import pytest

from ancsh.solvers import FitConfig, fit
from ancsh.solvers.limits import LIMIT_TOLERANCE_RAD, beyond_range, check_joint_range, on_bound
from ancsh.solvers.types import FitStatus

CFG = FitConfig(ransac=False)


def test_beyond_range_measures_outside_the_range_and_counts_turns_of_a_hinge():
    lim = np.array([[0.0, 1.0], [0.0, 1.0], [-np.inf, 0.5], [0.0, 4.0]])
    q = np.array([-0.2, 0.5, 0.7, 2 * np.pi + 1.0])
    np.testing.assert_allclose(beyond_range(q, lim, [True, False, False, True]), [0.2, 0.0, 0.2, 0.0])
    # a prismatic state does not wrap
    np.testing.assert_allclose(beyond_range([2 * np.pi + 0.5], [[0.0, 1.0]], [False]), [2 * np.pi - 0.5])
    assert on_bound([0.0, 0.5, 1.0 - 1e-5], lim[:3], [True, True, False]).tolist() == [True, False, False]


@pytest.mark.parametrize("where", ["lower", "upper"])
def test_known_states_near_both_limits_are_recovered_as_a_success(fit_case, where):
    """The true states 2 deg inside the range, next to one bound: recovered, and not flagged."""
    case = fit_case(5, num_parts=3, joint_types="revolute")
    q = case.gt.joint_states
    offset = np.deg2rad(2.0)
    lim = np.stack([q - offset, q + 1.0], axis=1) if where == "lower" else np.stack([q - 1.0, q + offset], axis=1)
    for formulation in ("exact_reduced", "exact_maximal"):
        r = fit(case.observation, replace(case.correspondences, joint_limits=lim), formulation, config=CFG)
        assert r.ok, r.message
        np.testing.assert_allclose(r.joint_states, q, atol=1e-5)


def test_a_fit_started_beyond_a_limit_ends_inside_it_and_is_flagged_when_the_data_disagree(fit_case):
    """Truth 30 deg past the upper bound: every exact formulation stops inside the range, on the bound, and the data
    (the same fit without the bounds) say ``joint_at_limit``; 5 deg past it (within the tolerance) is a success."""
    case = fit_case(3, num_parts=3, joint_types="revolute")
    q = case.gt.joint_states
    for past, flagged in ((np.deg2rad(30.0), True), (np.deg2rad(5.0), False)):
        lim = np.stack([q - 1.0, q - past], axis=1)
        corr = replace(case.correspondences, joint_limits=lim)
        for formulation, solver in (("exact_reduced", "ipopt"), ("exact_reduced", "lsq"), ("exact_maximal", "ipopt")):
            r = fit(case.observation, corr, formulation, solver, config=CFG)
            assert np.all(r.joint_states <= lim[:, 1] + 1e-6) and np.all(r.joint_states >= lim[:, 0] - 1e-6)
            assert (r.status == FitStatus.JOINT_AT_LIMIT) == flagged, (formulation, solver, r.message)
            if flagged:
                assert "joint" in r.message and "outside its range" in r.message


def test_unbounded_formulations_report_a_state_outside_the_range(fit_case):
    case = fit_case(3, num_parts=3, joint_types="revolute")
    q = case.gt.joint_states
    lim = np.stack([q - 1.0, q - np.deg2rad(30.0)], axis=1)
    corr = replace(case.correspondences, joint_limits=lim)
    for formulation in ("per_part", "soft"):
        r = fit(case.observation, corr, formulation, config=CFG)
        assert r.status == FitStatus.JOINT_AT_LIMIT, (formulation, r.message)
    # the same states inside the range pass
    inside = replace(case.correspondences, joint_limits=np.stack([q - 1.0, q + 1.0], axis=1))
    assert all(fit(case.observation, inside, f, config=CFG).ok for f in ("per_part", "soft"))
    # without enforce_limits, nothing is checked
    assert fit(case.observation, corr, "per_part", config=FitConfig(ransac=False, enforce_limits=False)).ok


def test_check_joint_range_leaves_a_state_on_its_bound_alone_when_the_free_fit_agrees(fit_case):
    case = fit_case(5, num_parts=2, joint_types="revolute")
    r = fit(case.observation, case.correspondences, "exact_reduced", config=CFG)
    q = r.joint_states
    lim = np.stack([q, q + 1.0], axis=1)  # the state on the lower bound
    calls = []

    def unbounded(shift):
        calls.append(shift)
        return replace(r, joint_states=q - shift)

    assert check_joint_range(r, lim, [True], bounded=True, unbounded=lambda: unbounded(0.5 * LIMIT_TOLERANCE_RAD)).ok
    out = check_joint_range(r, lim, [True], bounded=True, unbounded=lambda: unbounded(2 * LIMIT_TOLERANCE_RAD))
    assert out.status == FitStatus.JOINT_AT_LIMIT and len(calls) == 2
    # off the bounds, the free fit is never asked
    assert check_joint_range(r, lim - 0.3, [True], bounded=True, unbounded=lambda: unbounded(1.0)).ok and len(calls) == 2
