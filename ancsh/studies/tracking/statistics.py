"""Statistics of the tracking benchmark's records: mean errors per method, coverage, frame-to-frame error correlation."""

from __future__ import annotations

import numpy as np

from .measure import COVERAGE_QUANTITIES

__all__ = ["summarize", "CORRELATION_KINDS"]


# ---------------------------------------------------------------------------------------------
# summary and report
# ---------------------------------------------------------------------------------------------
def _mean(values) -> float:
    from ...evaluation import aggregate

    return aggregate(values).mean


def summarize(report: dict) -> dict:
    """Per (object, provider): both methods' mean errors over the in-view frames, frames/s, ratios,
    lost / re-initialised frames and whether every loss was recovered."""
    rows = []
    recs = report["records"]
    keys = sorted({(r["object"], r["provider"]) for r in recs}, key=lambda k: (k[1] == "urdf", k[1], k[0]))
    for obj, prov in keys:
        row = {"object": obj, "provider": prov}
        for method in ("tracking", "per_frame"):
            sel = [r for r in recs if r["object"] == obj and r["provider"] == prov and r["method"] == method]
            view = [r for r in sel if not r["blank"]]
            good = [r for r in view if r["ok"]]
            m = {"frames": len(sel), "in_view": len(view), "failed": len(view) - len(good),
                 "fps": len(sel) / sum(r["time_s"] for r in sel),
                 "rot_deg": _mean([np.mean(r["rot_deg"]) for r in good]),
                 "trans": _mean([np.mean(r["trans"]) for r in good]),
                 "state_err": _mean([np.mean(r["state_err"]) for r in good if r["state_err"]]),
                 # failed in-view frames count as wrong
                 "ad_accuracy": (sum(all(r["ad_correct"]) for r in good) / len(view)) if prov == "urdf" and view else None}
            m["ms_median"] = _median_ms(view)
            if method == "tracking":
                # warm frames by where their correspondences came from (URDF: "model")
                for source in ("network", "carried", "model", "template"):
                    m[f"ms_{source}"] = _median_ms([r for r in view if r["track"] == "tracked" and r["source"] == source])
                m["lost"] = sum(r["track"] == "lost" for r in sel)
                m["lost_in_view"] = sum(r["track"] == "lost" for r in view)
                m["reinitialised"] = sum(r["track"] == "reinitialised" for r in sel)
                m["network_frames"] = sum(r["source"] == "network" for r in sel)
                m["recovered"] = _recovered(sel)
            row[method] = m
        if prov != "urdf":
            row["coverage"] = _coverage_summary([r for r in recs if r["object"] == obj and r["provider"] == prov])
        t, p = row["tracking"], row["per_frame"]
        row["ratio"] = {k: (t[k] / p[k] if p[k] else float("nan")) for k in ("rot_deg", "trans", "state_err")}
        row["speedup"] = t["fps"] / p["fps"]
        if prov != "urdf":
            row["correlation"] = {method: _correlation([r for r in recs if r["object"] == obj and r["provider"] == prov
                                                        and r["method"] == method]) for method in ("per_frame", "tracking")}
        rows.append(row)
    return {"rows": rows}


def _coverage_summary(records) -> list:
    """Coverage of the reported standard deviations, per method and (tracking) per frame source:
    ``[{"method", "source", "fits", "with_std", quantity: [1 sigma, 2 sigma] or None, "n_" + quantity}, ...]``
    over the in-view frames with an accepted fit (:func:`~ancsh.studies.uncertainty_calibration.coverage`;
    unbounded variances left out)."""
    from ..uncertainty_calibration import coverage

    out = []
    for method in ("tracking", "per_frame"):
        good = [r for r in records if r["method"] == method and not r["blank"] and r["ok"]]
        sources = [None] + (sorted({r["source"] for r in good}) if method == "tracking" else [])
        for source in sources:
            sel = [r for r in good if source is None or r["source"] == source]
            if not sel:
                continue
            have = [r for r in sel if r.get("d2")]
            row = {"method": method, "source": source or "all", "fits": len(sel), "with_std": len(have)}
            for q in COVERAGE_QUANTITIES:
                d2 = np.array([np.nan if v is None else v for r in have for v in r["d2"][q]], dtype=np.float64)
                row["n_" + q] = int(np.isfinite(d2).sum())
                row[q] = coverage(d2, q).tolist() if row["n_" + q] else None
            out.append(row)
    return out


CORRELATION_KINDS = (("rot_vec", "rotation"), ("trans_vec", "translation"), ("state_signed", "joint state"))


def _correlation(records) -> dict:
    """Frame-to-frame correlation of the signed errors of one method's records
    (:func:`~ancsh.tracking.analysis.error_correlation`): runs of consecutive in-view frames with a fit,
    one run per part (joint) and sequence; ``{kind: CorrelationStudy.to_dict()}``."""
    from ...tracking.analysis import error_correlation

    out = {}
    for key, kind in CORRELATION_KINDS:
        runs = []
        for seq in sorted({r["sequence"] for r in records}):
            current = []
            for r in sorted((r for r in records if r["sequence"] == seq), key=lambda r: r["t"]) + [None]:
                if r is not None and not r["blank"] and r["ok"] and key in r:
                    current.append(np.asarray(r[key], dtype=np.float64).reshape(len(r[key]), -1))
                    continue
                if current:
                    stack = np.stack(current)  # (T, parts or joints, d)
                    runs += [stack[:, i, :] for i in range(stack.shape[1])]
                current = []
        if runs and sum(len(x) for x in runs):
            out[kind] = error_correlation(runs).to_dict()
    return out


def _median_ms(records) -> float | None:
    """Median time of the records in milliseconds (``None`` without any)."""
    return 1e3 * float(np.median([r["time_s"] for r in records])) if records else None


def _recovered(records) -> bool:
    """Every run of lost frames in a sequence is followed by a re-initialised frame (before the sequence ends)."""
    for seq in {r["sequence"] for r in records}:
        seq_recs = sorted((r for r in records if r["sequence"] == seq), key=lambda r: r["t"])
        lost = False
        for r in seq_recs:
            if r["track"] == "lost":
                lost = True
            elif lost and r["track"] in ("reinitialised", "initialised"):
                lost = False
        if lost:
            return False
    return True
