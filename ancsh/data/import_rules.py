"""The importer's geometric rules (:mod:`ancsh.data.importer`): state 0 and the opening direction of a joint
measured on the object's geometry, and the free range of a hinge the file leaves unlimited.

All of them take the loaded model in the file's parameterisation and one joint index ``k``.
"""

from __future__ import annotations

import numpy as np

from .conventions import (
    _horizontal_angle_to_front_deg,
    _joint_pair,
    _side_ok,
    _with_state,
    box_volume,
    closing_scores,
    side_volumes,
)

__all__ = ["FREE_MARGIN", "FREE_SHARE", "FREE_STEP_DEG", "ImportRejected", "free_range", "find_sign", "find_zero",
           "search_limits", "unbounded"]

_GRID = 241
"""Grid of the state searches over a joint's range."""


class ImportRejected(ValueError):
    """The object cannot be an instance of the category; ``reason`` says why."""

    def __init__(self, name: str, reason: str):
        super().__init__(f"{name}: {reason}")
        self.name = name
        self.reason = reason


def unbounded(joint) -> bool:
    """A revolute joint without limits or with more than a full turn between them (``continuous``, ``+-1e9``)."""
    return joint.is_revolute and not (np.isfinite(joint.lower) and np.isfinite(joint.upper)
                                      and joint.upper - joint.lower <= 2 * np.pi)


def search_limits(joint) -> tuple[float, float]:
    """The range searched for state 0 and the direction: the limits, or one turn around the file's 0."""
    if unbounded(joint):
        return -np.pi, np.pi
    lo = joint.lower if np.isfinite(joint.lower) else -np.pi
    hi = joint.upper if np.isfinite(joint.upper) else np.pi
    return lo, hi


FREE_STEP_DEG = 1.0
"""Step (degrees) of :func:`free_range`'s scan."""

FREE_MARGIN = 0.1
"""The base's box shrunk by this fraction of its thinnest side on every side: the part's surface entering that
inner box passes through the base (touching it, as a closed lid does, does not)."""

FREE_SHARE = 0.05
"""Rise of the share of the part's surface points inside the base's inner box that ends :func:`free_range`'s
range (the part entering the base)."""


def free_range(model, k: int, zero: float, sign: int, *, closed: bool) -> tuple[float, float]:
    """The states, from ``zero`` in the convention's units (``q = sign * (q_file - zero)``), through which joint
    ``k``'s part turns without passing through the base: for a joint the file leaves unlimited.

    The scan turns the part in steps of :data:`FREE_STEP_DEG` each way from state 0 (at most a full turn),
    following the share of its surface points inside the base's box shrunk by :data:`FREE_MARGIN`. A closed lid
    may start with many there (a keyboard's recess, a lid's rim) and a hinge's edge keeps a few; the part has
    left the base once the share fell :data:`FREE_SHARE` below its start (or started at most that), and the range
    ends where the share rises :data:`FREE_SHARE` above the least it reached: the part entering the base again.
    A ``closed`` state 0 is the lower limit (closing further goes into the body).
    """
    import trimesh

    base, _ = _joint_pair(model, k, _with_state(model, k, zero))
    margin = FREE_MARGIN * float(np.min(base.max(axis=0) - base.min(axis=0)))
    lo_box, hi_box = base.min(axis=0) + margin, base.max(axis=0) - margin
    child = model.joint_parts(k)[1]
    mesh = model.parts[child].mesh  # surface samples (a box's 8 corners can all lie outside the inner box)
    verts = np.asarray(trimesh.sample.sample_surface(mesh, 2000, seed=0)[0], dtype=np.float64)

    def share(t) -> float:
        pose = model.forward_kinematics(_with_state(model, k, zero + sign * t))[child]
        pts = pose.apply(verts) @ model.R_canon_base.T
        return float(np.mean(np.all((pts > lo_box) & (pts < hi_box), axis=1)))

    start = share(0.0)
    step = np.radians(FREE_STEP_DEG)
    ends = []
    for direction in (1, -1):
        if closed and direction == -1:
            ends.append(0.0)
            continue
        t, least = 0.0, start
        while abs(t) + step <= 2 * np.pi - step:
            now = share(t + direction * step)
            if (least <= FREE_SHARE or least < start - FREE_SHARE) and now > least + FREE_SHARE:
                break  # out of the base, and entering it again
            least = min(least, now)
            t += direction * step
        left = least <= FREE_SHARE or least < start - FREE_SHARE
        ends.append(t if left else 0.0)  # a part that never leaves the base has no free range
    return ends[1], ends[0]


def _argbest(scores, lo, hi) -> tuple[float, float]:
    """Grid search over ``[lo, hi]``, then a finer grid around the best value.

    ``scores`` maps a ``(Q,)`` array of states to ``(Q,)`` values, minimised; returns
    ``(state, value)``.
    """
    qs = np.linspace(lo, hi, _GRID)
    i = int(np.argmin(scores(qs)))
    step = (hi - lo) / (_GRID - 1)
    fine = np.linspace(max(lo, qs[i] - step), min(hi, qs[i] + step), 21)
    vals = scores(fine)
    j = int(np.argmin(vals))
    return float(fine[j]), float(vals[j])


def _each(score):
    """``score`` of one state, applied to every state of an array."""
    return lambda qs: np.array([score(q) for q in qs])


def find_zero(model, k, jc) -> float:
    lo, hi = search_limits(model.joints[k])
    if jc.zero == "closed":
        vol0 = box_volume(*_joint_pair(model, k, model.rest_states))
        tie = 1e-6  # ties (flat minima) go to the state nearest the file's 0
        q, value = _argbest(lambda qs: closing_scores(model, k, qs) / vol0 + tie * np.abs(qs), lo, hi)
        if np.isfinite(value):
            return q

        def score(q):  # no state is aligned with the base (an odd shape): the smallest box
            return box_volume(*_joint_pair(model, k, _with_state(model, k, q))) / vol0 + tie * abs(q)

        return _argbest(_each(score), lo, hi)[0]

    def score(q):  # perpendicular: long axis along the front axis, on the convention's side
        base, child = _joint_pair(model, k, _with_state(model, k, q))
        return _horizontal_angle_to_front_deg(child) + (0.0 if _side_ok(base, child, jc.side) else 180.0)

    return _argbest(_each(score), lo, hi)[0]


def find_sign(model, k, jc, zero) -> int:
    """+1 or -1: the direction from ``zero`` in which the state opens or folds.

    ``opens``: the side whose states, over its whole range within the limits, grow the box
    around base and part the most (the mean growth times the side's length); the first step
    alone can leave the box unchanged (a lid's front edge rising within the body's height) or
    grow it by swinging the part into the body where a file's limits allow a little of that.
    ``folds``: the first step that brings the part's centre towards the base's centre line.
    """
    lo, hi = search_limits(model.joints[k])
    base0, child0 = _joint_pair(model, k, _with_state(model, k, zero))
    gains = {}
    if jc.positive == "opens":
        vol0 = box_volume(base0, child0)
        for s, end in ((1, hi), (-1, lo)):
            length = abs(end - zero)
            if length < 1e-9:
                continue
            gains[s] = (np.mean(side_volumes(model, k, zero, end)) / vol0 - 1.0) * length
    else:
        step = min(0.2, 0.25 * (hi - lo)) if model.joints[k].is_revolute else 0.1 * (hi - lo)
        cx = (base0.min(axis=0)[0] + base0.max(axis=0)[0]) / 2
        for s in (1, -1):
            q = min(max(zero + s * step, lo), hi)
            if abs(q - zero) < 1e-9:
                continue
            base, child = _joint_pair(model, k, _with_state(model, k, q))
            gains[s] = abs(child0.mean(axis=0)[0] - cx) - abs(child.mean(axis=0)[0] - cx)
    if not gains:
        raise ImportRejected(model.name, f"joint {model.joints[k].name!r} has no range to move in")
    return max(gains, key=gains.get)


