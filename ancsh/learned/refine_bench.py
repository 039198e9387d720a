"""``ancsh bench template-refinement``: ANCSH-exact with and without the category-template refinement.

For every category with shipped weights, one :func:`~ancsh.learned.evaluate.evaluate_category` run
over held-out procedural frames (and the real test split where the shipped catalog has test objects)
fits ``exact_reduced`` and refines it (:func:`ancsh.solvers.icp.category.refine_fit`) on the same
network output, so the two rows differ only by the refinement. It writes each category's report
(``<category>.md``, ``<category>_real.md``, the same tables as ``ancsh evaluate``) into a folder and a
side-by-side summary (``template_refinement.md``) with the command that made it.
"""

from __future__ import annotations

import argparse
import datetime
import shlex
from pathlib import Path

import numpy as np

from ..outputs import output_flags

__all__ = ["defaults_from", "refinement_helps", "register", "refinement_rows", "run_template_refinement", "write_summary"]


def register(sub) -> None:
    """Add ``ancsh bench template-refinement`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("template-refinement", help="ANCSH-exact with and without the category-template refinement, "
                       "side by side (shipped weights)")
    p.add_argument("--categories", nargs="+", help="categories (default: every one with shipped weights)")
    p.add_argument("--frames", type=int, default=100, help="procedural test frames per category (default 100)")
    p.add_argument("--real-frames", type=int, default=50,
                   help="real test-split frames per category where the shipped catalog has test objects (default 50; 0 = none)")
    p.add_argument("--out", type=Path, help="folder (default: a fresh ancsh_results/template-refinement-<time>/)")
    p.add_argument("--update-docs", action="store_true", help="write into docs/results/ (when --out is not given)")
    p.add_argument("--install-defaults", action="store_true",
                   help="write ancsh/data/templates/refine_defaults.json (refine='auto'): on for the categories where "
                   "the refinement helped on the procedural split (refinement_helps)")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..outputs import DOCS_RESULTS, fresh_output_dir
    from .weights import shipped_categories

    cats = list(args.categories) if args.categories else list(shipped_categories())
    if args.frames < 1 or args.real_frames < 0:
        raise ValueError(f"--frames, --real-frames: expected >= 1 and >= 0, got {args.frames} and {args.real_frames}")
    parts = ["bench", "template-refinement"]
    if args.categories:
        parts += ["--categories", *args.categories]
    if args.frames != 100:
        parts += ["--frames", str(args.frames)]
    if args.real_frames != 50:
        parts += ["--real-frames", str(args.real_frames)]
    parts += output_flags(args.out, update_docs=args.update_docs)
    if args.install_defaults:
        parts.append("--install-defaults")
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    if args.out is not None:
        summary_path, folder = args.out / "template_refinement.md", args.out
    elif args.update_docs:
        summary_path, folder = DOCS_RESULTS / "template_refinement.md", DOCS_RESULTS / "template_refinement"
    else:
        folder = fresh_output_dir("template-refinement")
        summary_path = folder / "template_refinement.md"
    results = run_template_refinement(cats, frames=args.frames, real_frames=args.real_frames, out_dir=folder,
                                      command=command, progress=not args.no_progress)
    path = write_summary(results, summary_path, command=command, folder=folder)
    print(path.read_text())
    print(f"wrote {path} and the per-category reports in {folder}")
    if args.install_defaults:
        import json

        target = Path(__file__).resolve().parents[1] / "data" / "templates" / "refine_defaults.json"
        target.write_text(json.dumps({"measured_by": command, "summary": str(path), "rule": HELPS_RULE,
                                      "categories": defaults_from(results)}, indent=1) + "\n")
        print(f"installed {target}")
    return 0


HELPS_RULE = ("on where, on the procedural test split, the refinement lowered the mean rotation error of every part "
              "and did not raise the mean joint-state error by more than 5 %")


def refinement_helps(summary: dict) -> bool:
    """The rule of :data:`HELPS_RULE` on one evaluation's :func:`~ancsh.learned.evaluate.summarize` result."""
    a, b = summary["methods"]["exact_reduced"], summary["methods"]["template"]
    rot_a, rot_b = np.array(a["rot_deg"]["mean"], dtype=float), np.array(b["rot_deg"]["mean"], dtype=float)
    st_a, st_b = np.array(a["state_err"]["mean"], dtype=float), np.array(b["state_err"]["mean"], dtype=float)
    return bool(np.all(rot_b < rot_a) and np.all(st_b <= 1.05 * st_a))


def defaults_from(results: list[dict]) -> dict:
    """``{category: on}`` from :func:`run_template_refinement`'s procedural results."""
    return {r["category"]: refinement_helps(r["summary"]) for r in results if r["split"] == "procedural"}


def run_template_refinement(categories, *, frames: int, real_frames: int, out_dir, command: str,
                            progress: bool = True) -> list[dict]:
    """Evaluate ``exact_reduced`` and ``template`` per category (procedural, and real where there are
    test objects); write each category's reports to ``out_dir``.

    Returns one ``{"category", "split", "evaluation", "summary"}`` per evaluated split.
    """
    from ..data.catalog import load_catalog
    from .evaluate import evaluate_category, summarize, write_real_report, write_report

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
    from .evaluate import refine_summary_line

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
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
    lines += ["", f"Rule for the per-category default (`refine='auto'`, `ancsh predict`; written by `--install-defaults` "
              f"to `ancsh/data/templates/refine_defaults.json`): {HELPS_RULE}."]
    lines.append("")
    path.write_text("\n".join(lines))
    return path
