"""``ancsh bench sensor-realism``: the arguments of :mod:`ancsh.studies.sensor_realism`."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from ...outputs import output_flags
from .._args import changed_options, non_negative_int, positive_int


def register(sub) -> None:
    """Add ``ancsh bench sensor-realism`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("sensor-realism", help="depth-sensor artefacts (holes, dropped and mixed pixels at depth jumps, "
                       "depth steps) of real frames against rendered scenes under the dataset's and the measured noise")
    p.add_argument("folders", nargs="*", type=Path, metavar="DIR",
                   help="real-frame folders (default: every folder of ../shared/data/real_frames)")
    p.add_argument("--categories", nargs="+", default=["box", "laptop"],
                   help="categories of the rendered scenes (default: box laptop)")
    p.add_argument("--frames", type=positive_int, default=20, help="rendered scenes per category (default 20)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="base seed of the rendered frames (default 0)")
    p.add_argument("--out", type=Path, help="report file (default: a fresh ancsh_results/sensor-realism-<time>/"
                   "sensor_realism.md)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/sensor_realism.md (when --out is not "
                   "given)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ...data.procedural import CATEGORIES
    from ...data.real_frames import default_real_frame_folders
    from ...outputs import report_path
    from ...studies.sensor_realism import measure_sensor_realism, write_sensor_report

    unknown = [c for c in args.categories if c not in CATEGORIES]
    if unknown:
        raise ValueError(f"--categories: unknown {unknown}; known: {list(CATEGORIES)}")
    folders = list(args.folders) or default_real_frame_folders()
    if not folders:
        raise ValueError("DIR: no real-frame folders given and none in ../shared/data/real_frames")
    parts = ["bench", "sensor-realism", *[str(f) for f in args.folders],
             *changed_options(args, {"categories": ["box", "laptop"], "frames": 20, "seed": 0})]
    parts += output_flags(args.out, update_docs=args.update_docs)
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    path = report_path(args.out, update_docs=args.update_docs, docs_name="sensor_realism.md", command="sensor-realism")
    results = measure_sensor_realism(folders, categories=tuple(args.categories), frames=args.frames, seed=args.seed,
                                     progress=None if args.quiet else (lambda line: print(line, flush=True)))
    write_sensor_report(results, path, command=command)
    print(path.read_text())
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
