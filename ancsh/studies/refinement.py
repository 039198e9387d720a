"""``ancsh bench template-refinement``: ANCSH-exact with and without the category-template refinement.

For every category with shipped weights, one :func:`~ancsh.studies.table1.evaluate_category` run
over held-out procedural frames (and the real test split where the shipped catalog has test objects)
fits ``exact_reduced`` and refines it (:func:`ancsh.solvers.icp.category.refine_fit`) on the same
network output, so the two rows differ only by the refinement. It writes each category's report
(``<category>.md``, ``<category>_real.md``, the same tables as ``ancsh evaluate``) into a folder and a
side-by-side summary (``template_refinement.md``) with the command that made it.

``ancsh bench refine-defaults`` decides the per-category default of ``refine="auto"`` from the
categories' full evaluations instead (``ancsh evaluate --refine template``: 500 or more frames, where the
side-by-side runs a few dozen) and installs it in ``ancsh/data/templates/refine_defaults.json``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .report import utc_date, write_text

__all__ = ["HELPS_RULE", "RefineDefault", "defaults_from_reports", "install_defaults", "refinement_helps", "refinement_rows", "run_template_refinement", "write_summary"]


HELPS_RULE = ("on where, on the procedural test split of the category's full evaluation (`ancsh evaluate --refine "
              "template`, the shipped weights), the refinement lowered the mean rotation error of every part and did "
              "not raise any joint's mean state error by more than 5 %")


def refinement_helps(summary: dict) -> bool:
    """The rule of :data:`HELPS_RULE` on one evaluation's :func:`~ancsh.studies.table1.summarize` result."""
    a, b = summary["methods"]["exact_reduced"], summary["methods"]["template"]
    rot_a, rot_b = np.array(a["rot_deg"]["mean"], dtype=float), np.array(b["rot_deg"]["mean"], dtype=float)
    st_a, st_b = np.array(a["state_err"]["mean"], dtype=float), np.array(b["state_err"]["mean"], dtype=float)
    return bool(np.all(rot_b < rot_a) and np.all(st_b <= 1.05 * st_a))


@dataclass(frozen=True)
class RefineDefault:
    """The ``refine="auto"`` decision for one category and the evidence it rests on.

    Attributes
    ----------
    category : str
    on : bool
        Whether ``refine="auto"`` refines against the category template.
    reason : str
        Why (the rule's verdict, or why there was no evidence).
    report : str or None
        The evaluation report read (``<category>.json``), None where there was none.
    command : str or None
        The command that produced that report.
    frames : int or None
        Its procedural test frames.
    rot_deg, rot_deg_refined : tuple of float
        Per part, mean rotation error (degrees) of ANCSH-exact and of the refined fit.
    state_err, state_err_refined : tuple of float
        Per joint, mean joint-state error (degrees for revolute joints, object units for prismatic ones).
    """

    category: str
    on: bool
    reason: str
    report: str | None = None
    command: str | None = None
    frames: int | None = None
    rot_deg: tuple = ()
    rot_deg_refined: tuple = ()
    state_err: tuple = ()
    state_err_refined: tuple = ()


def defaults_from_reports(reports_dir, categories=None) -> list[RefineDefault]:
    """Apply :func:`refinement_helps` to each category's full evaluation report.

    Parameters
    ----------
    reports_dir : path
        A folder of ``ancsh evaluate`` reports (``<category>.json``).
    categories : iterable of str, optional
        Default: every category with shipped ANCSH weights.

    Returns
    -------
    list of RefineDefault
        One per category; off where the report is missing, has no refined (``template``) rows, or was
        made with other weights than the shipped ones or on frames of another generator version (stale).
    """
    import json

    from ..data.procedural import generator_version
    from ..learned.network.weights import shipped_categories
    from .targets import is_shipped

    reports_dir = Path(reports_dir)
    if not reports_dir.is_dir():
        raise ValueError(f"reports_dir: not a folder: {reports_dir}")
    out = []
    for cat in (list(categories) if categories else shipped_categories()):
        path = reports_dir / f"{cat}.json"
        if not path.is_file():
            out.append(RefineDefault(cat, False, f"no evaluation report {path}"))
            continue
        report = json.loads(path.read_text())
        methods = report["summary"]["methods"]
        command = report.get("command")
        if "template" not in methods or "exact_reduced" not in methods:
            out.append(RefineDefault(cat, False, "its report has no refined rows (run `ancsh evaluate --refine template`)",
                                     str(path), command))
            continue
        if not is_shipped(cat, report["settings"].get("weights_sha256")):
            out.append(RefineDefault(cat, False, "its report is of other weights than the shipped ones (stale)",
                                     str(path), command))
            continue
        if report["settings"].get("generator_version") != generator_version(cat):
            out.append(RefineDefault(cat, False, f"its report's frames are not of today's generator (version "
                                     f"{generator_version(cat)}; stale)", str(path), command))
            continue
        a, b = methods["exact_reduced"], methods["template"]
        on = refinement_helps(report["summary"])
        rot_a, rot_b = tuple(a["rot_deg"]["mean"]), tuple(b["rot_deg"]["mean"])
        st_a, st_b = tuple(a["state_err"]["mean"]), tuple(b["state_err"]["mean"])
        if on:
            reason = "every part's rotation lower, no joint state more than 5 % higher"
        elif not all(y < x for x, y in zip(rot_a, rot_b)):
            reason = "some part's rotation not lower"
        else:
            reason = "a joint's state error more than 5 % higher"
        out.append(RefineDefault(cat, on, reason, str(path), command, int(report["settings"]["frames"]),
                                 rot_a, rot_b, st_a, st_b))
    return out


def install_defaults(decisions: list[RefineDefault], command: str, path=None) -> Path:
    """Write :func:`defaults_from_reports`' decisions to ``refine_defaults.json`` (read by
    :func:`ancsh.data.templates.refine_default`); returns the path written."""
    import json

    target = Path(path) if path is not None else Path(__file__).resolve().parents[1] / "data" / "templates" / "refine_defaults.json"
    evidence = {d.category: {k: v for k, v in dataclasses.asdict(d).items() if k not in ("category", "on")}
                for d in decisions}
    return write_text(target, json.dumps({"measured_by": command, "rule": HELPS_RULE,
                                          "categories": {d.category: d.on for d in decisions}, "evidence": evidence},
                                         indent=1) + "\n")


def run_template_refinement(categories, *, frames: int, real_frames: int, out_dir, command: str,
                            progress: bool = True) -> list[dict]:
    """Evaluate ``exact_reduced`` and ``template`` per category (procedural, and real where there are
    test objects); write each category's reports to ``out_dir``.

    Returns one ``{"category", "split", "evaluation", "summary"}`` per evaluated split.
    """
    from ..data.catalog import load_catalog
    from .table1 import evaluate_category, summarize, write_real_report, write_report

    catalog = load_catalog()
    out = []
    for cat in categories:
        ev = evaluate_category(cat, frames=frames, methods=("exact_reduced",), refine="template", progress=progress)
        sm = summarize(ev)
        write_report(ev, sm, out_dir, command=command)
        out.append({"category": cat, "split": "procedural", "evaluation": ev, "summary": sm})
        if real_frames and catalog.instances(cat, "test"):
            rv = evaluate_category(cat, frames=real_frames, methods=("exact_reduced",), refine="template", real="builtin",
                                   progress=progress)
            rs = summarize(rv)
            write_real_report(ev, sm, rv, rs, out_dir, command=command)
            out.append({"category": cat, "split": "real", "evaluation": rv, "summary": rs})
    return out


def _fmt(values, spec) -> str:
    return ", ".join("-" if v is None or not np.isfinite(v) else format(v, spec) for v in values)


def refinement_rows(result: dict) -> list[str]:
    """Markdown rows: the two methods of one category and split, side by side."""
    s = result["summary"]["methods"]
    ev = result["evaluation"]["settings"]
    st = ".1f" if all(t == "revolute" for t in ev["joint_types"]) else ".3f"
    rows = []
    for key, label in (("exact_reduced", "ANCSH-exact"), ("template", "+ template")):
        r = s[key]
        rows.append(
            f"| {result['category']} | {result['split']} ({ev['frames']}) | {label} | {_fmt(r['rot_deg']['mean'], '.2f')} "
            f"| {_fmt(r['rot_deg']['median'], '.2f')} | {_fmt(r['trans']['mean'], '.3f')} | {_fmt(r['state_err']['mean'], st)} "
            f"| {_fmt(r['axis_deg']['mean'], '.2f')} | {r['fit_ms']['mean']:.0f} |"
        )
    return rows


def _worse_share(result: dict, threshold: float = 2.0) -> tuple[float, float]:
    """Fractions of frames where the refinement made some part's rotation error more than ``threshold``
    degrees worse / better."""
    worse = better = n = 0
    for rec in result["evaluation"]["records"]:
        a, b = rec["methods"]["exact_reduced"], rec["methods"]["template"]
        if not (a["ok"] and b["ok"]):
            continue
        d = np.array([pb["rot_deg"] - pa["rot_deg"] for pa, pb in zip(a["parts"], b["parts"])])
        worse += bool(np.any(d > threshold))
        better += bool(np.any(d < -threshold))
        n += 1
    return (worse / n, better / n) if n else (float("nan"), float("nan"))


def write_summary(results: list[dict], path, *, command: str, folder) -> Path:
    """Write the side-by-side summary of :func:`run_template_refinement`'s results."""
    from .._machine import describe_machine, machine_facts
    from .table1.report import refine_summary_line

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    date = utc_date()
    lines = [
        "# Category-template refinement: ANCSH-exact with and without it",
        "",
        f"Command: `{command}`  ",
        f"Date: {date}  ",
        f"Machine: {describe_machine(machine_facts())}  ",
        f"Per-category reports (the same tables as `ancsh evaluate`, with the refined row beside ANCSH-exact): "
        f"`{folder}`",
        "",
        "Both rows fit the same network output (shipped weights) on the same held-out frames: **ANCSH-exact** = the "
        "`exact_reduced` fit; **+ template** = that fit refined by articulated ICP against the nearest training "
        "instance of the category (part boxes), scaled to the fitted object box, at three global scales (1, 0.94, "
        "0.88), keeping the ICP joints or only its object pose, and kept only where its score on the observed points "
        "beats the fit's (`ancsh.solvers.icp.category.refine_fit`, default `RefineConfig`). Rotation in degrees per "
        "part (part order of each category's report), translation in object units, joint state in degrees "
        "(revolute) or object units (drawer), joint axis in degrees; means over frames unless marked median. "
        "Time: the fit, and for the refined row fit + refinement, per frame (ms).",
        "",
        "| Category | Split (frames) | Method | Rotation (°) mean | Rotation (°) median | Translation | Joint state "
        "| Joint axis (°) | ms/frame |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines += refinement_rows(r)
    lines += ["", "| Category | Split | Refinement | Frames with a part > 2° worse | > 2° better | Helps (rule below) |",
              "|---|---|---|---|---|---|"]
    for r in results:
        worse, better = _worse_share(r)
        helps = ("yes" if refinement_helps(r["summary"]) else "no") if r["split"] == "procedural" else ""
        lines.append(f"| {r['category']} | {r['split']} | {refine_summary_line(r['summary']['methods']['template'])} "
                     f"| {100 * worse:.0f}% | {100 * better:.0f}% | {helps} |")
    lines += ["", "Helps: the rule of the per-category default on these frames. The default itself (`refine='auto'`, "
              "`ancsh predict`) is decided on each category's full evaluation, not on these few frames: `ancsh bench "
              f"refine-defaults --reports docs/results --install` ({HELPS_RULE}; "
              "`ancsh/data/templates/refine_defaults.json`)."]
    lines.append("")
    write_text(path, "\n".join(lines))
    return path
