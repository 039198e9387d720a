"""``ancsh bench render``: the arguments of :mod:`ancsh.studies.render`."""

from __future__ import annotations

import sys

from .._args import non_negative_int, positive_int


def register_bench(bench_sub) -> None:
    b = bench_sub.add_parser(
        "render",
        help="frames/s of raw ray casting and of full frames (render + noise + points + ground truth)",
    )
    b.add_argument("--frames", type=positive_int, default=100, help="frames per category and mode (default 100)")
    b.add_argument("--categories", default=None, help="comma-separated categories (default: the paper's five)")
    b.add_argument("--threads", type=positive_int, default=1, help="open3d ray-casting threads (default 1)")
    b.add_argument("--width", type=positive_int, default=640)
    b.add_argument("--height", type=positive_int, default=480)
    b.add_argument("--seed", type=non_negative_int, default=0)
    b.add_argument("--out", default=None, help="also write the table, with this command, to a Markdown file")
    b.set_defaults(func=run_bench)


def run_bench(args) -> int:
    from ...data.procedural import CATEGORIES, PAPER_CATEGORIES
    from ...data.render import Intrinsics
    from ...studies.render import measure_render, write_render_report
    from ...studies.report import Provenance

    cats = PAPER_CATEGORIES if args.categories is None else tuple(c.strip() for c in args.categories.split(","))
    unknown = [c for c in cats if c not in CATEGORIES]
    if unknown:
        raise ValueError(f"--categories: unknown {unknown}; known: {', '.join(CATEGORIES)}")
    intr = Intrinsics.kinect(args.width, args.height)
    command = "ancsh " + " ".join(sys.argv[1:]) if sys.argv and sys.argv[0].endswith("ancsh") else "ancsh bench render"
    provenance = Provenance(command)
    lines, full_fps = measure_render(cats, intr, frames=args.frames, threads=args.threads, seed=args.seed,
                                     emit=lambda line: print(line, flush=True))
    if args.out:
        out = write_render_report(args.out, lines, full_fps, intr.width, intr.height, provenance=provenance)
        print(f"wrote {out}")
    return 0
