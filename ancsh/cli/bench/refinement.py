"""``ancsh bench template-refinement`` and ``ancsh bench refine-defaults``: the arguments of :mod:`ancsh.studies.refinement`."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from ...outputs import output_flags
from .._args import changed_options


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
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=run)
    d = sub.add_parser("refine-defaults", help="decide refine='auto' per category (the category template, the "
                       "refinement network or neither) from the full evaluations (ancsh evaluate --refine template "
                       "network reports) and optionally install it",
                       description="Read each category's <category>.json of `ancsh evaluate --refine template network` "
                       "in --reports; a refinement helps where it lowered every part's mean rotation error without "
                       "raising any joint's mean state error by more than 5 % on the procedural test split and, where "
                       "the report has a real split, did not raise the mean rotation over the parts nor a joint's state "
                       "error by more than 5 % there; auto takes the helping one with the lower mean rotation. Only "
                       "reports of the shipped weights (and refiner) count. Prints the decisions; --install writes "
                       "ancsh/data/templates/refine_defaults.json (categories without such a report: no refinement).")
    d.add_argument("--reports", type=Path, required=True, metavar="DIR", help="the evaluation reports (e.g. docs/results)")
    d.add_argument("--categories", nargs="+", help="categories (default: every one with shipped weights)")
    d.add_argument("--install", action="store_true", help="write ancsh/data/templates/refine_defaults.json")
    d.add_argument("--veto", action="append", default=[], metavar="CATEGORY:REFINEMENT=REASON",
                   help="do not choose REFINEMENT (template or network) for CATEGORY although its reports pass the "
                   "rule, for the evidence REASON names (e.g. real sensor frames); recorded with the decision "
                   "(repeatable)")
    d.set_defaults(func=run_defaults)


def run(args: argparse.Namespace) -> int:
    from ...learned.network.weights import shipped_categories
    from ...outputs import DOCS_RESULTS, fresh_output_dir
    from ...studies.refinement import run_template_refinement, write_summary

    cats = list(args.categories) if args.categories else list(shipped_categories())
    if args.frames < 1 or args.real_frames < 0:
        raise ValueError(f"--frames, --real-frames: expected >= 1 and >= 0, got {args.frames} and {args.real_frames}")
    parts = ["bench", "template-refinement", *changed_options(args, {"categories": None, "frames": 100, "real_frames": 50})]
    parts += output_flags(args.out, update_docs=args.update_docs)
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
    return 0


def run_defaults(args: argparse.Namespace) -> int:
    from ...studies.refinement import HELPS_RULE, REFINEMENTS, _fmt, defaults_from_reports, install_defaults

    parts = ["bench", "refine-defaults", "--reports", str(args.reports)]
    if args.categories:
        parts += ["--categories", *args.categories]
    if args.install:
        parts.append("--install")
    vetoes = {}
    for text in args.veto:
        key, sep, reason = text.partition("=")
        cat, colon, refinement = key.partition(":")
        if not (sep and colon and cat.strip() and refinement.strip() in REFINEMENTS and reason.strip()):
            raise ValueError(f"--veto: expected CATEGORY:REFINEMENT=REASON with REFINEMENT one of {REFINEMENTS}, got {text!r}")
        vetoes[(cat.strip(), refinement.strip())] = reason.strip()
        parts += ["--veto", text]
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    decisions = defaults_from_reports(args.reports, args.categories, vetoes)
    print(f"refine='auto' per category ({HELPS_RULE}):")
    for d in decisions:
        nums = "".join(f"; {k}: rotation {_fmt(d.rot_deg, '.2f')} -> {_fmt(r['rot_deg'], '.2f')} deg, joint state "
                       f"{_fmt(d.state_err, '.3g')} -> {_fmt(r['state_err'], '.3g')}"
                       + (f" (real split: rotation {_fmt(r['real_rot_deg_base'], '.2f')} -> {_fmt(r['real_rot_deg'], '.2f')})"
                          if "real_rot_deg" in r else "") for k, r in d.refined.items())
        frames = f" ({d.frames} frames)" if d.frames else ""
        print(f"  {d.category}: {d.choice or 'none'} -- {d.reason}{nums}{frames}")
    if args.install:
        print(f"installed {install_defaults(decisions, command)}")
    return 0
