"""``ancsh bench track-scenes``: the arguments of :mod:`ancsh.studies.track_scenes`."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from ...outputs import output_flags
from .._args import changed_options, non_negative_int, positive_int


def register(sub) -> None:
    """Add ``ancsh bench track-scenes`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("track-scenes", help="multi-object tracking against per-frame predict on rendered scene "
                       "sequences (two or three objects, one opening, an occluder, a translucent one, an empty scene)")
    p.add_argument("--categories", nargs="+", default=["box", "laptop"], help="categories (default: box laptop)")
    p.add_argument("--length", type=positive_int, default=90, help="frames per sequence (default 90: 3 s at 30 frames/s)")
    p.add_argument("--sequences", nargs="+", default=None, metavar="NAME",
                   help="which sequences (default: pair triple empty)")
    p.add_argument("--seed", type=non_negative_int, default=0)
    p.add_argument("--no-baseline", dest="baseline", action="store_false",
                   help="do not run per-frame predict (no ratios; for a quick look)")
    p.add_argument("--out", type=Path, help="report file (default: a fresh ancsh_results/track-scenes-<time>/)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/track_scenes.md (when --out is not "
                   "given)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ...outputs import report_path
    from ...studies.report import Provenance
    from ...studies.track_scenes import SEQUENCES, measure_track_scenes, write_track_scenes_report

    sequences = tuple(args.sequences) if args.sequences else tuple(SEQUENCES)
    for name in sequences:
        if name not in SEQUENCES:
            raise ValueError(f"--sequences: unknown sequence {name!r} (known: {', '.join(SEQUENCES)})")
    parts = ["bench", "track-scenes", *changed_options(args, {"categories": ["box", "laptop"], "length": 90,
                                                               "sequences": None, "seed": 0})]
    parts += [] if args.baseline else ["--no-baseline"]
    parts += output_flags(args.out, update_docs=args.update_docs)
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    path = report_path(args.out, update_docs=args.update_docs, docs_name="track_scenes.md", command="track-scenes")
    progress = None if args.quiet else (lambda line: print(line, flush=True))
    results = measure_track_scenes(args.categories, length=args.length, seed=args.seed, sequences=sequences,
                                   baseline=args.baseline, progress=progress)
    write_track_scenes_report(results, path, Provenance(command))
    print(path.read_text())
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
