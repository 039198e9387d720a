"""The learned Table 1 / Table 2 reports: ``<category>.md`` / ``.json`` / occlusion plot, and ``<category>_real.md``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..._machine import describe_machine
from ...learned.inference.refine_network import passes_text
from ...outputs import json_safe
from ..report import utc_date, write_text
from .measure import METHODS, PAPER_TABLE1, PAPER_TABLE2
from .statistics import AXIS_FLIP_DEG

__all__ = ["write_json", "write_real_report", "write_report"]


# --------------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------------
def _fmt(values, spec: str) -> str:
    if values is None:
        return "-"
    parts = ["-" if v is None or (isinstance(v, float) and not np.isfinite(v)) else format(v, spec) for v in values]
    return "-" if all(p == "-" for p in parts) else ", ".join(parts)


def _state_spec(joint_types) -> str:
    return ".1f" if all(t == "revolute" for t in joint_types) else ".3f"


def _table1(summary: dict, settings: dict, stat: str, paper: dict | None) -> list[str]:
    st = _state_spec(settings["joint_types"])
    lines = [
        "| Method | Rotation error (°) | Translation error | 3D IoU (%) | Joint-state error | Joint-axis angle (°) "
        "| Line–line distance | Failed fits |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for key, row in summary["methods"].items():
        lines.append(
            f"| {METHODS[key].label} | {_fmt(row['rot_deg'][stat], '.2f')} | {_fmt(row['trans'][stat], '.3f')} "
            f"| {_fmt(row['iou'][stat], '.1f')} | {_fmt(row['state_err'][stat], st)} | {_fmt(row['axis_deg'][stat], '.2f')} "
            f"| {_fmt(row['line_dist'][stat], '.3f')} | {row['failures']}/{row['frames']} |"
        )
    for name, row in (paper or {}).items():
        lines.append(
            f"| *paper: {name}* | {_fmt(row.get('rot_deg'), '.1f')} | {_fmt(row.get('trans'), '.3f')} "
            f"| {_fmt(row.get('iou'), '.1f')} | {_fmt(row.get('state_err'), st)} | {_fmt(row.get('axis_deg'), '.1f')} "
            f"| {_fmt(row.get('line_dist'), '.3f')} | |"
        )
    return lines


def _occlusion_table(occ: dict, methods) -> list[str]:
    edges = occ["edges"]
    lines = []
    for part in occ["parts"]:
        used = [b for b, c in enumerate(part["counts"]) if c > 0]
        if not used:
            continue
        lines.append(f"Part **{part['name']}** — mean rotation error (°) per visible-area-ratio bin:\n")
        lines.append("| Method | " + " | ".join(f"{edges[b]:.2f}–{edges[b + 1]:.2f}" for b in used) + " |")
        lines.append("|---|" + "---|" * len(used))
        lines.append("| frames | " + " | ".join(str(part["counts"][b]) for b in used) + " |")
        for key in methods:
            vals = part[key]["rot_deg"]
            lines.append(f"| {METHODS[key].label} | " + " | ".join(_fmt([vals[b]], ".2f") for b in used) + " |")
        lines.append("")
    return lines


def plot_occlusion(summary: dict, settings: dict, path) -> Path:
    """Error vs visible-area ratio (binned means), one column per part, rows: rotation, translation."""
    from matplotlib.figure import Figure

    from ...data.show import save_figure

    occ = summary["occlusion"]
    edges = np.asarray(occ["edges"])
    centres = 0.5 * (edges[:-1] + edges[1:])
    M = len(occ["parts"])
    fig = Figure(figsize=(4.5 * M, 7), dpi=100)
    for j, part in enumerate(occ["parts"]):
        counts = np.array(part["counts"])
        for row, (metric, unit) in enumerate((("rot_deg", "rotation error (°)"), ("trans", "translation error (object units)"))):
            ax = fig.add_subplot(2, M, row * M + j + 1)
            for key in settings["methods"]:
                y = np.array([np.nan if v is None else v for v in part[key][metric]])
                keep = (counts >= 5) & np.isfinite(y)
                ax.plot(centres[keep], y[keep], marker="o", ms=3, label=METHODS[key].label)
            used = np.flatnonzero(counts > 0)
            if used.size:
                ax.set_xlim(edges[used[0]], edges[used[-1] + 1])
            ax.set_xlabel("visible-area ratio of the part")
            ax.set_ylabel(unit)
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(f"part {part['name']} (bins with >= 5 frames)", fontsize=10)
                ax.legend(fontsize=7)
    fig.suptitle(f"{settings.get('category', '')}: mean error vs occlusion on held-out instances", fontsize=11)
    fig.tight_layout()
    return save_figure(fig, path)


def _budget_section(summary: dict, settings: dict) -> list[str]:
    """The error-budget table (:func:`npcs_error_budget`): network NPCS orientation vs fitted rotation."""
    if "budget" not in summary:
        return []
    b = summary["budget"]
    fitted = [key for key in ("per_part", "exact_reduced", "template", "network") if key in summary["methods"]]
    head = "| Part | NPCS head: raw error | NPCS head: orientation error (°) | residual after the similarity |"
    head += "".join(f" {METHODS[k].label}: rotation error (°) |" for k in fitted)
    lines = [
        "",
        "## Where the rotation error comes from (means)",
        "",
        "The network's NPCS for each part, on the points that truly belong to it, against the true NPCS "
        "(`ancsh.studies.table1.npcs_error_budget`). A similarity fitted from the predicted onto the true "
        "NPCS splits their difference into an orientation error (its rotation) and a non-rigid residual. The "
        "orientation error equals the rotation error of a plain Umeyama fit of that part's predicted NPCS "
        "(true labels, no RANSAC): it is carried by the network output, and a fit of one part cannot remove it. "
        "Combining parts under the joints removes only what differs between parts. NPCS distances in NPCS units "
        f"(unit box diagonal). Segmentation accuracy: {b['seg_acc']['mean'][0]:.1%} of points.",
        "",
        head,
        "|---|---|---|---|" + "---|" * len(fitted),
    ]
    for j, name in enumerate(settings["part_names"]):
        row = f"| {name} | {_fmt([b['npcs_err']['mean'][j]], '.3f')} | {_fmt([b['npcs_rot_deg']['mean'][j]], '.2f')} "
        row += f"| {_fmt([b['npcs_resid']['mean'][j]], '.3f')} |"
        row += "".join(f" {_fmt([summary['methods'][k]['rot_deg']['mean'][j]], '.2f')} |" for k in fitted)
        lines.append(row)
    return lines


def refine_summary_line(row: dict) -> str:
    """One sentence on a ``template`` row's refinements: how many were kept, which kind, their cost."""
    r = row["refine"]
    scales = ", ".join(f"{k}: {v}" for k, v in r["scales"].items()) or "none"
    return (f"kept on {r['accepted']}/{r['frames']} frames (articulated {r['choices']['articulated']}, base-only "
            f"{r['choices']['base']}; scales of the kept ones {scales}); the refinement alone costs mean "
            f"{r['refine_ms']['mean']:.0f} ms, median {r['refine_ms']['median']:.0f} ms per frame")


def _refine_lines(summary: dict) -> list[str]:
    row = summary["methods"].get("template")
    if row is None or "refine" not in row:
        return []
    return [f"- category-template refinement: {refine_summary_line(row)} (included in its fit time above)"]


def _axis_tail_cell(tail: dict | None) -> str:
    """``"3/500 (1.85)"`` per joint, joined by ``"; "`` (:func:`~.statistics.axis_tail`); empty without one."""
    if not tail:
        return ""
    return "; ".join(f"{o}/{n} ({_fmt([m], '.2f')})" for o, n, m in zip(tail["over"], tail["frames"], tail["mean_within"]))


def _per_frame(evaluation: dict) -> dict:
    """Compact per-frame arrays for re-analysis (rounded)."""
    recs = evaluation["records"]
    out = {"instance": [r["instance"] for r in recs], "visibility": [np.round(r["visibility"], 4).tolist() for r in recs]}
    for key in evaluation["settings"]["methods"]:
        m = {}
        for name in ("rot_deg", "trans"):
            m[name] = [[round(p[name], 4) for p in r["methods"][key]["parts"]] or None for r in recs]
        for name in ("state_err", "axis_deg"):
            m[name] = [[round(j[name], 4) for j in r["methods"][key]["joints"]] or None for r in recs]
        out[key] = m
    return out


def _json_text(value, pad: str, one_line_entries: bool) -> str:
    """JSON of ``value`` at indentation ``pad``: containers one item a line (``indent=1``), or, where
    ``one_line_entries``, a mapping whose entries each fit on one line."""
    if not isinstance(value, (dict, list)) or not value:
        return json.dumps(value, allow_nan=False)
    inner = pad + " "
    if isinstance(value, list):
        items = [inner + _json_text(v, inner, False) for v in value]
        return "[\n" + ",\n".join(items) + "\n" + pad + "]"
    key = lambda k: json.dumps(k if isinstance(k, str) else json.dumps(k))  # noqa: E731  (JSON's key rule)
    if one_line_entries:
        items = [f"{inner}{key(k)}: {json.dumps(v, allow_nan=False)}" for k, v in value.items()]
    else:
        items = [f"{inner}{key(k)}: {_json_text(v, inner, False)}" for k, v in value.items()]
    return "{\n" + ",\n".join(items) + "\n" + pad + "}"


def write_json(path, data: dict, *, one_line: tuple = ()) -> Path:
    """Write ``data`` (made :func:`json_safe`) as JSON indented by one space a level, except the mappings
    under the top-level keys ``one_line``: each of their entries on one line (per-frame arrays, so
    the file stays small). ``json.loads`` of the file equals ``json_safe(data)``."""
    data = json_safe(data)
    unknown = [k for k in one_line if not isinstance(data.get(k), dict)]
    if unknown:
        raise ValueError(f"one_line: {unknown} are not mapping entries of data")
    inner = " "
    items = [f"{inner}{json.dumps(k)}: {_json_text(v, inner, k in one_line)}" for k, v in data.items()]
    path = Path(path)
    write_text(path, "{\n" + ",\n".join(items) + "\n}\n")
    return path


def split_comparison(procedural: dict, sp: dict, real: dict, sr: dict) -> list[str]:
    """Markdown: the real test split's Table 1 means beside the procedural split's, per part and
    method, with their ratio (the real-CAD issue's goal: real <= 1.25x procedural, per part).
    ``sp`` and ``sr`` are the two evaluations' :func:`summarize` results."""
    parts = procedural["settings"]["part_names"]
    joints = procedural["settings"]["joint_names"]
    lines = [
        f"Real test objects ({len(real['settings']['real_instances'])}): "
        f"{', '.join(real['settings']['real_instances'])}; {real['settings']['frames']} real frames, "
        f"{procedural['settings']['frames']} procedural frames (same seeds, noise, points and viewpoints).",
        "",
        "| Method | Part | Rotation (°) procedural | real | ratio | Translation procedural | real | ratio | 3D IoU (%) procedural | real |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]

    def val(row, metric, i):
        v = row[metric]["mean"]
        return None if v is None or v[i] is None else float(v[i])

    def cell(v, spec):
        return "-" if v is None else format(v, spec)

    for key in procedural["settings"]["methods"]:
        rp, rr = sp["methods"][key], sr["methods"][key]
        for i, part in enumerate(parts):
            rot_p, rot_r = val(rp, "rot_deg", i), val(rr, "rot_deg", i)
            tr_p, tr_r = val(rp, "trans", i), val(rr, "trans", i)
            ratio_rot = rot_r / rot_p if rot_p and rot_r is not None else None
            ratio_tr = tr_r / tr_p if tr_p and tr_r is not None else None
            lines.append(
                f"| {METHODS[key].label} | {part} | {cell(rot_p, '.2f')} | {cell(rot_r, '.2f')} | {cell(ratio_rot, '.2f')}x "
                f"| {cell(tr_p, '.3f')} | {cell(tr_r, '.3f')} | {cell(ratio_tr, '.2f')}x "
                f"| {cell(val(rp, 'iou', i), '.1f')} | {cell(val(rr, 'iou', i), '.1f')} |"
            )
    lines += ["", "| Method | Joint | Axis angle (°) procedural | real | State error procedural | real |", "|---|---|---|---|---|---|"]
    for key in procedural["settings"]["methods"]:
        rp, rr = sp["methods"][key], sr["methods"][key]
        for k, joint in enumerate(joints):
            lines.append(f"| {METHODS[key].label} | {joint} | {cell(val(rp, 'axis_deg', k), '.2f')} | "
                         f"{cell(val(rr, 'axis_deg', k), '.2f')} | {cell(val(rp, 'state_err', k), '.3f')} | "
                         f"{cell(val(rr, 'state_err', k), '.3f')} |")
    failures = ", ".join(f"{METHODS[k].label} {sr['methods'][k]['failures']}/{sr['methods'][k]['frames']}"
                         for k in real["settings"]["methods"])
    lines += ["", f"Failed fits on the real split: {failures}."]
    return lines


def write_real_report(procedural: dict, procedural_summary: dict, real: dict, real_summary: dict, out_dir, *,
                      command: str) -> Path:
    """Write ``<category>_real.md``: the real test split beside the procedural one (Table 1, ratios).

    The summaries are the evaluations' :func:`summarize` results (measured by the caller)."""
    category = procedural["category"]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    date = utc_date()
    s = real["settings"]
    every = s.get("real_split") == "all"
    which = ("every imported object (train and test: the training objects were seen in training, so this is no "
             "held-out measure)" if every else "the test split")
    md = [
        f"# {category}: real {'objects' if every else 'test objects'} beside procedural test instances",
        "",
        f"Command: `{command}`  ",
        f"Date: {date}  ",
        f"Weights: {_weights_line(s)}  ",
        f"Real objects: {which} of the catalog `{s['real_catalog']}` ({len(s.get('real_instances', []))}: "
        f"{', '.join(s.get('real_instances', []))}; imported PartNet-Mobility objects in the "
        "category's convention, `ancsh data import`), rendered with the same renderer, noise, viewpoints and points "
        "as the procedural test instances. Means over frames; translation in object units; failed fits left out.",
        "",
        *split_comparison(procedural, procedural_summary, real, real_summary),
        "",
        "## Table 1 on the real split (means)",
        "",
        *_table1(real_summary, dict(s), "mean", None),
        "",
    ]
    path = out / f"{category}_real.md"
    write_text(path, "\n".join(md))
    return path


def write_report(evaluation: dict, summary: dict, out_dir, *, command: str, real: tuple | None = None) -> dict:
    """Write ``<category>.md``, ``<category>.json`` and ``<category>_occlusion.png`` to ``out_dir``.

    Parameters
    ----------
    evaluation : dict
        :func:`evaluate_category` output (settings and the per-frame records, for ``per_frame``).
    summary : dict
        ``summarize(evaluation)``: the report writes it and computes no statistic itself.
    out_dir : path
    command : str
        The command line that produced ``evaluation`` (quoted in the report).
    real : (dict, dict), optional
        ``(real_evaluation, summarize(real_evaluation))`` of the real test split from the same run:
        the report then shows it beside the procedural split (:func:`split_comparison`) and points to
        ``<category>_real.md`` (:func:`write_real_report`) for its full tables.

    Returns ``{"md", "json", "png"}`` paths. The JSON schema is in ``docs/REPORT_SCHEMAS.md``.
    """
    category = evaluation["category"]
    s = dict(evaluation["settings"], category=category)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"md": out / f"{category}.md", "json": out / f"{category}.json", "png": out / f"{category}_occlusion.png"}
    date = utc_date()
    plot_occlusion(summary, s, paths["png"])
    paper1, paper2 = PAPER_TABLE1.get(category), PAPER_TABLE2.get(category)
    t = summary["timing"]
    parts = ", ".join(s["part_names"])
    joints = ", ".join(f"{n} ({ty})" for n, ty in zip(s["joint_names"], s["joint_types"]))
    state_unit = "degrees" if all(ty == "revolute" for ty in s["joint_types"]) else "object units (prismatic)"
    md = [
        f"# {category}: learned ANCSH on held-out instances",
        "",
        f"Command: `{command}`  ",
        f"Date: {date}  ",
        f"Frames: {s['frames']} (requested {s['frames_requested']}) rendered frames `0..{s['frames'] - 1}` of the test "
        f"stream (seed {s['seed']}) over the {s['test_instances']} held-out {category} instances, "
        f"{s['num_points']} points each, Kinect-like depth noise  ",
        f"Weights: {_weights_line(s)}"
        + (f"; direct voting: `{Path(s['direct_weights']).name}`" if s["direct_weights"] else "") + "  ",
        f"Parts (in the order of every list below): {parts}; joints: {joints}",
        "",
        "Statistics: **means** over frames (the paper's official evaluation script averages per part; the paper "
        "does not say), medians in the second table. Failed fits are left out of the statistics and counted. "
        "Rotation in degrees; translation and line–line distance divided by the object scale (object units) as "
        f"in the paper; 3D IoU of the amodal part boxes in %; joint-state error in {state_unit}. "
        "Metrics: `ancsh.evaluation.evaluate_fit`.",
        "",
        "Methods (all fit the output of the one ANCSH network, so they differ only in how they use it): "
        "**NPCS** = per-part Umeyama + RANSAC on the predicted NPCS; **NAOCS** = per-part poses fitted from the "
        "predicted NAOCS `G_s·NPCS + G_t` with the network's per-point `G_s, G_t` (reported as NPCS poses through "
        "the per-part median `G_s, G_t`; with per-part `G` it would equal NPCS exactly; no boxes, as in the paper); **ANCSH-soft** = the paper's combined optimisation with soft joint energies (`soft`, "
        "`FitConfig.paper()`, also used for NPCS and NAOCS); **ANCSH-exact** = joints as exact constraints, reduced "
        "(object pose + joint states) and maximal (all part poses + equality constraints) coordinates, IPOPT, "
        "the shipped networks' default `FitConfig` (`LearnedProvider.fit_config()`, "
        "`ancsh.solvers.formulations.DEFAULT_OBJECTIVES`). The NPCS and NAOCS baselines use the ANCSH network's own heads, not separately "
        "trained networks. " + ("The paper's rows are its Table 1 (its CAD datasets, not our procedural instances)."
                                if paper1 else f"The paper has no {category} category, so no paper rows."),
        "",
        "## Table 1 (means)",
        "",
        *_table1(summary, s, "mean", paper1),
        "",
        "## Table 1 (medians)",
        "",
        *_table1(summary, s, "median", None),
        "",
        "## 3D IoU: estimated box vs a true-size box at the fitted pose (means, %)",
        "",
        "The second column places a box of the part's true size at the fitted pose: when it is low too, the "
        "pose (not the size estimate from the NPCS extents) limits the IoU. Thin parts are the typical case: a "
        "few degrees of rotation move the box faces by more than the part's thickness.",
        "",
        "| Method | 3D IoU, estimated box | 3D IoU, true size at the fitted pose |",
        "|---|---|---|",
        *[f"| {METHODS[key].label} | {_fmt(row['iou']['mean'], '.1f')} | {_fmt(row['iou_pose']['mean'], '.1f')} |"
          for key, row in summary["methods"].items() if key != "naocs"],
        "",
        "## Table 2: joint parameters, direct voting vs ANCSH (means, camera frame)",
        "",
        f"| Method | Joint-axis angle (°) | Line–line distance | Axis over {AXIS_FLIP_DEG:g}°: frames (mean of the rest, °) |",
        "|---|---|---|---|",
    ]

    def row2(label: str, row: dict) -> str:
        return (f"| {label} | {_fmt(row['axis_deg']['mean'], '.2f')} | {_fmt(row['line_dist']['mean'], '.3f')} "
                f"| {_axis_tail_cell(row.get('axis_tail'))} |")

    if "direct_voting" in summary["table2"]:
        md.append(row2("Direct voting (PointNet++)", summary["table2"]["direct_voting"]))
    else:
        md.append("| Direct voting (PointNet++) | not shipped | not shipped | |")
    if "naocs_vote" in summary["table2"]:
        md.append(row2("ANCSH network: voted joints in NAOCS, before fitting", summary["table2"]["naocs_vote"]))
    for key, row in summary["methods"].items():
        if key in ("soft", "exact_reduced", "exact_maximal", "template", "network"):
            md.append(row2(METHODS[key].label, row))
    for name, row in (paper2 or {}).items():
        label = "PointNet++ (direct voting)" if name == "direct_voting" else name
        md.append(f"| *paper: {label}* | {_fmt(row.get('axis_deg'), '.1f')} | {_fmt(row.get('line_dist'), '.3f')} | |")
    md += ["", "Camera-frame joint errors after fitting include the error of the fitted part poses (the axis is "
           "carried into the camera by the base pose); the NAOCS row measures the network's joint vote alone. "
           f"An axis more than {AXIS_FLIP_DEG:g}° off is the wrong axis (for example an oven's side-hinged door read as "
           "hinged at its bottom), not a noisy estimate of the right one: the last column counts those frames per joint and gives "
           "the mean of the others, so a few such frames carrying a mean can be told from a spread of small errors."]
    if "direct_voting" not in summary["table2"]:
        md += ["", f"No direct-voting network is shipped for {category} (shipped weights: "
               f"{', '.join(s['available_weights']) or 'none'}), so our direct-voting row is missing."]
    md += _budget_section(summary, s)
    md += [
        "",
        "## Occlusion: error vs visible-area ratio",
        "",
        "Visible-area ratio = visible surface area / total surface area of the part (ray-cast surface samples, "
        "as in the paper's supplementary occlusion study). Frames are binned per part by that ratio.",
        "",
        f"![error vs visible-area ratio]({paths['png'].name})",
        "",
        *_occlusion_table(summary["occlusion"], s["methods"]),
        f"## Timings ({describe_machine(s.get('machine'))})",
        "",
        f"- network forward (all points, {s['num_threads']} torch thread(s)), per frame: "
        f"mean {t['network_ms']['mean']:.1f} ms, median {t['network_ms']['median']:.1f} ms",
    ]
    for key, row in summary["methods"].items():
        md.append(f"- fit {METHODS[key].label}: mean {row['fit_ms']['mean']:.1f} ms, median {row['fit_ms']['median']:.1f} ms")
    if "direct_voting_network_ms" in t:
        md.append(f"- direct-voting network + voting: mean {t['direct_voting_network_ms']:.1f} ms")
    md += _refine_lines(summary)
    md += [
        f"- frame rendering (not part of the pipeline): mean {t['generate_ms']['mean']:.1f} ms",
        f"- whole evaluation: {t['wall_s']:.0f} s wall",
        "",
    ]
    if real is not None:
        md += ["## The real test split beside the procedural one (means)", "",
               "The same network and fits on imported real objects of the category's test split, rendered with the "
               "same renderer, noise, viewpoints and points; ratio = real / procedural (the goal: at most 1.25x per "
               f"part). Full tables of the real split: `{category}_real.md`.", "",
               *split_comparison(evaluation, summary, real[0], real[1]), ""]
    write_text(paths["md"], "\n".join(md))
    from ..._version import __version__

    data = {
        "category": category, "command": command, "date": date, "ancsh_version": __version__, "settings": s, "summary": summary,
        "paper": {"table1": paper1, "table2": paper2}, "per_frame": _per_frame(evaluation),
    }
    if real is not None:  # the real split's summary, so that its figures can be read back (ancsh weights --reports)
        rs = real[0]["settings"]
        data["real"] = {"settings": {k: rs[k] for k in ("frames", "real_catalog", "real_instances", "weights_sha256")},
                        "summary": {k: real[1][k] for k in ("methods", "table2", "budget") if k in real[1]}}
    write_json(paths["json"], data, one_line=("per_frame",))
    return paths


def _weights_line(s: dict) -> str:
    """The network (and refinement network) of an evaluation: file, training step, SHA-256 prefix."""
    line = f"`{Path(s['weights']).name}` (step {s['weights_step']}, sha256 {s['weights_sha256'][:12]})"
    if s.get("refiner"):
        sha = s.get("refiner_sha256") or ""
        passes = s.get("refine_passes") or 2  # reports before the option ran two passes
        line += (f"; refinement network: `{Path(s['refiner']).name}` (step {s.get('refiner_step')}, sha256 {sha[:12]}, "
                 f"{passes_text(passes)})")
    return line
