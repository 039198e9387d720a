"""``ancsh bench train-test-gap``: the arguments of :mod:`ancsh.studies.train_test_gap`."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from ...outputs import output_flags
from .._args import non_negative_int


def register(sub) -> None:
    """Add ``ancsh bench train-test-gap`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("train-test-gap", help="the shipped networks on new views of their training instances "
                       "beside the held-out test instances (under-fitting or generalisation?)")
    p.add_argument("--categories", nargs="+", help="categories (default: every one with shipped weights)")
    p.add_argument("--frames", type=int, default=200, help="procedural frames per category and instance set (default 200)")
    p.add_argument("--real-frames", type=int, default=100,
                   help="real frames per category and instance set where the shipped catalog has objects of both "
                   "sets (default 100; 0 = none)")
    p.add_argument("--seed", type=non_negative_int, default=3, help="frame seed of both instance sets (default 3: neither the "
                   "training data's nor the evaluations' frames)")
    p.add_argument("--out", type=Path, help="report file (default: a fresh ancsh_results/train-test-gap-<time>/)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/train_test_gap.md (when --out is not given)")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ...learned.network.weights import shipped_categories
    from ...outputs import report_path
    from ...studies.train_test_gap import run_gap, write_gap_report

    if args.frames < 1 or args.real_frames < 0:
        raise ValueError(f"--frames, --real-frames: expected >= 1 and >= 0, got {args.frames} and {args.real_frames}")
    cats = list(args.categories) if args.categories else list(shipped_categories())
    parts = ["bench", "train-test-gap"]
    if args.categories:
        parts += ["--categories", *args.categories]
    if args.frames != 200:
        parts += ["--frames", str(args.frames)]
    if args.real_frames != 100:
        parts += ["--real-frames", str(args.real_frames)]
    if args.seed != 3:
        parts += ["--seed", str(args.seed)]
    parts += output_flags(args.out, update_docs=args.update_docs)
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    path = report_path(args.out, update_docs=args.update_docs, docs_name="train_test_gap.md", command="train-test-gap")
    results = run_gap(cats, frames=args.frames, real_frames=args.real_frames, seed=args.seed,
                      progress=not args.no_progress)
    write_gap_report(results, path, command=command)
    print(path.read_text())
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
