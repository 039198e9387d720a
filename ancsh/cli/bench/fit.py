"""``ancsh bench fit``: the arguments of :mod:`ancsh.studies.fit`."""

from __future__ import annotations

import time

from ...outputs import output_flags
from .._args import changed_options, fit_config_fields, non_negative_int


def register(sub) -> None:
    """Add ``fit`` to the ``ancsh bench`` sub-commands."""
    from ...studies.fit.measure import VERDICT_FRAMES

    p = sub.add_parser("fit", help="compare every fitting formulation and the official ANCSH scheme")
    p.add_argument("--quick", action="store_true", help="few frames, two corruption levels (~1-2 min); not the verdict "
                   "(the default fit against the official scheme per part), which needs the full run")
    p.add_argument("--json", action="store_true", help="also write the records as JSON next to the markdown")
    p.add_argument("--out", default=None, help="markdown report path (default: a fresh ancsh_results/bench-fit-<time>/)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/fit_benchmark.md (when --out is not given)")
    p.add_argument("--frames", type=int, default=None, help=f"frames per category (default {VERDICT_FRAMES}, what the "
                   "verdict needs at least; quick 2)")
    p.add_argument("--categories", default=None, help="comma-separated categories (default: the paper's five)")
    p.add_argument("--levels", default=None, help="comma-separated corruption presets")
    p.add_argument("--methods", default=None, help="comma-separated method names (default: all)")
    p.add_argument("--official-hypotheses", type=int, default=None,
                   help="RANSAC hypotheses of the official baseline (default: the official 200)")
    p.add_argument("--seed", type=non_negative_int, default=0)
    p.add_argument("--exact-config", default=None, metavar="JSON",
                   help="FitConfig fields for the exact formulations only, as a JSON object (e.g. "
                   "'{\"npcs_bias_weight\": 0.01, \"npcs_scale_bias\": true}'); the other methods keep the defaults")
    p.set_defaults(func=run)


def _command(args) -> str:
    """The command line that reproduces ``args``."""
    import shlex

    parts = changed_options(args, {"quick": False, "json": False, "frames": None, "categories": None, "levels": None,
                                   "methods": None, "official_hypotheses": None, "seed": 0, "exact_config": None})
    parts += output_flags(args.out, update_docs=args.update_docs)
    return " ".join(["ancsh bench fit", *(shlex.quote(str(t)) for t in parts)])


def run(args) -> int:
    from dataclasses import replace

    from ...studies.fit import FULL, QUICK, run_benchmark, write_report

    config = QUICK if args.quick else FULL
    changes = {"seed": args.seed}
    if args.frames is not None:
        changes["frames_per_category"] = args.frames
    if args.categories:
        changes["categories"] = tuple(c.strip() for c in args.categories.split(",") if c.strip())
    if args.levels:
        changes["levels"] = tuple(c.strip() for c in args.levels.split(",") if c.strip())
    if args.official_hypotheses is not None:
        changes["official_hypotheses"] = args.official_hypotheses
    if args.methods:
        changes["methods"] = tuple(c.strip() for c in args.methods.split(",") if c.strip())
    if args.exact_config is not None:
        changes["exact_config"] = tuple(fit_config_fields(args.exact_config, "--exact-config").items())
    config = replace(config, **changes)
    command = _command(args)
    t0 = time.perf_counter()
    report = run_benchmark(config, progress=lambda s: print(s, flush=True))
    from ...outputs import report_path

    out_md = report_path(args.out, update_docs=args.update_docs, docs_name="fit_benchmark.md", command="bench-fit")
    out_json = out_md.with_suffix(".json") if args.json else None
    head = write_report(report, out_md, out_json, command=command, quick=args.quick)
    print(f"\nwrote {out_md}" + (f" and {out_json}" if out_json else "") + f" in {time.perf_counter() - t0:.0f} s")
    from ...studies.fit.report import verdict_line

    print(verdict_line(head["verdict"]))
    for key in ("speedup", "thin_part_reduction", "exact_vs_gt_refit"):
        if key in head:
            print(f"{key}: {head[key]:.3g}")
    return 0
