"""Joint ranges as physics: a fit the data pull beyond a joint's range is flagged ``joint_at_limit``.

The exact formulations take the correspondences' joint limits as bounds (``exact_reduced``) or inequalities
(``exact_maximal``), so their states always lie inside the range. A state *on* a bound is either right (a closed lid
at 0) or the sign of data that want something the object cannot do (a lid fitted through its closed box). The test
tells them apart by asking the data: the same fit, started from the bounded solution, without the bounds
(:func:`check_joint_range`'s ``unbounded``). When that fit takes a state more than :data:`LIMIT_TOLERANCE_RAD` /
:data:`LIMIT_TOLERANCE_M` past the bound, the bounded answer is not what the data say, and the fit's status becomes
``joint_at_limit``. ``per_part`` and ``soft`` have no bounds: a state that far outside the range is the same status.

Units: joint states and limits relative to rest, radians (revolute) or metres (prismatic).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .types import FitStatus

__all__ = ["AT_BOUND_M", "AT_BOUND_RAD", "LIMIT_TOLERANCE_M", "LIMIT_TOLERANCE_RAD", "beyond_range",
           "check_joint_range", "on_bound"]

#: A revolute state further than this outside its range (radians; 10 deg) is what the data say, not noise.
LIMIT_TOLERANCE_RAD = float(np.deg2rad(10.0))
#: The same for a prismatic state (metres).
LIMIT_TOLERANCE_M = 0.03
#: A state this close to a bound (radians / metres) is on it.
AT_BOUND_RAD = 1e-3
AT_BOUND_M = 1e-4


def beyond_range(states, limits, revolute) -> np.ndarray:
    """How far each joint state lies outside its range (0 inside).

    Parameters
    ----------
    states : (K,) float64
        Relative to rest; radians (revolute) or metres (prismatic).
    limits : (K, 2) float64
        ``(lower, upper)`` relative to rest; infinite where unbounded.
    revolute : (K,) bool

    Returns
    -------
    (K,) float64
        Radians / metres; a revolute state counts at its nearest turn (``q + 2 pi n``) to the range. NaN where the
        state is NaN.
    """
    q = np.asarray(states, dtype=np.float64).ravel()
    lim = np.asarray(limits, dtype=np.float64).reshape(-1, 2)
    rev = np.asarray(revolute, dtype=bool).ravel()
    out = np.zeros(len(q))
    for k, (v, (lo, hi), r) in enumerate(zip(q, lim, rev)):
        if not np.isfinite(v):
            out[k] = np.nan
            continue
        turns = v + 2 * np.pi * np.arange(-2, 3) if r and np.isfinite(lo) and np.isfinite(hi) else np.array([v])
        out[k] = float(np.min(np.maximum(lo - turns, 0.0) + np.maximum(turns - hi, 0.0)))
    return out


def on_bound(states, limits, revolute) -> np.ndarray:
    """(K,) bool: the state lies on (within :data:`AT_BOUND_RAD` / :data:`AT_BOUND_M` of) a finite bound."""
    q = np.asarray(states, dtype=np.float64).ravel()
    lim = np.asarray(limits, dtype=np.float64).reshape(-1, 2)
    eps = np.where(np.asarray(revolute, dtype=bool).ravel(), AT_BOUND_RAD, AT_BOUND_M)
    with np.errstate(invalid="ignore"):
        return (np.abs(q - lim[:, 0]) <= eps) | (np.abs(q - lim[:, 1]) <= eps)


def check_joint_range(result, limits, revolute, *, bounded: bool, unbounded=None):
    """``result`` with status ``joint_at_limit`` where the data put a joint past its range (else unchanged).

    Parameters
    ----------
    result : FitResult
        A fit whose states are relative to rest.
    limits : (K, 2) float64
        The ranges it was fitted with (relative to rest).
    revolute : (K,) bool
    bounded : bool
        The fit took the limits as bounds or inequalities (exact formulations): only states on a bound are tested,
        by ``unbounded``. ``False`` (``per_part``, ``soft``): the states are tested as they are.
    unbounded : callable, optional
        ``() -> FitResult``: the same fit without the limits, started from ``result`` (called only when a state is on
        a bound; a failure of it leaves ``result`` unchanged).
    """
    if not result.ok or len(result.joint_states) == 0:
        return result
    rev = np.asarray(revolute, dtype=bool)
    tol = np.where(rev, LIMIT_TOLERANCE_RAD, LIMIT_TOLERANCE_M)
    states = np.asarray(result.joint_states, dtype=np.float64)
    if bounded:
        at = on_bound(states, limits, rev)
        if not at.any() or unbounded is None:
            return result
        free = unbounded()
        if not free.ok:
            return result
        free_states = np.asarray(free.joint_states, dtype=np.float64)
        past = beyond_range(free_states, limits, rev)
        far = at & (past > tol)
        how = "stopped at its bound; without the bounds the fit puts it at"
    else:
        free_states = states
        past = beyond_range(states, limits, rev)
        far = past > tol
        how = "fitted at"
    if not far.any():
        return result
    words = []
    for k in np.flatnonzero(far):
        f, unit = (np.degrees(1.0), "deg") if rev[k] else (1.0, "m")
        lo, hi = np.asarray(limits, dtype=np.float64)[k]
        words.append(f"joint {k} {how} {f * free_states[k]:.3g} {unit}, {f * past[k]:.3g} {unit} outside its range "
                     f"[{f * lo:.3g}, {f * hi:.3g}] {unit} (relative to rest)")
    return dataclasses.replace(result, status=FitStatus.JOINT_AT_LIMIT, message=(
        "check joint range: " + "; ".join(words) + ": the data want a state the object cannot take (a lid through its "
        "base, a drawer into its cabinet), so the fit does not explain them"))
