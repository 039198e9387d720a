"""``ancsh category check`` and ``ancsh category build``: your own category from a spec file and URDFs."""

from __future__ import annotations

import sys
from pathlib import Path

from ._args import non_negative_int, positive_float, positive_int


def register(sub) -> None:
    p = sub.add_parser("category", help="your own category: check a spec file against URDFs, build a trained, "
                                        "calibrated, evaluated category folder (docs/category_spec.md)")
    cat_sub = p.add_subparsers(dest="category_command", metavar="SUBCOMMAND")
    p.set_defaults(func=lambda args: (p.print_help(), 0)[1])

    c = cat_sub.add_parser("check", help="read a spec file and import URDFs into it: the accept / reject table, no "
                                         "rendering or training",
                           description="Read a category spec (docs/category_spec.md) and, with --urdfs, import every "
                           "URDF into it. A wrong spec, or URDFs that cannot make the category (no object with the "
                           "spec's moving parts, no object in a split), is an error naming the file and the key.")
    c.add_argument("spec", type=Path, help="the category spec file (.toml) or a built category folder")
    c.add_argument("--urdfs", nargs="+", type=Path, default=(), metavar="PATH",
                   help="URDF files, object folders or folders of them")
    c.add_argument("--out", type=Path, help="write catalog.json and import_report.md here")
    c.set_defaults(func=run_check)

    b = cat_sub.add_parser(
        "build", help="spec file + URDFs -> a category folder: import, render, train, template, calibrate, evaluate",
        description="Build a category folder from a spec file and URDFs (ancsh.cli.category_build): import the "
        "URDFs (the train / test split by instance), render frames of them, train the network, build the template "
        "library, calibrate p_good and p_object, evaluate on the test objects and write report.md. Run the same "
        "command again to resume. Then: --category OUT with predict, track, evaluate.")
    b.add_argument("spec", type=Path, help="the category spec file (.toml)")
    b.add_argument("--urdfs", nargs="+", type=Path, required=True, metavar="PATH",
                   help="URDF files, object folders or folders of them")
    b.add_argument("--out", type=Path, required=True, help="the category folder to write")
    b.add_argument("--size", choices=("full", "notebook"), default="full",
                   help="full (default: 4000 training frames, up to 120 min of training, calibrated; a few "
                        "core-hours) or notebook (minutes; the pipeline end to end, not a useful network)")
    b.add_argument("--train-frames", type=positive_int, help="rendered training frames (default: the size's)")
    b.add_argument("--test-frames", type=positive_int, help="rendered test frames")
    b.add_argument("--time-limit-min", type=positive_float, help="training budget in minutes (the CPU budget)")
    b.add_argument("--max-steps", type=positive_int, help="training steps at most")
    b.add_argument("--calibrate-frames", type=non_negative_int, help="p_good calibration frames (0: none)")
    b.add_argument("--evaluate-frames", type=positive_int, help="evaluation frames")
    b.add_argument("--workers", type=positive_int, help="rendering processes (default 2)")
    b.add_argument("--seed", type=non_negative_int, help="base seed (default 0)")
    b.add_argument("--init", choices=("auto", "none"), help="auto (default): train from the shipped network nearest "
                   "in structure (all of it for the same joints, else its backbone); none: a random start")
    b.add_argument("--no-progress", action="store_true", help="no progress bars (default: shown on a terminal)")
    b.add_argument("--override", type=Path, help="JSON file of per-object import overrides (as data import)")
    b.set_defaults(func=run_build)


def run_check(args) -> int:
    from ..data.category_spec import load_spec

    conv = load_spec(args.spec)
    joints = ", ".join(f"{j.name} ({j.type.value}, {j.parent}->{j.child})" for j in conv.joints)
    print(f"{conv.spec_path}: category {conv.name!r}: parts {', '.join(conv.part_names)}; joints {joints}")
    if not args.urdfs:
        return 0
    from .category_build import check_category

    checked = check_category(args.spec, args.urdfs, args.out)
    catalog = checked["catalog"]
    print(f"| object | split | result |\n|---|---|---|")
    for o in catalog.objects:
        print(f"| {o.name} | {o.split} | imported |")
    for r in catalog.rejected:
        print(f"| {r.name} | - | rejected: {r.reason} |")
    print(f"{checked['imported']} imported ({checked['train']} train, {checked['test']} test), "
          f"{checked['rejected']} rejected"
          + (f"; wrote {args.out}/catalog.json, import_report.md" if args.out else ""))
    return 0


def run_build(args) -> int:
    import dataclasses

    from ..data.importer import load_overrides
    from .category_build import SIZES, build_category

    chosen = {key: getattr(args, key) for key in ("train_frames", "test_frames", "time_limit_min", "max_steps",
                                                   "calibrate_frames", "evaluate_frames", "workers", "seed", "init")
              if getattr(args, key) is not None}
    settings = dataclasses.replace(SIZES[args.size], **chosen)
    overrides = load_overrides(args.override) if args.override else None
    try:
        report = build_category(args.spec, args.urdfs, args.out, settings=settings, overrides=overrides,
                                progress=not args.no_progress and sys.stderr.isatty())
    except RuntimeError as exc:  # a step's command failed: it said why on stderr
        print(f"ancsh category build: error: {exc}; finished steps are kept in {args.out}: run the same command "
              "again to resume", file=sys.stderr)
        return 1
    print(f"{args.out}: the category is built; {report}")
    return 0
