"""``ancsh bench cad-auto``: the arguments of :mod:`ancsh.studies.cad.auto_start`."""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

from ...outputs import output_flags
from .._args import changed_options, non_negative_int

_DEFAULTS = {"per_category": 3, "seeds": [0, 1, 2], "points": 3000, "noise": False, "scene_seed": 0, "data": None,
             "before": None}


def register(sub) -> None:
    """Add ``ancsh bench cad-auto`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("cad-auto", help="fit-cad with its automatic start on renders of the shared real objects at "
                       "several seeds: right / wrong but success / refused, seed agreement")
    p.add_argument("--per-category", type=int, default=3, help="objects per category, the first in name order "
                   "(default 3)")
    p.add_argument("--seeds", type=non_negative_int, nargs="+", default=[0, 1, 2], help="fit-cad --seed values "
                   "(default 0 1 2)")
    p.add_argument("--points", type=int, default=3000, help="fit-cad --points (default 3000)")
    p.add_argument("--noise", action="store_true", help="Kinect-like depth noise on the renders")
    p.add_argument("--scene-seed", type=non_negative_int, default=0, help="seed of the articulations and views "
                   "(default 0)")
    p.add_argument("--data", type=Path, help="folder of <category>_<id>/mobility.urdf objects (default: the shared "
                   "data's partnet_mobility)")
    p.add_argument("--before", type=Path, help="the JSON of an earlier run, shown beside this one")
    p.add_argument("--out", type=Path, help="report file (default: a fresh ancsh_results/cad-auto-<time>/"
                   "cad_auto_start.md)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/cad_auto_start.md (when --out is "
                   "not given)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import json

    from ...outputs import report_path
    from ...studies.cad.auto_start import AutoStartConfig, measure_auto_start, write_auto_start_report
    from ...studies.report import Provenance

    config = AutoStartConfig(per_category=args.per_category, seeds=tuple(args.seeds), points=args.points,
                             noise=args.noise, scene_seed=args.scene_seed,
                             data=None if args.data is None else str(args.data))
    before = None
    if args.before is not None:
        if not args.before.is_file():
            raise FileNotFoundError(f"--before: no such file {str(args.before)!r}")
        before = json.loads(args.before.read_text())
        if not isinstance(before, dict) or "records" not in before or "agreement" not in before:
            raise ValueError(f"--before: {args.before} is not the JSON of an ancsh bench cad-auto run")
    parts = ["bench", "cad-auto", *changed_options(args, _DEFAULTS)]
    parts += output_flags(args.out, update_docs=args.update_docs)
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    path = report_path(args.out, update_docs=args.update_docs, docs_name="cad_auto_start.md", command="cad-auto")
    t0 = time.perf_counter()

    def progress(name, recs, agree):
        print(f"  {name:28s} {' '.join(r.outcome for r in recs):50s} seeds {'agree' if agree else 'DISAGREE'} "
              f"[{time.perf_counter() - t0:6.0f} s]", file=sys.stderr, flush=True)

    results = measure_auto_start(config, progress=progress)
    write_auto_start_report(results, path, Provenance(command), before=before, wall_s=time.perf_counter() - t0)
    print(path.read_text())
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
