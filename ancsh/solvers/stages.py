"""Where a fit spends its time: wall-clock seconds per stage of :func:`ancsh.solvers.fit.fit`, recorded on demand.

Inside :func:`record_stages` every fit call adds the time of each of its stages (:data:`FIT_STAGES`) and its
backend's own breakdown (:data:`SOLVER_STAGES`) to the :class:`StageTimes` it yields; outside it the driver's
clock does nothing but one ``None`` test per stage. ``ancsh bench fit-profile`` reads it
(``docs/results/fit_profile.md``)::

    with record_stages() as times:
        fit(observation, correspondences)
    times.seconds["ransac"], times.solver["ipopt.nlp_hess_l"]

A fit that calls itself (the joint-range check's unbounded refit) records its inner stages too: the stage
``limits`` holds that refit's whole time, its stages are also added to theirs (the sums then exceed the calls' wall
time by that refit; :attr:`StageTimes.nested_calls` counts them).
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field

__all__ = ["FIT_STAGES", "SOLVER_STAGES", "StageClock", "StageTimes", "record_stages"]

FIT_STAGES = {
    "validate": "argument checks of fit()",
    "setup": "kinematic structure, canonical parameters, term weights of the call",
    "ransac": "articulated RANSAC (minimal samples, scoring, refits on the inliers)",
    "rescale": "the initial per-part scales (FitConfig.scale_estimator)",
    "program": "program cache lookup, start x (joint states read off the per-part poses), bounds",
    "moments": "per-part data moments of the inliers",
    "pack": "the program's parameter vector p",
    "solve": "the backend's call (see the solver stages)",
    "extract": "unpacking the solution, per-term costs",
    "covariance": "FitResult.uncertainty: linearisation (CasADi) and the Gauss-Newton covariance (numpy)",
    "result": "camera-space joints (post-processing), amodal boxes, constraint violation",
    "limits": "the joint-range check (an unbounded refit when a state is on a bound)",
}
"""The driver's stages, in order, with what each holds."""

SOLVER_STAGES = {
    "ipopt.nlp_f": "IPOPT: CasADi evaluations of the objective",
    "ipopt.nlp_grad_f": "IPOPT: CasADi evaluations of the objective's gradient",
    "ipopt.nlp_g": "IPOPT: CasADi evaluations of the constraints",
    "ipopt.nlp_jac_g": "IPOPT: CasADi evaluations of the constraint Jacobian",
    "ipopt.nlp_hess_l": "IPOPT: CasADi evaluations of the Lagrangian's Hessian",
    "ipopt.internal": "IPOPT: the rest of the call (its linear solves (MUMPS), line search, bookkeeping, "
                      "CasADi's argument handling)",
    "lm.evaluate": "LM: CasADi evaluations of the residual and its Jacobian",
    "lm.linear": "LM: normal equations and their solves (numpy)",
    "lm.python": "LM: the rest of the loop (Python)",
}
"""The backends' own breakdown of the stage ``solve`` (``ipopt.*`` from IPOPT's statistics, ``lm.*`` timed)."""

_ACTIVE: ContextVar = ContextVar("ancsh_fit_stage_times", default=None)


@dataclass
class StageTimes:
    """Seconds per stage summed over the fit calls made while recording.

    Attributes
    ----------
    seconds : dict of str to float
        Keys of :data:`FIT_STAGES` (seconds, summed over calls).
    solver : dict of str to float
        Keys of :data:`SOLVER_STAGES` (seconds) and ``"<backend>.iterations"`` (counts), summed.
    calls : int
        Top-level fit calls.
    nested_calls : int
        Fit calls made inside another (counted in its ``limits`` stage and in their own stages).
    """

    seconds: dict = field(default_factory=dict)
    solver: dict = field(default_factory=dict)
    calls: int = 0
    nested_calls: int = 0
    _depth: int = 0

    def add(self, stage: str, seconds: float) -> None:
        self.seconds[stage] = self.seconds.get(stage, 0.0) + seconds

    def add_solver(self, values: dict) -> None:
        for k, v in values.items():
            self.solver[k] = self.solver.get(k, 0.0) + v


@contextmanager
def record_stages():
    """Record the stages of every fit call in this context (thread / task local); yields the :class:`StageTimes`."""
    times = StageTimes()
    token = _ACTIVE.set(times)
    try:
        yield times
    finally:
        _ACTIVE.reset(token)


class StageClock:
    """The driver's clock: :meth:`mark` adds the time since the previous mark to a stage (only while recording)."""

    __slots__ = ("times", "last")

    def __init__(self):
        self.times = _ACTIVE.get()
        self.last = time.perf_counter()
        if self.times is not None:
            if self.times._depth:
                self.times.nested_calls += 1
            else:
                self.times.calls += 1
            self.times._depth += 1

    @property
    def recording(self) -> bool:
        return self.times is not None

    def mark(self, stage: str) -> None:
        """Add the time since the last mark (or the clock's start) to ``stage``."""
        if self.times is None:
            return
        now = time.perf_counter()
        self.times.add(stage, now - self.last)
        self.last = now

    def solver(self, values: dict) -> None:
        """Add a backend's own breakdown (:attr:`~ancsh.solvers.backends.SolveOutcome.timings`)."""
        if self.times is not None and values:
            self.times.add_solver(values)

    def close(self) -> None:
        """The call is over (its nested calls are counted apart)."""
        if self.times is not None:
            self.times._depth -= 1
