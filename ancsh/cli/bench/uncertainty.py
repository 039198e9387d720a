"""``ancsh bench uncertainty``: the arguments of :mod:`ancsh.studies.uncertainty_calibration`."""

from __future__ import annotations

import time

from ...outputs import output_flags
from ...studies.uncertainty_calibration.measure import CALIBRATION_FRAMES_PER_TEST_FRAME, DEFAULT_PROVIDERS, PROVIDERS
from .._args import changed_options, non_negative_int


def register(sub) -> None:
    """Add ``uncertainty`` to the ``ancsh bench`` sub-commands."""
    p = sub.add_parser("uncertainty", help="coverage of the fits' standard deviations; measured inflation factors")
    p.add_argument("--frames", type=int, default=150, help="test frames per category (default 150)")
    p.add_argument("--calibration-frames", type=int, default=None,
                   help=f"calibration frames per category (default {CALIBRATION_FRAMES_PER_TEST_FRAME} x --frames)")
    p.add_argument("--categories", default=None, help="comma-separated (default: every category with shipped weights)")
    p.add_argument("--providers", default=None, help=f"comma-separated from {','.join(PROVIDERS)} (default: {','.join(DEFAULT_PROVIDERS)})")
    p.add_argument("--seed", type=non_negative_int, default=0, help="test frame seed (default 0, as ancsh evaluate)")
    p.add_argument("--calibration-seed", type=non_negative_int, default=1001)
    p.add_argument("--out", default=None, help="markdown path (default: a fresh ancsh_results/bench-uncertainty-<time>/)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/uncertainty_calibration.md")
    p.add_argument("--install", action="store_true", help="write the maps to ancsh/weights/uncertainty_inflation.json")
    p.add_argument("--save-records", default=None, metavar="NPZ",
                   help="also write every frame's errors and raw covariances (to compare inflation maps offline)")
    p.add_argument("--records", default=None, metavar="NPZ", nargs="+",
                   help="reuse the errors of --save-records instead of fitting the frames (the same --frames, "
                        "--calibration-frames and seeds); several files combine their categories, a category in "
                        "several taken from the last")
    p.set_defaults(func=run)


def _command(args) -> str:
    """The command line that reproduces ``args``."""
    parts = ["ancsh bench uncertainty", f"--frames {args.frames}",
             *changed_options(args, {"calibration_frames": None, "categories": None, "providers": None, "seed": 0,
                                     "calibration_seed": 1001})]
    parts += output_flags(args.out, update_docs=args.update_docs)
    parts += changed_options(args, {"install": False, "save_records": None, "records": None})
    return " ".join(parts)


def run(args) -> int:
    from ...outputs import report_path
    from ...studies.uncertainty_calibration import (CalibrationConfig, install, load_records, measure, merge_records,
                                                    save_records, summarize, write_report)

    kw = {"frames": args.frames, "calibration_frames": getattr(args, "calibration_frames", None), "seed": args.seed,
          "calibration_seed": args.calibration_seed}
    if args.categories:
        kw["categories"] = tuple(c.strip() for c in args.categories.split(",") if c.strip())
    if args.providers:
        kw["providers"] = tuple(c.strip() for c in args.providers.split(",") if c.strip())
    config = CalibrationConfig(**kw)
    command = _command(args)
    t0 = time.perf_counter()
    if getattr(args, "records", None):
        parts = []
        for path in args.records:
            m = load_records(path)
            held = sorted({(c[s]["frames"] + c[s].get("not_refined", 0), s)  # learned-template: refined + not
                           for per in m["counts"].values() for c in per.values() for s in c})
            want = sorted({(config.n_calibration, "calibration"), (config.frames, "test")})
            if held != want:
                raise ValueError(f"--records: {path} holds {held} frames per split, not {want} "
                                 "(pass the --frames / --calibration-frames it was measured with)")
            parts.append(m)
        taken = set()  # each file's source names the categories taken from it (the last file holding them)
        for m in reversed(parts):
            if isinstance(m.get("source"), dict):
                m["source"] = dict(m["source"], categories=sorted(set(m["records"]) - taken))
            taken |= set(m["records"])
        measured = merge_records(parts)
        if len(parts) == 1 and isinstance(measured.get("source"), dict):
            measured["source"].pop("categories", None)
        if sorted(measured["records"]) != sorted(config.categories):
            raise ValueError(f"--records: {' '.join(map(str, args.records))} hold categories "
                             f"{sorted(measured['records'])}, not {sorted(config.categories)}")
    else:
        measured = measure(config, progress=lambda s: print(s, flush=True))
        measured["source"] = {"command": command, "elapsed_s": time.perf_counter() - t0}
    if getattr(args, "save_records", None):
        print(f"wrote {save_records(measured, args.save_records)}")
    summary = summarize(measured)
    out_md = report_path(args.out, update_docs=args.update_docs, docs_name="uncertainty_calibration.md",
                         command="bench-uncertainty")
    head = write_report(measured, summary, config, out_md, command=command, elapsed_s=time.perf_counter() - t0)
    print(f"wrote {out_md}; rotation/translation/state rows within 10 points after inflation: "
          f"{head['rows_within_main']} of {head['rows_main']} (all quantities {head['rows_within_all']} of {head['rows_all']})")
    if args.install:
        print(f"installed the maps in {install(summary, config, command)}")
    return 0
