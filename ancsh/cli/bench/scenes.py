"""``ancsh bench scenes``: the arguments of :mod:`ancsh.studies.scenes`."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from ...outputs import output_flags
from .._args import changed_options, non_negative_int, positive_int, shipped_categories_option


def register(sub) -> None:
    """Add ``ancsh bench scenes`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("scenes", help="ancsh predict without a mask on rendered scenes (floor or stairs, wall or "
                       "curtain, clutter), with the object's mask, and on the same scenes without the object")
    p.add_argument("--categories", nargs="+", help="categories (default: every one with shipped weights)")
    p.add_argument("--frames", type=positive_int, default=20, help="scenes per category (default 20)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="seed of the test frames and scenes (default 0)")
    p.add_argument("--stress-frames", type=non_negative_int, default=8, metavar="N",
                   help="stress scenes per category: two or three objects of the category, one translucent, keyed by "
                   "object (ancsh.studies.stress_scenes; default 8, 0: none)")
    p.add_argument("--seeds", type=non_negative_int, nargs="+", default=[0], metavar="SEED",
                   help="predict seeds of the stress scenes' runs without a mask, for their seed agreement (default 0; "
                   "the issue's measure: 0 1 2 3 4 5 6 7 8 9)")
    p.add_argument("--out", type=Path, help="report file (default: a fresh ancsh_results/scenes-<time>/scenes.md)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/scenes.md (when --out is not given)")
    p.add_argument("--records", type=Path, nargs="+", metavar="JSON", help="write the report again from a report's "
                   "records (its scenes.json; the measuring run's command, date and machine kept) instead of fitting "
                   "the scenes; several: the runs of one command on other --categories (two processes on two cores), "
                   "merged into one report")
    p.add_argument("--real-frames", type=Path, metavar="JSON", default=None,
                   help="a bench real-frames JSON summarised beside the scenes (default: docs/results/real_frames.json "
                   "where it exists; 'none' for no such table)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ...outputs import report_path
    from ...studies.report import Provenance
    from ...studies.scenes import measure_scenes, write_scenes_report

    categories = shipped_categories_option(args.categories)
    parts = ["bench", "scenes", *changed_options(args, {"categories": None, "frames": 20, "seed": 0, "stress_frames": 8,
                                                        "seeds": [0], "real_frames": None})]
    parts += output_flags(args.out, update_docs=args.update_docs)
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    path = report_path(args.out, update_docs=args.update_docs, docs_name="scenes.md", command="scenes")
    from ...outputs import DOCS_RESULTS

    real = DOCS_RESULTS / "real_frames.json" if args.real_frames is None else args.real_frames
    real = None if str(real) == "none" or not Path(real).is_file() else real
    if args.real_frames is not None and str(args.real_frames) != "none" and real is None:
        raise ValueError(f"--real-frames: no such file {args.real_frames}")
    if args.records is not None:
        from ...studies.scenes import load_scenes_records, merge_scenes_records

        if args.categories is not None or args.frames != 20 or args.seed != 0 or args.stress_frames != 8 \
                or args.seeds != [0]:
            raise ValueError("--records: the records hold their own categories, frames and seeds; leave out "
                             "--categories, --frames, --seed, --stress-frames and --seeds")
        results, provenance = merge_scenes_records(load_scenes_records(r) for r in args.records)
        rewritten = "ancsh " + " ".join(shlex.quote(a) for a in ["bench", "scenes", "--records", *map(str, args.records),
                                                                   *changed_options(args, {"real_frames": None}),
                                                                   *output_flags(args.out, update_docs=args.update_docs)])
        write_scenes_report(results, path, provenance, rewritten_by=rewritten, real_frames=real)
    else:
        progress = None if args.quiet else (lambda line: print(line, flush=True))
        results = measure_scenes(categories, frames=args.frames, seed=args.seed, progress=progress)
        if args.stress_frames:
            from ...studies.stress_scenes import measure_stress_scenes

            results["stress"] = measure_stress_scenes(categories, args.stress_frames, seed=args.seed, seeds=args.seeds,
                                                      progress=progress)
        write_scenes_report(results, path, Provenance(command), real_frames=real)
    print(path.read_text())
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
