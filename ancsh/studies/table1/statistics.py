"""Statistics of the learned evaluation's per-frame records: means / medians per method, part and joint, and the occlusion bins."""

from __future__ import annotations

import numpy as np

from .measure import BUDGET_METRICS, JOINT_METRICS, PART_METRICS

__all__ = ["AXIS_FLIP_DEG", "OCCLUSION_EDGES", "axis_tail", "occlusion_bins", "summarize"]

AXIS_FLIP_DEG = 45.0
"""A joint-axis error above this angle (degrees) reads as the wrong axis (a door hinged at its bottom edge taken for
one hinged at its side), not as a noisy estimate of the right one: :func:`axis_tail` counts such frames apart."""


# --------------------------------------------------------------------------------------------
# statistics
# --------------------------------------------------------------------------------------------
def _stats(values: np.ndarray) -> dict:
    """Mean / median over frames per column (:func:`ancsh.evaluation.aggregate`: NaN entries left
    out; ``None`` where a column has no finite entry)."""
    from ...evaluation import aggregate

    out = {"mean": [], "median": []}
    for col in np.asarray(values, dtype=float).T:
        a = aggregate(col).to_dict()
        out["mean"].append(a["mean"])
        out["median"].append(a["median"])
    return out


def axis_tail(values, threshold_deg: float = AXIS_FLIP_DEG) -> dict:
    """How much of a joint-axis mean comes from frames whose axis is the wrong one.

    Parameters
    ----------
    values : array_like, shape (F, K)
        Joint-axis angle errors (degrees) of ``F`` frames and ``K`` joints; NaN entries are left out.
    threshold_deg : float
        Errors above it count as a wrong axis (:data:`AXIS_FLIP_DEG`).

    Returns
    -------
    dict
        Per joint: ``over`` (frames above the threshold), ``frames`` (finite entries), ``mean_within`` (the mean
        of the others, ``None`` where there are none) and ``threshold_deg``.
    """
    v = np.asarray(values, dtype=float)
    if v.ndim != 2:
        raise ValueError(f"values: expected shape (F, K), got {v.shape}")
    over, frames, within = [], [], []
    for col in v.T:
        col = col[np.isfinite(col)]
        keep = col[col <= threshold_deg]
        over.append(int(col.size - keep.size))
        frames.append(int(col.size))
        within.append(float(keep.mean()) if keep.size else None)
    return {"threshold_deg": float(threshold_deg), "over": over, "frames": frames, "mean_within": within}


def _joint_summary(joints: list, names, K: int) -> dict:
    """Mean / median per joint of each metric in ``names`` over frames (``joints``: per frame, one dict per joint),
    then, where ``axis_deg`` is among them, its :func:`axis_tail`."""
    vals = {name: np.array([[j[name] for j in js] for js in joints]).reshape(-1, K) for name in names}
    out = {name: _stats(v) for name, v in vals.items()}
    if "axis_deg" in vals:
        out["axis_tail"] = axis_tail(vals["axis_deg"])
    return out


def summarize(evaluation: dict) -> dict:
    """Means and medians per method, part and joint; Table 2 rows; timings; occlusion bins."""
    recs = evaluation["records"]
    s = evaluation["settings"]
    M, K = len(s["part_names"]), len(s["joint_names"])
    out = {"methods": {}, "table2": {}, "timing": {}}
    for key in s["methods"]:
        ok = [r["methods"][key] for r in recs if r["methods"][key]["ok"]]
        row = {"frames": len(recs), "failures": len(recs) - len(ok)}
        for name in PART_METRICS:
            vals = np.array([[p.get(name, np.nan) for p in e["parts"]] for e in ok]).reshape(-1, M)
            if name.startswith("iou"):
                vals = 100.0 * vals
            row[name] = _stats(vals)
        row.update(_joint_summary([e["joints"] for e in ok], JOINT_METRICS, K))
        fit_ms = [r["methods"][key]["fit_ms"] for r in recs]
        row["fit_ms"] = {"mean": float(np.mean(fit_ms)), "median": float(np.median(fit_ms))} if fit_ms else None
        refs = [r["methods"][key]["refine"] for r in recs if "refine" in r["methods"][key]]
        if refs:
            choices = [x["choice"] for x in refs]
            ms = [x["refine_ms"] for x in refs]
            row["refine"] = {
                "frames": len(refs), "accepted": int(sum(x["accepted"] for x in refs)),
                "choices": {c: choices.count(c) for c in ("input", "articulated", "base")},
                "scales": {str(sc): sum(1 for x in refs if x["accepted"] and x["scale"] == sc)
                           for sc in sorted({x["scale"] for x in refs if x["accepted"]})},
                "refine_ms": {"mean": float(np.mean(ms)), "median": float(np.median(ms))},
            }
        out["methods"][key] = row
    nj = [r["naocs_joints"] for r in recs if "naocs_joints" in r]
    if nj:
        out["table2"]["naocs_vote"] = _joint_summary(nj, ("axis_deg", "line_dist"), K)
    bud = [r["budget"] for r in recs if "budget" in r]
    if bud:
        out["budget"] = {
            name: _stats(np.array([[p[name] for p in b["parts"]] for b in bud]).reshape(-1, M)) for name in BUDGET_METRICS
        }
        out["budget"]["seg_acc"] = _stats(np.array([[b["seg_acc"]] for b in bud]))
    dv = [r["direct_voting"] for r in recs if "direct_voting" in r]
    if dv:
        out["table2"]["direct_voting"] = _joint_summary([d["joints"] for d in dv], ("axis_deg", "line_dist"), K)
        out["timing"]["direct_voting_network_ms"] = float(np.mean([d["network_ms"] for d in dv]))
    for name in ("network_ms", "generate_ms"):
        vals = [r[name] for r in recs]
        out["timing"][name] = {"mean": float(np.mean(vals)), "median": float(np.median(vals))} if vals else None
    out["timing"]["wall_s"] = evaluation["timing"]["wall_s"]
    out["occlusion"] = occlusion_bins(evaluation)
    return out


OCCLUSION_EDGES = tuple(np.round(np.arange(0.0, 1.0001, 0.05), 2))


def occlusion_bins(evaluation: dict, edges=OCCLUSION_EDGES) -> dict:
    """Mean rotation / translation error per part and method in bins of the part's visible-area ratio.

    Returns ``{"edges": [...], "parts": [{"name", "counts", <method>: {"rot_deg": [...], "trans": [...]}}]}``
    (``None`` for empty bins; failed fits left out).
    """
    recs = evaluation["records"]
    s = evaluation["settings"]
    edges = np.asarray(edges, dtype=float)
    out = {"edges": edges.tolist(), "parts": []}
    for j, name in enumerate(s["part_names"]):
        vis = np.array([r["visibility"][j] for r in recs])
        idx = np.clip(np.digitize(vis, edges) - 1, 0, len(edges) - 2)
        part = {"name": name, "counts": np.bincount(idx, minlength=len(edges) - 1).tolist()}
        for key in s["methods"]:
            m = {}
            for metric in ("rot_deg", "trans"):
                vals = np.array([r["methods"][key]["parts"][j][metric] if r["methods"][key]["ok"] else np.nan for r in recs])
                m[metric] = []
                for b in range(len(edges) - 1):
                    v = vals[(idx == b) & np.isfinite(vals)]
                    m[metric].append(float(np.mean(v)) if v.size else None)
            part[key] = m
        out["parts"].append(part)
    return out
