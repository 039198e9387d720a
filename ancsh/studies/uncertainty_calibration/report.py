"""The uncertainty calibration's report (``uncertainty_calibration.md`` / ``.json``, the reliability plot) and the
installed inflation table (``ancsh/weights/uncertainty_inflation.json``)."""

from __future__ import annotations

import datetime
import json
import platform
from pathlib import Path

import numpy as np

from ..report import save_figure, write_text
from .measure import PROVIDERS, CalibrationConfig
from .statistics import COVERAGE_TARGETS, GAP_TOLERANCE, MIN_GAIN, MIN_RECORDS_PER_INDEX, coverage

__all__ = ["describe_sigma_map", "write_report", "install", "reliability_plot"]


# ------------------------------------------------------------------------------------------------
# report
# ------------------------------------------------------------------------------------------------
def _within(cov, tol=0.10) -> bool:
    return bool(np.all(np.abs(np.asarray(cov) - np.asarray(COVERAGE_TARGETS)) <= tol))


def reliability_plot(measured: dict, summary: dict, path) -> Path:
    """Observed vs nominal coverage on the test frames (rows: providers; columns: rotation,
    translation, joint state), raw (dashed) and inflated (solid), one colour per category."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    probs = np.linspace(0.02, 0.99, 40)
    providers = sorted({r["provider"] for r in summary["rows"]}, key=PROVIDERS.index)
    qs = ("rotation", "translation", "joint_state")
    fig, axes = plt.subplots(len(providers), len(qs), figsize=(4.2 * len(qs), 3.8 * len(providers)), squeeze=False)
    cats = list(measured["records"])
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for a, p in enumerate(providers):
        for b, q in enumerate(qs):
            ax = axes[a][b]
            ax.plot([0, 1], [0, 1], color="0.6", lw=0.8)
            for c, cat in enumerate(cats):
                pair = summary["d2"].get(cat, {}).get(p, {}).get(q)
                if pair is None:
                    continue
                raw, inflated = pair
                ent = summary["factors"][p][cat]
                col = colours[c % len(colours)]
                ax.plot(probs, coverage(raw, q, 1.0, probs), "--", color=col, lw=1)
                ax.plot(probs, coverage(inflated, q, 1.0, probs), "-", color=col, lw=1.5,
                        label=f"{cat} (rho {ent['correlation']:g}, {describe_sigma_map(ent[q])})"[:60])
            for t in COVERAGE_TARGETS:
                ax.axvline(t, color="0.85", lw=0.8)
            ax.set_title(f"{p}: {q.replace('_', ' ')}")
            ax.set_xlabel("nominal coverage")
            ax.set_ylabel("observed coverage (test frames)")
            ax.set_xlim(0, 1)
            ax.set_ylim(0, 1)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("Reliability of the fits' covariances (test frames): dashed raw, solid with the calibrated "
                 "correlation and inflation map")
    fig.tight_layout()
    path = save_figure(fig, path, dpi=90)
    plt.close(fig)
    return path


def describe_sigma_map(stored, per: str = "per part") -> str:
    """A stored map (:meth:`SigmaMap.to_json`, or a list of them ``per`` part / joint) in a few characters."""
    if isinstance(stored, list):
        return f"{per}: " + "; ".join(describe_sigma_map(v) for v in stored)
    if not isinstance(stored, dict):
        return f"×{stored:.3g}"
    out = f"×{stored['factor']:.3g}"
    if stored["power"] != 1.0:
        out += f", p {stored['power']:g} (s {stored['reference']:.2g})"
    if stored["floor"] > 0.0:
        out += f", floor {stored['floor']:.2g}"
    return out


def _misses(rows) -> list:
    """Lines naming the rows that miss the target and whether the calibration frames met it."""
    miss = [r for r in rows if not _within(r["inflated"])]
    if not miss:
        return []
    out = ["Rows that miss it (calibration-frame coverage after the same inflation beside the test-frame one):", ""]
    for r in miss:
        cal = r["calibration_inflated"]
        why = ("the calibration frames met the target, the test frames differ from them" if _within(cal) else
               "no map form fits the calibration frames at both levels either")
        se = [np.sqrt(t * (1 - t) / max(r["n_test"], 1)) for t in COVERAGE_TARGETS]  # binomial, at the targets
        out.append(f"- {r['category']} / {r['provider']} / {r['quantity']}: test {_pct(r['inflated'][0])} / "
                   f"{_pct(r['inflated'][1])} %, calibration {_pct(cal[0])} / {_pct(cal[1])} % ({why}; standard error "
                   f"of a test coverage at the targets over {r['n_test']} errors: {_pct(se[0])} / {_pct(se[1])} points).")
    return out + [""]


def _frames_note(config: CalibrationConfig) -> str:
    """Why the calibration frames outnumber the test frames (when they do)."""
    if config.n_calibration <= config.frames:
        return ""
    return (f"The calibration frames are {config.n_calibration / config.frames:g} times the test frames: a map measured on "
            "as few frames as it is tested on adds its own sampling error to the test frames' (over 150 frames a "
            "coverage near 68 % has a standard error of about 4 points, near 95 % about 2, more where frames of one "
            "instance err alike); measured once by resampling 1200 laptop / learned frames, one joint-state row in 16 missed the "
            "target by chance with 150 + 150 frames, one in 100 with 300 + 150.")


def _source_note(measured: dict, command: str) -> str:
    """Where the errors came from when they were read from a records file (``--records``)."""
    src = measured.get("source")
    if isinstance(src, list):  # several records files (merge_records)
        return "; the frames were fitted by " + " and ".join(
            f"`{x['command']}` ({x['elapsed_s'] / 60:.0f} min; its categories {', '.join(x.get('categories', []))})"
            if x.get("categories") else f"`{x['command']}` ({x['elapsed_s'] / 60:.0f} min)" for x in src)
    if not src or src.get("command") == command:
        return ""
    return f"; the frames were fitted by `{src['command']}` ({src['elapsed_s'] / 60:.0f} min)"


def _pct(v) -> str:
    return "-" if v is None or not np.isfinite(v) else f"{100 * v:.0f}"


def write_report(measured: dict, summary: dict, config: CalibrationConfig, out_md, *, command: str, elapsed_s: float) -> dict:
    """Write the markdown table, the JSON records and the reliability plot beside it; returns the headline."""
    out_md = Path(out_md)
    out_md.parent.mkdir(parents=True, exist_ok=True)
    png = reliability_plot(measured, summary, out_md.with_suffix(".png"))
    rows = summary["rows"]
    target_q = ("rotation", "translation", "joint_state")
    main = [r for r in rows if r["quantity"] in target_q]
    ok_main = sum(_within(r["inflated"]) for r in main)
    ok_all = sum(_within(r["inflated"]) for r in rows)
    t = measured["timing"]
    lines = [
        "# Calibration of the fits' uncertainties",
        "",
        f"Command: `{command}` ({elapsed_s / 60:.0f} min on {platform.machine()} / {platform.python_version()}, "
        f"{datetime.date.today().isoformat()})" + _source_note(measured, command) + ".",
        "",
        f"Frames: per category {config.n_calibration} calibration frames (held-out test instances, frame seed stream "
        f"{config.calibration_seed}) and {config.frames} test frames (seed {config.seed}, the frames of `ancsh evaluate`); "
        f"formulation `{config.formulation}` with each provider's default objective (the oracle's `FitConfig()`, the "
        f"networks' `LearnedProvider.fit_config()`: `ancsh.solvers.formulations.DEFAULT_OBJECTIVES`). {_frames_note(config)} Providers: `oracle-realistic` (ground truth "
        "corrupted by the `realistic` preset) and `learned` (shipped weights, with the plausibility checks of "
        "`ancsh predict`). Each error is normalised by its predicted covariance (squared Mahalanobis distance, "
        "see `ancsh/studies/uncertainty_calibration.py`); `1σ` / `2σ`: the share of test errors inside the region of "
        "probability 68.3 % / 95.4 % (chi-square with the quantity's degrees of freedom). The inflation has two "
        "parts, both measured on the calibration frames only, then applied to the test frames: a within-part "
        "residual correlation `rho` per provider and category (a part's `n` points count as `n / (1 + (n - 1) rho)` "
        "independent ones: network and warp errors do not average out over points), and per quantity a map of each "
        "fit's raw standard deviation `σ` (the RMS per coordinate of the quantity's covariance block) to the reported "
        "one, `σ' = sqrt((k σ^p s^(1-p))² + b²)` (`ancsh.solvers.uncertainty.SigmaMap`; the block keeps its shape). "
        "Three forms are fitted, each minimising the larger of the two coverage gaps: a single factor `k` (`×k`); "
        "a power `p` about the calibration frames' median raw `σ`, `s` (`p > 1`: the fits' errors differ more than "
        "their raw `σ` say); a floor `b` (the quantity's unit). A two-parameter form replaces the factor only where "
        f"it lowers the larger calibration gap by {100 * MIN_GAIN:g} points (of its parameters within "
        f"{100 * GAP_TOLERANCE:g} point of its best, the one nearest the plain factor). Maps per part (per joint) "
        f"replace the pooled one where every part has ≥ {MIN_RECORDS_PER_INDEX} calibration errors and they lower the "
        f"pooled calibration gap by {100 * MIN_GAIN:g} points: parts of one object can be calibrated very differently, "
        "and pooled they give a mixture of scales that no single map fits at both levels.",
        "",
        f"**Target (issue 15): after inflation, 1σ / 2σ coverage within 10 points of 68 / 95 %.** Rotation, translation "
        f"and joint state: {ok_main} of {len(main)} category × provider rows meet it; all quantities: {ok_all} of {len(rows)}.",
        "",
        *_misses(rows),
        "| category | provider | quantity | n cal / test | raw 1σ / 2σ (%) | rho | inflation | inflated 1σ / 2σ (%) | within 10 pts |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['category']} | {r['provider']} | {r['quantity']} | {r['n_calibration']} / {r['n_test']} | "
            f"{_pct(r['raw'][0])} / {_pct(r['raw'][1])} | {r['correlation']:g} | "
            f"{describe_sigma_map(r['sigma_map'], 'per joint' if r['quantity'].startswith('joint') else 'per part')} | "
            f"{_pct(r['inflated'][0])} / {_pct(r['inflated'][1])} | {'yes' if _within(r['inflated']) else '**no**'} |")
    lines += ["", "Fits per split (failed: no estimate or a failed plausibility check, not scored; singular: some "
              "quantity undetermined, its errors not scored; not refined: learned-template frames whose template "
              "refinement kept the learned fit or chose the base candidate, which carries no covariance, and "
              "learned-network frames whose refinement failed):", "",
              "| category | provider | calibration frames / failed / singular | test frames / failed / singular |",
              "|---|---|---|---|"]
    for cat, per in measured["counts"].items():
        for p, c in per.items():
            a, b = c["calibration"], c["test"]
            def frames(x):  # learned-template: the frames left to the learned fit (or without a covariance) beside
                return f"{x['frames']}" + (f" (+{x['not_refined']} not refined)" if "not_refined" in x else "")

            lines.append(f"| {cat} | {p} | {frames(a)} / {a['failed']} / {a['singular']} | "
                         f"{frames(b)} / {b['failed']} / {b['singular']} |")
    lines += ["", "## Cost of the covariance", "",
              "Mean over the test frames, the same fit run with and without `FitConfig(uncertainty=...)` in one process:", "",
              "| provider | fit with covariance (ms) | without (ms) | covariance alone (ms) |", "|---|---|---|---|"]
    for p, v in t.items():
        lines.append(f"| {p} | {np.mean(v['fit_ms']):.1f} | {np.mean(v['fit_ms_without']):.1f} | "
                     f"{np.mean(v['covariance_ms']):.2f} |")
    lines += ["", "## Inflation maps", "",
              "Stored in `ancsh/weights/uncertainty_inflation.json` (written by this command with `--install`); "
              "`ancsh predict` and `ancsh track` apply the `learned` ones to the shipped weights' fits "
              "(`ancsh.solvers.uncertainty.inflation_for`). Per quantity: a number is the single factor `k`; "
              "`{factor, power, reference, floor}` is `k, p, s, b` of the map above; a list holds one map per part "
              "(pose quantities, in the category's part order; the object pose takes the root part's) or per joint.", "",
              "```json", json.dumps(summary["factors"], indent=1, sort_keys=True), "```", "",
              f"Reliability plot: [{png.name}]({png.name})", "", f"![reliability]({png.name})", ""]
    write_text(out_md, "\n".join(lines))
    payload = {"command": command, "config": {k: getattr(config, k) for k in config.__dataclass_fields__},
               "summary": {k: v for k, v in summary.items() if k != "d2"}, "counts": measured["counts"],
               "timing_ms": {p: {k: float(np.mean(v)) for k, v in d.items() if v} for p, d in t.items()}}
    write_text(out_md.with_suffix(".json"), json.dumps(payload, indent=1, default=_json_default))
    return {"rows_within_main": ok_main, "rows_main": len(main), "rows_within_all": ok_all, "rows_all": len(rows)}


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    return str(o)


def install(summary: dict, config: CalibrationConfig, command: str, path=None) -> Path:
    """Write the measured maps (merged per provider and category into an existing table)."""
    from ...solvers.inflation import INFLATION_PATH, load_inflation_table

    path = INFLATION_PATH if path is None else Path(path)
    table = load_inflation_table(path)
    for p, per_cat in summary["factors"].items():
        if p.startswith("learned"):  # the factors hold for the network they were measured with (the refiner's fits: it)
            from ...learned.network.weights import weights_path
            from ...outputs import file_sha256

            kind = "refine" if p == "learned-network" else "ancsh"
            per_cat = {c: {**f, "weights_sha256": file_sha256(weights_path(c, kind))} for c, f in per_cat.items()}
        # each entry keeps the command that measured it: a run on some categories leaves the others' entries as they were
        entries = table["providers"].setdefault(p, {})
        covers_all = set(entries) <= set(per_cat)
        entries.update({c: {**f, "command": command} for c, f in per_cat.items()})
        commands = table.setdefault("commands", {})
        if covers_all or p not in commands:
            commands[p] = command  # the run that measured all of a provider's maps
    table["formulation"] = config.formulation
    table["command"] = command
    table["date"] = datetime.date.today().isoformat()
    table["meaning"] = ("maps of the raw Jacobian standard deviations of ancsh.solvers.uncertainty (SigmaMap: a number is "
                        "a single factor; a list holds one map per part or joint), per provider, category and quantity, "
                        "measured on calibration frames by ancsh bench uncertainty (providers *-tracked-<source>: warm tracked "
                        "frames, by ancsh bench tracking --calibration-sequences); an entry's command (where recorded) "
                        "measured it, commands[provider] the last run that measured all of the provider's maps")
    write_text(path, json.dumps(table, indent=1, sort_keys=True) + "\n")
    return path
