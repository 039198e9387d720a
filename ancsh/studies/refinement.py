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

__all__ = ["HELPS_RULE", "REFINEMENTS", "RefineDefault", "defaults_from_reports", "install_defaults", "refinement_helps", "refinement_rows", "run_template_refinement", "write_summary"]


REFINEMENTS = ("template", "network")
"""What ``refine="auto"`` may choose per category: the category template or the refinement network."""

HELPS_RULE = ("a refinement (the category template, the refinement network) helps a category where, in its full "
              "evaluation (`ancsh evaluate --refine template network`, the shipped weights), it lowered the mean "
              "rotation error of every part on the procedural test split without raising any joint's mean state error "
              "by more than 5 %, and, where the report has a real split, did not raise the mean rotation error over "
              "the parts there nor any joint's mean state error by more than 5 %; of the refinements that help, "
              "refine='auto' takes the one with the lower mean rotation error over the parts on the procedural split")


def _helps(a: dict, b: dict) -> str | None:
    """``None`` where row ``b`` (refined) passes the procedural rule of :data:`HELPS_RULE` against ``a``, else why not."""
    rot_a, rot_b = np.array(a["rot_deg"]["mean"], dtype=float), np.array(b["rot_deg"]["mean"], dtype=float)
    st_a, st_b = np.array(a["state_err"]["mean"], dtype=float), np.array(b["state_err"]["mean"], dtype=float)
    if not np.all(rot_b < rot_a):
        return "some part's rotation not lower"
    if not np.all(st_b <= 1.05 * st_a):
        return "a joint's state error more than 5 % higher"
    return None


def _real_ok(a: dict, b: dict) -> str | None:
    """``None`` where row ``b`` passes the real-split rule of :data:`HELPS_RULE` against ``a``, else why not."""
    rot_a, rot_b = np.array(a["rot_deg"]["mean"], dtype=float), np.array(b["rot_deg"]["mean"], dtype=float)
    st_a, st_b = np.array(a["state_err"]["mean"], dtype=float), np.array(b["state_err"]["mean"], dtype=float)
    if rot_b.mean() > rot_a.mean():
        return f"on the real split the mean rotation rose ({rot_a.mean():.2f} -> {rot_b.mean():.2f} deg)"
    if not np.all(st_b <= 1.05 * st_a):
        return "on the real split a joint's state error more than 5 % higher"
    return None


def refinement_helps(summary: dict, key: str = "template", real_summary: dict | None = None) -> bool:
    """The rule of :data:`HELPS_RULE` for refinement ``key`` on one evaluation's :func:`~ancsh.studies.table1.summarize`
    result (and its real split's, where given)."""
    m = summary["methods"]
    if _helps(m["exact_reduced"], m[key]) is not None:
        return False
    if real_summary is None or key not in real_summary["methods"]:
        return True
    return _real_ok(real_summary["methods"]["exact_reduced"], real_summary["methods"][key]) is None


@dataclass(frozen=True)
class RefineDefault:
    """The ``refine="auto"`` decision for one category and the evidence it rests on.

    Attributes
    ----------
    category : str
    choice : str or None
        What ``refine="auto"`` does: ``"template"`` (refine against the category template), ``"network"`` (the
        refinement network) or ``None`` (no refinement).
    reason : str
        Why (the rule's verdict per refinement, or why there was no evidence).
    report : str or None
        The evaluation report read (``<category>.json``), None where there was none.
    command : str or None
        The command that produced that report.
    frames : int or None
        Its procedural test frames.
    rot_deg : tuple of float
        Per part, mean rotation error (degrees) of ANCSH-exact on the procedural split.
    state_err : tuple of float
        Per joint, its mean joint-state error (degrees for revolute joints, object units for prismatic ones).
    refined : dict
        Per refinement in the report (``"template"``, ``"network"``): ``rot_deg``, ``state_err`` (procedural
        split), ``real_rot_deg``, ``real_state_err`` (real split, where evaluated, with ``real_rot_deg_base``,
        ``real_state_err_base`` of ANCSH-exact there), ``helps`` and ``reason``.
    """

    category: str
    choice: str | None
    reason: str
    report: str | None = None
    command: str | None = None
    frames: int | None = None
    rot_deg: tuple = ()
    state_err: tuple = ()
    refined: dict = dataclasses.field(default_factory=dict)

    @property
    def on(self) -> bool:
        """Whether ``refine="auto"`` refines at all."""
        return self.choice is not None


def _decide(cat: str, report: dict, path: Path, vetoes: dict) -> RefineDefault:
    """:func:`defaults_from_reports`' decision for one current report (``vetoes``: as there)."""
    from .targets import is_shipped

    methods = report["summary"]["methods"]
    real = (report.get("real") or {}).get("summary")
    command = report.get("command")
    a = methods["exact_reduced"]
    refined, reasons = {}, []
    for key in REFINEMENTS:
        if key not in methods:
            continue
        b = methods[key]
        entry = {"rot_deg": tuple(b["rot_deg"]["mean"]), "state_err": tuple(b["state_err"]["mean"])}
        why = _helps(a, b)
        if key == "network" and not is_shipped(cat, report["settings"].get("refiner_sha256"), "refine"):
            why = "its refinement-network rows are of another refiner than the shipped one (stale)"
        if why is None and real is not None and key in real["methods"]:
            ra, rb = real["methods"]["exact_reduced"], real["methods"][key]
            entry.update(real_rot_deg=tuple(rb["rot_deg"]["mean"]), real_state_err=tuple(rb["state_err"]["mean"]),
                         real_rot_deg_base=tuple(ra["rot_deg"]["mean"]), real_state_err_base=tuple(ra["state_err"]["mean"]))
            why = _real_ok(ra, rb)
        if why is None and (cat, key) in vetoes:
            why = f"vetoed: {vetoes[(cat, key)]}"
        entry.update(helps=why is None, reason=why or "helps")
        refined[key] = entry
        reasons.append(f"{key}: {why or 'helps'}")
    helping = [k for k in refined if refined[k]["helps"]]
    choice = min(helping, key=lambda k: float(np.mean(refined[k]["rot_deg"]))) if helping else None
    if len(helping) > 1:
        reasons.append(f"{choice} has the lower mean rotation")
    return RefineDefault(cat, choice, "; ".join(reasons), str(path), command, int(report["settings"]["frames"]),
                         tuple(a["rot_deg"]["mean"]), tuple(a["state_err"]["mean"]), refined)


def defaults_from_reports(reports_dir, categories=None, vetoes=None) -> list[RefineDefault]:
    """Apply the rule of :data:`HELPS_RULE` to each category's full evaluation report.

    Parameters
    ----------
    reports_dir : path
        A folder of ``ancsh evaluate`` reports (``<category>.json``).
    categories : iterable of str, optional
        Default: every category with shipped ANCSH weights.
    vetoes : dict, optional
        ``{(category, refinement): reason}``: evidence the reports do not hold (e.g. real sensor frames,
        ``ancsh bench real-frames``) against a refinement that passes the rule; it is not chosen, and the
        reason is recorded with the decision.

    Returns
    -------
    list of RefineDefault
        One per category; no refinement where the report is missing, has no refined (``template`` or ``network``)
        rows, or was made with other weights than the shipped ones or on frames of another generator version
        (stale); the refinement network only where its rows are of the shipped refiner.
    """
    import json

    from ..data.procedural import generator_version
    from ..learned.network.weights import shipped_categories
    from .targets import is_shipped

    reports_dir = Path(reports_dir)
    if not reports_dir.is_dir():
        raise ValueError(f"reports_dir: not a folder: {reports_dir}")
    vetoes = dict(vetoes or {})
    bad = [k for k in vetoes if not (isinstance(k, tuple) and len(k) == 2 and k[1] in REFINEMENTS)
           or not str(vetoes[k]).strip()]
    if bad:
        raise ValueError(f"vetoes: expected {{(category, one of {REFINEMENTS}): reason}}, got {bad}")
    out = []
    for cat in (list(categories) if categories else shipped_categories()):
        path = reports_dir / f"{cat}.json"
        if not path.is_file():
            out.append(RefineDefault(cat, None, f"no evaluation report {path}"))
            continue
        report = json.loads(path.read_text())
        methods = report["summary"]["methods"]
        command = report.get("command")
        if "exact_reduced" not in methods or not set(REFINEMENTS) & set(methods):
            out.append(RefineDefault(cat, None, "its report has no refined rows (run `ancsh evaluate --refine template "
                                     "network`)", str(path), command))
        elif not is_shipped(cat, report["settings"].get("weights_sha256")):
            out.append(RefineDefault(cat, None, "its report is of other weights than the shipped ones (stale)",
                                     str(path), command))
        elif report["settings"].get("generator_version") != generator_version(cat):
            out.append(RefineDefault(cat, None, f"its report's frames are not of today's generator (version "
                                     f"{generator_version(cat)}; stale)", str(path), command))
        else:
            out.append(_decide(cat, report, path, vetoes))
    return out


def install_defaults(decisions: list[RefineDefault], command: str, path=None) -> Path:
    """Write :func:`defaults_from_reports`' decisions to ``refine_defaults.json`` (read by
    :func:`ancsh.data.templates.refine_default`); returns the path written."""
    import json

    target = Path(path) if path is not None else Path(__file__).resolve().parents[1] / "data" / "templates" / "refine_defaults.json"
    evidence = {d.category: {k: v for k, v in dataclasses.asdict(d).items() if k not in ("category", "choice")}
                for d in decisions}
    return write_text(target, json.dumps({"measured_by": command, "rule": HELPS_RULE,
                                          "categories": {d.category: d.choice for d in decisions}, "evidence": evidence},
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
