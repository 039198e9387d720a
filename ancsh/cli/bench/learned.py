"""``ancsh bench learned-cost``, ``learned-ablation`` and ``roll-equivariance``: the arguments of
:mod:`ancsh.studies.learned_cost`, :mod:`ancsh.studies.ablation` and :mod:`ancsh.studies.equivariance`.

``python -m ancsh.cli.bench.learned timing|accuracy|pipeline`` runs the network-width measurements of
:mod:`ancsh.studies.learned_cost` (``docs/results/learned_width.md``; markdown rows on stdout, ``--json`` to a file).
"""

from __future__ import annotations

import argparse
import datetime
import json
from pathlib import Path

from ...studies.learned_cost.measure import SETTINGS, STEP_VARIANTS
from .._args import named_value, non_negative_int


def register(sub) -> None:
    """Add ``ancsh bench learned-cost``, ``learned-ablation`` and ``roll-equivariance`` to the ``bench`` sub-parsers."""
    r = sub.add_parser("roll-equivariance", help="how far each network's fitted rotation follows a camera roll "
                       "(1 = reads the shape; less = leans on the camera frame)")
    r.add_argument("--categories", nargs="+", help="shipped networks of these categories (default: every shipped one)")
    r.add_argument("--weights", nargs="*", default=(), metavar="LABEL=CATEGORY:PATH",
                   help="also these weights files or checkpoints (e.g. oven_aug=oven:runs/oven_aug/best.pt)")
    r.add_argument("--frames", type=int, default=30, help="test frames per network (default 30)")
    r.add_argument("--angle", type=float, default=10.0, help="roll in degrees (default 10)")
    r.add_argument("--seed", type=non_negative_int, default=0)
    r.add_argument("--out", type=Path, help="Markdown file; default: a fresh folder bench_out/roll_equivariance_<UTC time>/")
    r.set_defaults(func=run_roll)
    a = sub.add_parser("learned-ablation", help="held-out errors of training runs through the full pipeline (loss ablation)")
    a.add_argument("--runs", nargs="+", required=True, metavar="NAME=RUN_DIR", help="run directories of `ancsh train`")
    a.add_argument("--frames", type=int, default=300, help="rendered test frames per checkpoint (default 300)")
    a.add_argument("--seed", type=non_negative_int, default=0)
    a.add_argument("--baseline", metavar="WEIGHTS", help="also evaluate the weights the runs started from, as a row "
                   "'start': 'builtin' (the shipped network of the runs' category) or a weights file")
    a.add_argument("--train-commands", nargs="*", default=(), help="the commands that made the runs (for the report)")
    a.add_argument("--out", type=Path, help="Markdown file (e.g. docs/results/learned_ablation.md); default: a fresh "
                   "folder bench_out/learned_ablation_<UTC time>/")
    a.set_defaults(func=run_ablation)
    p = sub.add_parser("learned-cost", help="training frames per CPU-second: today's step vs the new one (one run)")
    p.add_argument("--variants", nargs="+", default=list(STEP_VARIANTS), choices=list(STEP_VARIANTS))
    p.add_argument("--repeats", type=int, default=6, help="steps per variant, the first a warm-up (default 6)")
    p.add_argument("--width", type=float, default=0.5)
    p.add_argument("--out", type=Path, help="Markdown file (e.g. docs/results/learned_cost.md); default: a fresh "
                   "folder bench_out/learned_cost_<UTC time>/")
    p.set_defaults(func=run_cost)


def run_cost(args) -> int:
    from ...studies.learned_cost import training_cost, write_cost_report

    result = training_cost(args.variants, width=args.width, repeats=args.repeats)
    out = args.out or Path("bench_out") / f"learned_cost_{_stamp()}" / "learned_cost.md"
    command = (f"ancsh bench learned-cost --repeats {args.repeats} --width {args.width} --variants {' '.join(args.variants)}"
               + (f" --out {args.out}" if args.out else ""))
    path = write_cost_report(result, out, command=command)
    print(path.read_text())
    print(f"wrote {path}")
    return 0


def run_ablation(args) -> int:
    from ...studies.ablation import ablation, write_ablation_report

    runs = {}
    for item in args.runs:
        name, run = named_value(item, "--runs", "NAME=RUN_DIR")
        runs[name] = run
    result = ablation(runs, frames=args.frames, seed=args.seed, baseline=args.baseline)
    out = args.out or Path("bench_out") / f"learned_ablation_{_stamp()}" / "learned_ablation.md"
    command = (f"ancsh bench learned-ablation --runs {' '.join(args.runs)} --frames {args.frames} --seed {args.seed}"
               + (f" --baseline {args.baseline}" if args.baseline else "") + (f" --out {args.out}" if args.out else ""))
    path = write_ablation_report(result, out, command=command, commands=args.train_commands)
    print(path.read_text())
    print(f"wrote {path}")
    return 0


def run_roll(args) -> int:
    from ...studies.equivariance import roll_equivariance, write_roll_report
    from ...learned.network.weights import shipped_categories

    networks = {c: (c, None) for c in (args.categories if args.categories is not None
                                      else ([] if args.weights else shipped_categories("ancsh")))}
    for item in args.weights:
        label, rest = named_value(item, "--weights", "LABEL=CATEGORY:PATH")
        category, sep, weights = rest.partition(":")
        if not (sep and category and weights):
            raise ValueError(f"--weights: expected LABEL=CATEGORY:PATH, got {item!r}")
        networks[label] = (category, weights)
    result = roll_equivariance(networks, frames=args.frames, angle_deg=args.angle, seed=args.seed)
    out = args.out or Path("bench_out") / f"roll_equivariance_{_stamp()}" / "roll_equivariance.md"
    command = " ".join(["ancsh bench roll-equivariance",
                        *(["--categories", *args.categories] if args.categories is not None else []),
                        *(["--weights", *args.weights] if args.weights else []),
                        f"--frames {args.frames} --angle {args.angle:g} --seed {args.seed}",
                        *([f"--out {args.out}"] if args.out else [])])
    path = write_roll_report(result, out, command=command)
    print(path.read_text())
    print(f"wrote {path}")
    return 0


def _stamp() -> str:
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%d-%H%M%S")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m ancsh.cli.bench.learned", description=__doc__.split("\n\n")[-1].strip())
    sub = p.add_subparsers(dest="what", required=True)
    t = sub.add_parser("timing")
    t.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    t.add_argument("--threads", type=int, default=1)
    t.add_argument("--json")
    a = sub.add_parser("accuracy")
    a.add_argument("--data", required=True)
    a.add_argument("--steps", type=int, default=300)
    a.add_argument("--frames", type=int)
    a.add_argument("--settings", nargs="+", default=["w0.125", "w0.25", "w0.5"], choices=list(SETTINGS))
    a.add_argument("--json")
    pl = sub.add_parser("pipeline")
    pl.add_argument("--data", required=True)
    pl.add_argument("--weights", default="laptop", help="category name or weights file")
    pl.add_argument("--frames", type=int, default=10)
    pl.add_argument("--direct", help="direct-voting weights (category name or file) to compare joints with")
    pl.add_argument("--json")
    args = p.parse_args(argv)
    from ...studies.learned_cost import accuracy, pipeline, timing

    if args.what == "timing":
        rows = timing(args.settings, threads=args.threads)
    elif args.what == "accuracy":
        rows = accuracy(args.settings, args.data, steps=args.steps, frames=args.frames)
    else:
        rows = pipeline(args.data, args.weights, frames=args.frames, direct=args.direct)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
