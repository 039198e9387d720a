"""``ancsh bench fit-profile``: the arguments of :mod:`ancsh.studies.fit_profile`."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from ...outputs import output_flags
from .._args import changed_options, non_negative_int, positive_int


def register(sub) -> None:
    """Add ``ancsh bench fit-profile`` to the ``bench`` sub-parsers."""
    p = sub.add_parser("fit-profile", help="where one exact fit spends its time, stage by stage, per category, beside "
                       "the official scheme (docs/results/fit_profile.md)")
    p.add_argument("--frames", type=positive_int, default=20, help="frames per category (default 20)")
    p.add_argument("--categories", default=None, help="comma-separated categories (default: all eight)")
    p.add_argument("--level", default="realistic", help="corruption preset (default realistic)")
    p.add_argument("--methods", default=None,
                   help="comma-separated formulation/backend pairs (default exact_reduced/lm,exact_reduced/ipopt)")
    p.add_argument("--repeats", type=positive_int, default=3, help="timed fits per frame and method, the median kept (default 3)")
    p.add_argument("--no-official", action="store_true", help="do not time the official scheme beside them")
    p.add_argument("--seed", type=non_negative_int, default=0, help="ancsh bench fit's seed (default 0)")
    p.add_argument("--out", type=Path, help="report file (default: a fresh ancsh_results/fit-profile-<time>/fit_profile.md)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/fit_profile.md (when --out is not given)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ...outputs import report_path
    from ...studies.fit_profile import DEFAULT_METHODS, ProfileConfig, profile_fits, write_profile_report
    from ...studies.report import Provenance

    split = lambda text: tuple(t.strip() for t in text.split(",") if t.strip())  # noqa: E731
    config = ProfileConfig(
        categories=split(args.categories) if args.categories else (), frames_per_category=args.frames,
        level=args.level, methods=split(args.methods) if args.methods else DEFAULT_METHODS, repeats=args.repeats,
        official=not args.no_official, seed=args.seed)
    parts = ["bench", "fit-profile", *changed_options(args, {"frames": 20, "categories": None, "level": "realistic",
                                                            "methods": None, "repeats": 3, "no_official": False,
                                                            "seed": 0})]
    parts += output_flags(args.out, update_docs=args.update_docs)
    provenance = Provenance("ancsh " + " ".join(shlex.quote(str(a)) for a in parts))
    path = report_path(args.out, update_docs=args.update_docs, docs_name="fit_profile.md", command="fit-profile")
    result = profile_fits(config, progress=lambda line: print(line, flush=True))
    summary = write_profile_report(result, path, provenance)
    for m, s in summary.items():
        ratio = "" if s["min_ratio"] is None else f", smallest official / total over categories {s['min_ratio']:.0f}x"
        print(f"{m}: {s['total_ms']:.2f} ms per fit{ratio}")
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
