"""``ancsh bench scaling``: the arguments of :mod:`ancsh.studies.scaling`."""

from __future__ import annotations

import sys


def register_bench(bench_sub) -> None:
    """``ancsh bench scaling``."""
    from ...studies.scaling import DEFAULTS

    b = bench_sub.add_parser(
        "scaling",
        help="frames/s of generation and evaluation on 1 and 2 workers, local processes vs Ray, and the CPU cost "
             "per frame (cores for N frames in T hours)",
    )
    b.add_argument("--gen-frames", type=int, default=DEFAULTS["gen_frames"], help="generated frames per run (default 64)")
    b.add_argument("--chunk", type=int, default=DEFAULTS["chunk"], help="frames per generation task (default 8)")
    b.add_argument("--eval-frames", type=int, default=DEFAULTS["eval_frames"], help="evaluated frames per run (default 8)")
    b.add_argument("--rounds", type=int, default=DEFAULTS["rounds"], help="runs of each configuration, interleaved (default 2)")
    b.add_argument("--workers", default=DEFAULTS["workers"], help="worker counts (default 1,2)")
    b.add_argument("--executors", default=DEFAULTS["executors"], help="executors (default local,ray; Ray needs ancsh[ray])")
    b.add_argument("--out", default=None, help="also write the Markdown report here (e.g. docs/results/scaling.md)")
    b.set_defaults(func=run_bench)


def run_bench(args) -> int:
    from pathlib import Path

    from ...executors import EXECUTORS
    from ...studies.report import write_text
    from ...studies.scaling import DEFAULTS, measure_scaling, scaling_report

    for name in ("gen_frames", "chunk", "eval_frames", "rounds"):
        if getattr(args, name) < 1:
            raise ValueError(f"--{name.replace('_', '-')}: expected a positive integer, got {getattr(args, name)}")
    if args.gen_frames <= args.chunk or args.eval_frames < 2:
        raise ValueError("--gen-frames, --chunk, --eval-frames: each job needs at least two tasks (a rate after the "
                         "first result)")
    try:
        workers = tuple(int(w) for w in args.workers.split(","))
    except ValueError:
        raise ValueError(f"--workers: expected comma-separated positive integers, got {args.workers!r}") from None
    if not workers or min(workers) < 1:
        raise ValueError(f"--workers: expected comma-separated positive integers, got {args.workers!r}")
    executors = tuple(e.strip() for e in args.executors.split(","))
    if any(e not in EXECUTORS for e in executors) or "local" not in executors:
        raise ValueError(f"--executors: expected 'local' and optionally 'ray', got {args.executors!r}")
    if "ray" in executors:
        from ...executors import RAY_MISSING, ray_available

        if not ray_available():
            raise ValueError(f"--executors ray: {RAY_MISSING}")
    result = measure_scaling(gen_frames=args.gen_frames, chunk=args.chunk, eval_frames=args.eval_frames,
                             rounds=args.rounds, workers=tuple(sorted(set(workers) | {1})), executors=executors,
                             progress=lambda line: print(line, file=sys.stderr, flush=True))
    command = "ancsh bench scaling" + "".join(
        f" --{name.replace('_', '-')} {getattr(args, name)}" for name in ("gen_frames", "chunk", "eval_frames", "rounds",
                                                                           "workers", "executors", "out")
        if getattr(args, name) != DEFAULTS[name])
    text = scaling_report(result, command=command)
    print(text)
    if args.out:
        out = write_text(Path(args.out), text)
        print(f"wrote {out}")
    return 0
