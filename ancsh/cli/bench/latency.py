"""``ancsh bench latency``: the arguments of :mod:`ancsh.studies.latency`."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from ...outputs import output_flags
from .._args import changed_options, non_negative_int, positive_int


def register(sub) -> None:
    """Add ``ancsh bench latency`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("latency", help="a prediction warm and cold, per stage, through ancsh serve and on 1 and 2 "
                       "workers, side by side (docs/results/latency.md)")
    p.add_argument("--stress-frames", type=non_negative_int, default=4, help="stress scenes beside the shared real "
                   "frames (default 4)")
    p.add_argument("--repeats", type=positive_int, default=3, help="timed warm predictions per frame (default 3)")
    p.add_argument("--serve-requests", type=positive_int, default=8, help="timed requests to the service (default 8)")
    p.add_argument("--no-cold", action="store_true", help="skip the fresh-process measurements")
    p.add_argument("--no-workers", action="store_true", help="skip the folder at 1 and 2 workers")
    p.add_argument("--out", type=Path, help="report file (default: a fresh ancsh_results/latency-<time>/latency.md)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/latency.md (when --out is not given)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import torch

    from ...data.real_frames import default_real_frame_folders, load_real_frame
    from ...outputs import report_path
    from ...studies.latency import (first_call, latency_frames, measure_cold, measure_serve, measure_stages,
                                    measure_warm, measure_workers, write_latency_report)
    from ...studies.report import Provenance

    torch.set_num_threads(1)  # one core, as the targets are stated
    parts = ["bench", "latency", *changed_options(args, {"stress_frames": 4, "repeats": 3, "serve_requests": 8,
                                                        "no_cold": False, "no_workers": False})]
    parts += output_flags(args.out, update_docs=args.update_docs)
    command = "ancsh " + " ".join(shlex.quote(a) for a in parts)
    path = report_path(args.out, update_docs=args.update_docs, docs_name="latency.md", command="latency")
    provenance = Provenance(command)
    frames = latency_frames(args.stress_frames)
    if not frames:
        raise ValueError("--stress-frames: no shared real frames here and no stress scenes asked for: nothing to time")
    say = lambda line: print(line, flush=True)  # noqa: E731
    results = {"first_call": first_call(frames[0])}
    results["warm"] = measure_warm(frames, repeats=args.repeats, progress=say)
    results["stages"] = measure_stages(frames, progress=say)
    results["serve"] = measure_serve(frames[0], requests=args.serve_requests)
    say(f"serve: {results['serve']['rps']:.2f} requests/s")
    if not args.no_workers:
        results["workers"] = measure_workers(frames, copies=24)
        say("workers: " + ", ".join(f"{r['workers']}: {r['fps']:.2f} frames/s" for r in results["workers"]))
    if not args.no_cold:
        real = [f for f in default_real_frame_folders() if load_real_frame(f).objects]
        if real:
            results["cold"] = measure_cold(real[0], load_real_frame(real[0]).objects[0].category)
            say(f"cold: {results['cold']['predict_s']:.2f} s")
    write_latency_report(results, path, provenance)
    print(path.read_text())
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
