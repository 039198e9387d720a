"""``ancsh bench real-frames``: the arguments of :mod:`ancsh.studies.real_frames`."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from ...outputs import output_flags
from .._args import category, category_as_given, named_value, non_negative_int, positive_int


def register(sub) -> None:
    """Add ``ancsh bench real-frames`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("real-frames", help="ancsh predict on real sensor frames with measured truth: with the mask, "
                       "without one and with a pixel hint; every category on frames without an object")
    p.add_argument("folders", nargs="*", type=Path, metavar="DIR",
                   help="real-frame folders (depth.png, K.json, truth.json, masks; default: every folder of "
                   "../shared/data/real_frames)")
    p.add_argument("--categories", nargs="+", type=category,
                   help="categories tried on frames without an object (names, spec files or built category folders; "
                   "default: every one with shipped weights); a frame's truth names the category of each object, "
                   "found by name (a built one: give its folder here or put it on ANCSH_CATEGORIES)")
    p.add_argument("--points", type=positive_int, default=1024, help="points per prediction (default 1024)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="sampling and RANSAC seed (default 0)")
    p.add_argument("--seeds", type=non_negative_int, nargs="+", default=[], metavar="SEED",
                   help="every run again at these seeds: the status's seed agreement and the states' spread (e.g. "
                   "0 1 2 3 4 5 6 7 8 9; default: none)")
    p.add_argument("--out", type=Path, help="report file (default: a fresh ancsh_results/real-frames-<time>/real_frames.md)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/real_frames.md (when --out is not given)")
    p.add_argument("--weights", action="append", default=[], metavar="CATEGORY=FILE",
                   help="a network under test instead of the category's shipped one (repeatable)")
    p.add_argument("--refine", action="append", default=[], metavar="CATEGORY=OPTION",
                   help="refine CATEGORY's fits with OPTION (template, network or none) instead of its default "
                   "(--refine auto of ancsh predict; its p_good / p_object calibrations were made on auto's fits) "
                   "(repeatable)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ...data.real_frames import default_real_frame_folders
    from ...outputs import report_path
    from ...studies.real_frames import measure_real_frames, write_real_frames_report

    folders = list(args.folders) or default_real_frame_folders()
    if not folders:
        raise ValueError("DIR: no real-frame folders given and none in ../shared/data/real_frames")
    parts = ["bench", "real-frames", *[str(f) for f in args.folders]]
    if args.categories:
        parts += ["--categories", *map(category_as_given, args.categories)]
    if args.points != 1024:
        parts += ["--points", str(args.points)]
    if args.seed != 0:
        parts += ["--seed", str(args.seed)]
    if args.seeds:
        parts += ["--seeds", *map(str, args.seeds)]
    weights = {}
    for item in args.weights:
        category, file = named_value(item, "--weights", "CATEGORY=FILE")
        if not Path(file).is_file():
            raise ValueError(f"--weights {item}: no such file")
        if category in weights:
            raise ValueError(f"--weights: {category!r} given twice")
        weights[category] = Path(file)
        parts += ["--weights", item]
    if weights and args.update_docs:
        raise ValueError("--weights: not with --update-docs (docs/results/real_frames.md is the shipped networks')")
    refine = {}
    for item in args.refine:
        category, option = named_value(item, "--refine", "CATEGORY=OPTION")
        if option not in ("template", "network", "none"):
            raise ValueError(f"--refine {item}: expected template, network or none after '='")
        if category in refine:
            raise ValueError(f"--refine: {category!r} given twice")
        refine[category] = option
        parts += ["--refine", item]
    if refine and args.update_docs:
        raise ValueError("--refine: not with --update-docs (docs/results/real_frames.md is ancsh predict's default)")
    parts += output_flags(args.out, update_docs=args.update_docs)
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    path = report_path(args.out, update_docs=args.update_docs, docs_name="real_frames.md", command="real-frames")
    results = measure_real_frames(folders, categories=args.categories, seed=args.seed, num_points=args.points,
                                  progress=not args.quiet, weights=weights, refine=refine, seeds=args.seeds)
    write_real_frames_report(results, path, command=command)
    print(path.read_text())
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
