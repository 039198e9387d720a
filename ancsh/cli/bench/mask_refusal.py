"""``ancsh bench mask-refusal``: the arguments of :mod:`ancsh.studies.mask_refusal`."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from ...outputs import output_flags
from .._args import changed_options, non_negative_int, shipped_categories_option


def register(sub) -> None:
    """Add ``ancsh bench mask-refusal`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("mask-refusal", help="what each p_object threshold refuses under a mask: correct fits of the "
                       "category against other categories and clutter (masked renders)")
    p.add_argument("--categories", nargs="+", help="categories (default: every one with shipped weights)")
    p.add_argument("--frames", type=int, default=40, help="object frames per category, about as many others (default "
                   "40, at least 8)")
    p.add_argument("--seed", type=non_negative_int, default=29, help="seed of the renders (default 29; the object "
                   "calibrations were fitted at 11)")
    p.add_argument("--out", type=Path, help="report file (default: a fresh ancsh_results/mask-refusal-<time>/"
                   "mask_refusal.md)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/mask_refusal.md (when --out is not "
                   "given)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ...learned.inference.checks import MIN_P_OBJECT_MASKED
    from ...outputs import report_path
    from ...studies.mask_refusal import measure_mask_refusal, write_mask_refusal_report
    from ...studies.report import Provenance

    categories = shipped_categories_option(args.categories)
    parts = ["bench", "mask-refusal", *changed_options(args, {"categories": None, "frames": 40, "seed": 29})]
    parts += output_flags(args.out, update_docs=args.update_docs)
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    path = report_path(args.out, update_docs=args.update_docs, docs_name="mask_refusal.md", command="mask-refusal")
    results = measure_mask_refusal(categories, frames=args.frames, seed=args.seed, progress=not args.quiet)
    write_mask_refusal_report(results, path, Provenance(command), chosen=MIN_P_OBJECT_MASKED)
    print(path.read_text())
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
