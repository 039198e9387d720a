"""The fit benchmark's speed section: per category, each method's mean and median time per frame and the official
scheme's over it (the speed-up), all measured side by side in one run (``docs/results/fit_benchmark.md``)."""

from __future__ import annotations

import numpy as np

__all__ = ["speed_by_category", "speed_lines"]


def speed_by_category(report: dict, level: str) -> list:
    """One row per (category, method) at ``level``: ``ms_mean``, ``ms_median`` (every frame, failed ones included) and,
    when ``official`` ran, ``ratio_mean`` / ``ratio_median`` = official's mean / median over the method's."""
    recs = [r for r in report["records"] if r["level"] == level]
    rows = []
    for cat in sorted({r["category"] for r in recs}):
        times = {m: np.array([r["time_ms"] for r in recs if r["category"] == cat and r["method"] == m])
                 for m in report["methods"]}
        ref = times.get("official")
        for m, t in times.items():
            if not t.size or m == "official":
                continue
            row = {"category": cat, "method": m, "frames": int(t.size), "ms_mean": float(t.mean()),
                   "ms_median": float(np.median(t))}
            if ref is not None and ref.size:
                row["official_ms_mean"], row["official_ms_median"] = float(ref.mean()), float(np.median(ref))
                row["ratio_mean"] = row["official_ms_mean"] / row["ms_mean"]
                row["ratio_median"] = row["official_ms_median"] / row["ms_median"]
            rows.append(row)
    return rows


def speed_lines(report: dict, level: str) -> list:
    """The markdown section of :func:`speed_by_category` (empty without rows)."""
    rows = speed_by_category(report, level)
    if not rows:
        return []
    lines = ["", f"## Speed per category (`{level}`)", "",
             "Milliseconds per frame (mean, median) and official / method (the speed-up, of the means and of the medians), "
             "from this run's frames.", "",
             "| category | method | frames | ms mean | ms median | official ms mean | official / method (mean) | "
             "official / method (median) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ratios = (f"{r['official_ms_mean']:.1f} | {r['ratio_mean']:.0f} | {r['ratio_median']:.0f}" if "ratio_mean" in r
                  else "- | - | -")
        lines.append(f"| {r['category']} | {r['method']} | {r['frames']} | {r['ms_mean']:.2f} | {r['ms_median']:.2f} | "
                     f"{ratios} |")
    return lines
