"""Fast CasADi evaluation (NumpyFunction) and the fit's stage timings (record_stages)."""

import threading

import casadi as ca
import numpy as np
import pytest

from ancsh.solvers import FitConfig, fit
from ancsh.solvers.program import NumpyFunction
from ancsh.solvers.stages import FIT_STAGES, SOLVER_STAGES, record_stages


def _function():
    x, p = ca.SX.sym("x", 4), ca.SX.sym("p", 3)
    r = ca.vertcat(ca.sin(x[0]) * p[0], x[1] * x[2] + p[1], ca.SX(0), p[2] * ca.sumsqr(x))  # a structural zero
    return ca.Function("f", [x, p], [r, ca.jacobian(r, x), ca.SX(0, 1)])


def test_numpy_function_matches_the_casadi_call():
    f = _function()
    fast = NumpyFunction(f)
    rng = np.random.default_rng(0)
    for _ in range(5):
        x, p = rng.normal(size=4), rng.normal(size=3)
        r, J, empty = fast(x, p)
        r_dm, J_dm, _ = f(x, p)
        assert r.shape == (4,) and J.shape == (4, 4) and empty.shape == (0,)
        np.testing.assert_array_equal(r, np.asarray(r_dm).ravel())
        np.testing.assert_array_equal(J, np.asarray(ca.densify(J_dm)))
    r1, _, _ = fast(x, p)
    fast(x + 1.0, p)
    np.testing.assert_array_equal(r1, fast(x, p)[0])  # results are copies, not the reused buffers
    with pytest.raises(ValueError, match="expected 2 inputs"):
        fast(x)


def test_numpy_function_is_thread_safe():
    fast = NumpyFunction(_function())
    rng = np.random.default_rng(1)
    inputs = [(rng.normal(size=4), rng.normal(size=3)) for _ in range(8)]
    expected = [fast(x, p)[1] for x, p in inputs]
    errors = []

    def work(i):
        for _ in range(200):
            if not np.array_equal(fast(*inputs[i])[1], expected[i]):
                errors.append(i)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors


@pytest.mark.parametrize("solver", ["ipopt", "lm"])
def test_record_stages_splits_a_fit(fit_case, solver):
    case = fit_case(3, num_parts=3, npcs_noise=0.01)
    fit(case.observation, case.correspondences, "exact_reduced", solver)  # builds the programs
    with record_stages() as times:
        r = fit(case.observation, case.correspondences, "exact_reduced", solver)
    assert r.ok and times.calls == 1
    assert set(times.seconds) <= set(FIT_STAGES) and {"ransac", "solve", "covariance", "result"} <= set(times.seconds)
    assert all(v >= 0 for v in times.seconds.values())
    # structural, not timing: the stages before the result's assembly lie inside the fit's own clock (time_s), the
    # backend's parts inside the solve stage
    assert sum(v for k, v in times.seconds.items() if k not in ("validate", "result", "limits")) <= r.time_s
    timed = {k for k in times.solver if not k.endswith(".iterations")}
    assert timed and timed <= set(SOLVER_STAGES) and times.solver[f"{solver}.iterations"] == r.iterations
    assert all(times.solver[k] >= 0 for k in timed if k != "ipopt.internal")
    assert sum(times.solver[k] for k in timed) <= times.seconds["solve"]
    with record_stages() as again:
        pass
    assert again.calls == 0  # nothing recorded outside a fit, nothing after the context
    fit(case.observation, case.correspondences, "exact_reduced", solver, FitConfig())
    assert times.calls == 1
