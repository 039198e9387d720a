"""``ancsh bench twin``: the arguments of :mod:`ancsh.studies.twin`."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from ...outputs import output_flags
from .._args import changed_options, non_negative_int, positive_int, shipped_categories_option


def register(sub) -> None:
    """Add ``ancsh bench twin`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("twin", help="the exported model of a fit (--urdf) rendered against the depth it was fitted to, "
                       "learned and oracle fits side by side, every shipped category")
    p.add_argument("--categories", nargs="+", help="categories (default: every one with shipped weights)")
    p.add_argument("--frames", type=positive_int, default=20, help="test frames per category (default 20)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="base seed of the test frames (default 0)")
    p.add_argument("--out", type=Path, help="report file (default: a fresh ancsh_results/twin-<time>/twin.md)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/twin.md (when --out is not given)")
    p.add_argument("--box-extents", choices=("max", "unit_diagonal"), default="max",
                   help="the fits' FitConfig.box_extents (default max; docs/results/box_extents.md)")
    p.add_argument("--candidates", type=positive_int, default=None,
                   help="also choose each fit's template among this many nearest by render-and-compare against the "
                   "depth (reported beside the nearest one; 1 = the nearest only; default: as many as ancsh predict "
                   "--urdf chooses among, URDF_CANDIDATES)")
    p.add_argument("--align", type=non_negative_int, default=None,
                   help="also align the best this many of those templates to the depth by articulated ICP (reported "
                   "beside the unaligned choice; 0 = none; default: as many as ancsh predict --urdf aligns, URDF_ALIGN)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ...learned.inference.predict import URDF_ALIGN, URDF_CANDIDATES
    from ...outputs import report_path
    from ...studies.twin import measure_twin, write_twin_report

    categories = shipped_categories_option(args.categories)
    if args.candidates is None:
        args.candidates = URDF_CANDIDATES
    default_align = URDF_ALIGN if args.candidates > 1 else 0
    if args.align is None:
        args.align = default_align
    if args.align and args.candidates == 1:
        raise ValueError("--align: aligns the best of several templates; give --candidates K > 1 as well")
    parts = ["bench", "twin", *changed_options(args, {"categories": None, "frames": 20, "seed": 0, "box_extents": "max",
                                                          "candidates": URDF_CANDIDATES,
                                                          "align": default_align})]
    parts += output_flags(args.out, update_docs=args.update_docs)
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    path = report_path(args.out, update_docs=args.update_docs, docs_name="twin.md", command="twin")
    results = measure_twin(categories, frames=args.frames, seed=args.seed, progress=not args.quiet,
                           box_extents=args.box_extents, candidates=args.candidates, align=args.align)
    write_twin_report(results, path, command=command)
    print(path.read_text())
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
