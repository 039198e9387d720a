"""The tracking benchmark's report: ``tracking.md`` / ``.json`` from the records of :func:`ancsh.studies.tracking.measure.run_benchmark`."""

from __future__ import annotations

import json

import numpy as np

from .measure import AD_THRESHOLD, COVERAGE_QUANTITIES

__all__ = ["write_report"]


def _template_words(categories) -> str:
    """The categories a tracker configuration carries the template of, in words (``None``: the specs' choice)."""
    if categories is None:
        from ...data.conventions import CONVENTIONS

        chosen = [name for name in CONVENTIONS if CONVENTIONS[name].track_template]
        return (", ".join(chosen) or "none") + " (the specs' `track_template`)"
    return ", ".join(categories) or "none"


def _ms_cell(m: dict, method: str) -> str:
    """The table's median-milliseconds cell: warm network / carried frames (URDF: warm) of tracking, all in-view frames of per-frame fitting."""
    if method != "tracking":
        return _fmt(m["ms_median"], 0)
    if m.get("ms_model") is not None:
        return f"warm {_fmt(m['ms_model'], 0)}"
    if m.get("ms_template") is not None and m.get("ms_network") is None:
        return f"template {_fmt(m['ms_template'], 0)}"
    return f"{_fmt(m.get('ms_network'), 0)} / {_fmt(m.get('ms_carried'), 0)}"


def _fmt(v, digits=2) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "—"
    return f"{v:.{digits}f}"


def write_report(report: dict, summary: dict, path, *, command: str, calibration: dict | None = None,
                 installed: bool = False) -> str:
    """Write the markdown table (and ``.json`` next to it: config, machine, summary, records, calibration);
    returns the markdown. ``calibration``: :func:`calibrate`'s result (``installed``: its maps were installed
    before the benchmark's sequences ran, so the coverage table tests them)."""
    from pathlib import Path

    from ..._machine import describe_machine

    cfg, rows = report["config"], summary["rows"]
    m0, m1 = report["machine"]["start"], report["machine"]["end"]
    lines = [
        "# Tracking vs independent per-frame fitting",
        "",
        f"Command: `{command}`",
        "",
        f"Machine: {describe_machine(m0)}, {m1.get('load_average_1min')} at the end (the machine is shared: both sides are "
        "measured interleaved, frame by frame, alternating which goes first). Times are per frame from the observed points "
        "(rendering, depth reading and object isolation excluded, identical for both sides); one torch thread.",
        "",
        f"Sequences: {cfg['sequences']} per object, {cfg['length']} frames (URDF: {cfg['urdf_sequences']} of "
        f"{cfg['urdf_length']}) at 30 frames/s "
        f"(`ancsh data generate --sequence-length`: joint open/close cycles within the limits, smooth camera drift, "
        f"Kinect-like noise), test instances, seed {cfg['seed']}; {cfg['gap']} blank frames (the object out of view) in "
        "each, after which the tracker must re-initialise. Errors are means over the in-view frames with an accepted fit "
        "(rotation in degrees and translation in object diagonals, averaged over parts; joint state in degrees for "
        "revolute joints, object diagonals for prismatic ones); `failed` counts in-view frames without one.",
        "",
        f"Tracking: category level -- network (or oracle) every k = {cfg['network_every']} frames, correspondences "
        f"carried by the previous fit in between, warm-started `exact_reduced` fits with {_prior_words(report['tracker'])}"
        f"; {_fusion_words(report['tracker'])}; categories "
        f"{_template_words(report['tracker'].get('template_categories', ()))} instead carry the "
        "category template refined at every (re-)initialisation (`refine_fit`, seconds, once) by warm articulated ICP, the "
        "network only re-initialising (median ms: template frames). Per frame: provider + RANSAC + `exact_reduced` on "
        "every frame. URDF -- warm-started articulated ICP "
        "(`InstanceTracker`); per frame: the multi-start cold articulated ICP from `auto_init` views. AD accuracy: every "
        f"part's AD below {AD_THRESHOLD} of its diameter, failed frames counted wrong.",
        "",
        "Median ms: the median time of an in-view frame; for tracking, of the warm frames fitted on the network's (or "
        "oracle's) correspondences / on carried ones (URDF: warm frames), re-initialisations excluded.",
        "",
        "| object | provider | method | frames/s | median ms | rot (deg) | trans | joint state | AD acc. | failed | lost / reinit. | recovered |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        for method in ("tracking", "per_frame"):
            m = row[method]
            lost = f"{m['lost']} / {m['reinitialised']}" if method == "tracking" else ""
            rec = ("yes" if m["recovered"] else "**no**") if method == "tracking" else ""
            lines.append(f"| {row['object']} | {row['provider']} | {method.replace('_', '-')} | {_fmt(m['fps'], 1)} | {_ms_cell(m, method)} | "
                         f"{_fmt(m['rot_deg'])} | {_fmt(m['trans'], 3)} | {_fmt(m['state_err'], 2)} | "
                         f"{_fmt(m['ad_accuracy'], 2)} | {m['failed']}/{m['in_view']} | {lost} | {rec} |")
        r = row["ratio"]
        lines.append(f"| {row['object']} | {row['provider']} | **tracking / per-frame** | {_fmt(row['speedup'], 1)}x | | "
                     f"{_fmt(r['rot_deg'])} | {_fmt(r['trans'])} | {_fmt(r['state_err'])} | | | | |")
    lines += ["", "## Targets", ""]
    lines += _targets(rows, cfg)
    lines += _coverage_table(rows)
    if calibration is not None:
        lines += _calibration_table(calibration, cfg, installed)
    lines += _correlation_table(rows)
    text = "\n".join(lines) + "\n"
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    from ..report import write_text

    write_text(path, text)
    payload = {"command": command, "config": cfg, "tracker": report["tracker"], "machine": report["machine"],
               "summary": summary, "calibration": calibration, "records": report["records"]}
    from ...outputs import json_safe

    write_text(path.with_suffix(".json"), json.dumps(json_safe(payload), separators=(",", ":")))
    return text


def _prior_words(tracker: dict) -> str:
    """How the report names the tracker's temporal prior (``TrackerConfig`` fields of the run)."""
    w, wq = tracker.get("temporal_weight", 0.0), tracker.get("temporal_state_weight", 0.0)
    if not w and not wq:
        return "no temporal prior"
    parts = [f"pose {w:g}"] + ([f"joint state {wq:g}"] if wq else ["no joint-state part"])
    return f"the constant-velocity temporal prior ({', '.join(parts)})"


def _fusion_words(tracker: dict) -> str:
    """How the report names the fusion of network frames (``TrackerConfig.fusion_weight``)."""
    w = tracker.get("fusion_weight", 0.0)
    if not w:
        return "network frames fitted on the network's correspondences alone"
    return (f"network frames fused: the network's correspondences and, with weight {w:g}, the carried ones in one fit "
            "(a recursive weighted mean over the network frames)")


def _coverage_table(rows) -> list:
    """The markdown section of the reported standard deviations' coverage (:func:`_coverage_summary`)."""
    from ..uncertainty_calibration import COVERAGE_TARGETS

    have = [r for r in rows if r.get("coverage")]
    if not have:
        return []
    lines = ["", "## Coverage of the reported standard deviations", "",
             "How often the truth lies within the reported 1σ / 2σ (%, target 68 / 95, within 10 points: issue 15), over "
             "the in-view frames with an accepted fit, per part (rotation, translation of `T_cam_npcs`) and joint (state): "
             "the squared Mahalanobis distance of the error under the reported covariance against the chi-square "
             "quantiles (`ancsh bench uncertainty`'s definitions). What is reported: the tracker's frames as it returns "
             "them (learned: inflated by the factors of `ancsh/weights/uncertainty_inflation.json`, provider "
             "`learned-tracked-<source>` for warm frames where measured, else `learned` -- `learned-template` for the "
             "carried category template), learned per-frame fits inflated as by `ancsh predict`; the oracle's fits by "
             "the factors of provider `oracle-realistic` (`oracle-realistic-tracked-<source>` likewise). `with std`: fits "
             "that report one, of the accepted fits; by source: the tracker's frames by where their correspondences "
             "came from (`network`: the cold and warm network frames).", "",
             "| object | provider | method | source | with std | rotation | translation | joint state |",
             "|---|---|---|---|---|---|---|---|"]

    def cell(c, q):
        v = c[q]
        if v is None:
            return "—"
        mark = "" if all(abs(a - b) <= 0.10 for a, b in zip(v, COVERAGE_TARGETS)) else " **x**"
        return f"{100 * v[0]:.0f} / {100 * v[1]:.0f}{mark} ({c['n_' + q]})"

    for row in have:
        for c in row["coverage"]:
            lines.append(f"| {row['object']} | {row['provider']} | {c['method'].replace('_', '-')} | {c['source']} | "
                         f"{c['with_std']}/{c['fits']} | " + " | ".join(cell(c, q) for q in COVERAGE_QUANTITIES) + " |")
    lines += ["", "**x**: outside 10 points of the target at 1σ or 2σ; in brackets the number of errors scored."]
    return lines


def _calibration_table(calibration: dict, cfg: dict, installed: bool) -> list:
    """The markdown section of the tracked frames' inflation maps (:func:`calibrate`)."""
    from ..uncertainty_calibration import describe_sigma_map

    rows = calibration["summary"]["rows"]
    lines = ["", "## Calibration of tracked frames' standard deviations", "",
             f"Measured on {cfg['calibration_sequences']} other sequences per object (frame seed "
             f"{cfg['calibration_seed']}, the same held-out instances; tracking only), per provider, object and source "
             "of the warm tracked frames, as `ancsh bench uncertainty` measures single frames (within-part correlation "
             "rho, then per quantity the map of the raw sigmas that brings the calibration coverage nearest 68 / 95 %). A "
             "carried frame's raw covariance counts the carried rows as observations, and a fused network frame's "
             "counts them beside the network's: both repeat earlier errors, so their raw sigmas are far too small. "
             + ("These maps were installed (`ancsh/weights/uncertainty_inflation.json`, providers `*-tracked-<source>`) "
                "before the benchmark's sequences ran: the coverage table above tests them on other sequences."
                if installed else "These maps were **not** installed (no `--install`): the coverage table above used "
                "the table as it was."), "",
             "| object | provider | quantity | n | raw 1σ / 2σ (%) | rho | map | inflated 1σ / 2σ (%) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["quantity"] not in COVERAGE_QUANTITIES:
            continue
        per = "per joint" if r["quantity"].startswith("joint") else "per part"
        raw, inf = r["raw"], r["calibration_inflated"]
        lines.append(f"| {r['category']} | {r['provider']} | {r['quantity']} | {r['n_calibration']} | "
                     f"{100 * raw[0]:.0f} / {100 * raw[1]:.0f} | {r['correlation']:g} | "
                     f"{describe_sigma_map(r['sigma_map'], per)} | {100 * inf[0]:.0f} / {100 * inf[1]:.0f} |")
    return lines


def _correlation_table(rows) -> list:
    """The markdown section of the per-frame errors' frame-to-frame correlation (see :mod:`.analysis`)."""
    from ...tracking.analysis import WINDOWS

    have = [r for r in rows if r.get("correlation", {}).get("per_frame")]
    if not have:
        return []
    lags = (1, 2, 3, 5, 10)
    lines = ["", "## How much temporal averaging can buy: frame-to-frame correlation of the per-frame errors", "",
             "Signed errors of the independent per-frame fits (per part the rotation error vector `log(R R_gt^T)` and "
             "the translation error vector, per joint the signed joint-state error), over runs of consecutive in-view "
             "frames. `rho(l)` = E[e_t . e_t+l] / E[|e_t|^2] (raw: a per-sequence bias counts as correlation; centred: "
             "each run's mean removed). Ideal fusion N: mean |mean of the last N frames' errors| / mean |error| -- what "
             "averaging the per-frame estimates over N frames would reach relative to per-frame fitting if the motion "
             "between frames were known exactly (`all`: every frame so far); tracking on these providers' outputs cannot "
             "beat it. (Averaging N frames of correlation rho leaves the variance fraction rho + (1 - rho) / N.)", "",
             "| object | provider | error | raw rho " + "/".join(f"l{l}" for l in lags) + " | centred rho "
             + "/".join(f"l{l}" for l in lags) + " | ideal fusion " + "/".join(f"N={n}" for n in WINDOWS) + "/all |",
             "|---|---|---|---|---|---|"]
    for row in have:
        for kind, c in row["correlation"]["per_frame"].items():
            raw = "/".join(_fmt(c["raw"][l - 1]) if l <= len(c["raw"]) else "—" for l in lags)
            cen = "/".join(_fmt(c["centred"][l - 1]) if l <= len(c["centred"]) else "—" for l in lags)
            fus = "/".join(_fmt(c["fusion"][str(n)]) for n in WINDOWS + ("all",))
            lines.append(f"| {row['object']} | {row['provider']} | {kind} | {raw} | {cen} | {fus} |")
    return lines


def _targets(rows, cfg) -> list:
    out = []
    for row in rows:
        t, p, r = row["tracking"], row["per_frame"], row["ratio"]
        errs = {k: v for k, v in r.items() if np.isfinite(v)}
        worst = max(errs, key=errs.get) if errs else None
        err_ok = bool(errs) and all(v <= 0.8 for v in errs.values())
        name = f"{row['object']} / {row['provider']}"
        line = (f"- {name}: tracking error {'<=' if err_ok else '**not** <='} 0.8x per-frame "
                f"(worst ratio {_fmt(errs.get(worst))} on {worst}); ")
        if row["provider"] == "learned":
            line += f"{_fmt(t['fps'], 1)} frames/s with the network every k = {cfg['network_every']} frames (target >= 25: " \
                    f"{'met' if t['fps'] >= 25 else '**missed**'}); "
        if row["provider"] == "urdf":
            warm = 1e3 / t["ms_model"] if t.get("ms_model") else float("nan")
            line += (f"warm frames {_fmt(warm, 1)} frames/s (median; target >= 10: {'met' if warm >= 10 else '**missed**'}), "
                     f"{_fmt(t['fps'], 1)} frames/s over the sequence with its cold (re-)initialisations, vs "
                     f"{_fmt(p['fps'], 2)} cold; AD accuracy {_fmt(t['ad_accuracy'])} vs cold "
                     f"{_fmt(p['ad_accuracy'])} ({'equal or better' if t['ad_accuracy'] >= p['ad_accuracy'] else '**worse**'}); ")
        line += (f"{t['lost']} lost frames ({t['lost_in_view']} with the object in view), {t['reinitialised']} "
                 f"re-initialisations, {'every loss recovered' if t['recovered'] else '**a loss not recovered**'}.")
        out.append(line)
    return out
