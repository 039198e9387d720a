"""``ancsh data generate``, ``ancsh data import``, ``ancsh data ranges`` and ``ancsh data show``."""

from __future__ import annotations

import sys


from ._args import category as category_arg
from ._args import non_negative_int as _non_negative_int
from ._args import positive_int as _positive_int


def register(sub) -> None:
    p = sub.add_parser("data", help="generate rendered depth datasets and draw frames")
    data_sub = p.add_subparsers(dest="data_command", metavar="SUBCOMMAND")
    p.set_defaults(func=lambda args: (p.print_help(), 0)[1])

    g = data_sub.add_parser(
        "generate",
        help="render frames with ANCSH ground truth into HDF5 shards (resumable)",
        description="Render depth frames of a procedural category (or one URDF object) with ANCSH ground truth "
        "into HDF5 shards. Re-running the same command resumes an interrupted run.",
    )
    src = g.add_mutually_exclusive_group(required=True)
    src.add_argument("--category", type=category_arg, help="a category (built in: eyeglasses, oven, washing_machine, laptop, drawer, microwave, "
                     "safe, box), a category spec file or a built category folder; one without a procedural generator "
                     "needs --real CATALOG --real-fraction 1")
    src.add_argument("--urdf", help="path of a URDF object (e.g. a PartNet-Mobility mobility.urdf)")
    g.add_argument("--split", default="train", choices=("train", "test"), help="instance split (default train)")
    g.add_argument("--real", default=None, metavar="CATALOG",
                   help="mix in the real objects of this split from a catalog ('builtin' = the shipped one)")
    g.add_argument("--real-fraction", type=float, default=None,
                   help="with --real: fraction of frames showing a real object (default 0.5; 1 = real only; a category "
                        "without a procedural generator: 1)")
    g.add_argument("--frames", type=_positive_int, required=True, help="number of frames")
    from ._args import add_executor_arguments

    add_executor_arguments(g, workers_default=2, workers_help="worker processes (default 2; 1 = in this process)")
    g.add_argument("--seed", type=_non_negative_int, default=0, help="base seed (default 0)")
    g.add_argument("--out", default=None, help="output directory (default data/<name>_<split>)")
    g.add_argument("--shard-size", type=_positive_int, default=500, help="frames per shard (default 500)")
    g.add_argument("--points", type=_positive_int, default=1024, help="points per frame (default 1024)")
    g.add_argument("--width", type=_positive_int, default=640, help="image width (default 640; Kinect-like intrinsics)")
    g.add_argument("--height", type=_positive_int, default=480, help="image height (default 480)")
    g.add_argument("--noise", dest="noise", action="store_true", default=True, help="Kinect-like sensor noise (default)")
    g.add_argument("--no-noise", dest="noise", action="store_false", help="exact depth")
    g.add_argument("--real-frames-noise", action="store_true",
                   help="the sensor noise with the whole-millimetre depth steps and the blob holes of the real frames "
                   "(DepthNoise.real_frames(); docs/results/sensor_realism.md)")
    g.add_argument("--min-part-pixels", type=_non_negative_int, default=30,
                   help="reject views where a part shows on fewer pixels (default 30)")
    g.add_argument("--min-part-fraction", type=float, default=0.02,
                   help="reject views where a part shows on less than this fraction of the object's pixels (default 0.02)")
    g.add_argument("--sequence-length", type=_positive_int, default=None, metavar="T",
                   help="generate sequences of T frames (smooth camera motion, joint open/close cycles; "
                        "--frames counts frames, T per sequence) instead of independent frames")
    g.add_argument("--fps", type=float, default=30.0, help="frames per second of the sequences (default 30)")
    g.add_argument("--overwrite", action="store_true", help="replace shards made with other settings")
    g.add_argument("--quiet", action="store_true", help="no progress bar")
    g.set_defaults(func=run_generate)

    im = data_sub.add_parser(
        "import",
        help="import real URDF objects into a category's convention (catalog, report, preview sheets)",
        description="Map URDF objects (PartNet-Mobility folders, or any URDF) onto a category's convention: "
        "moving parts, state 0 and direction from the geometry, NAOCS front, part order, metric scale, "
        "train/test split. Objects that the category cannot hold are rejected with the reason. "
        "Example: ancsh data import ../shared/data/partnet_mobility --out catalog_out",
    )
    im.add_argument("paths", nargs="+", help="URDF files, object folders, or folders of object folders")
    im.add_argument("--category", default=None, type=category_arg, help="import everything into this category (default: each object's own)")
    im.add_argument("--out", required=True, help="output folder: catalog.json, import_report.md, previews/")
    im.add_argument("--override", default=None, help="JSON file of per-object overrides (see ancsh.data.importer)")
    im.add_argument("--no-previews", dest="previews", action="store_false", help="skip the preview sheets")
    im.set_defaults(func=run_import)

    rg = data_sub.add_parser(
        "ranges",
        help="real objects' measured variation beside the procedural generators' (a Markdown table per category)",
        description="Measure every imported object of a catalog and the generator's training instances with the "
        "same function and write the ranges side by side. Example: ancsh data ranges --out ranges.md",
    )
    rg.add_argument("--catalog", default="builtin", help="catalog file or folder (default: the shipped one)")
    rg.add_argument("--instances", type=_positive_int, default=60, help="procedural instances per category (default 60)")
    rg.add_argument("--out", required=True, help="Markdown file to write")
    rg.set_defaults(func=run_ranges)

    s = data_sub.add_parser("show", help="draw one frame of a shard (points by part, NPCS, boxes, joint axes)")
    s.add_argument("file", help="a shard (.h5) or a directory of shards")
    s.add_argument("--frame", type=_non_negative_int, default=0, help="frame index (default 0)")
    s.add_argument("--out", default="view.png", help="image path (default view.png)")
    s.set_defaults(func=run_show)


def _noise_model(args):
    """The frames' :class:`~ancsh.data.noise.DepthNoise` from ``--noise`` / ``--no-noise`` / ``--real-frames-noise``."""
    from ..data.noise import DepthNoise

    if args.real_frames_noise and not args.noise:
        raise ValueError("--real-frames-noise: not with --no-noise")
    if not args.noise:
        return DepthNoise.off()
    return DepthNoise.real_frames() if args.real_frames_noise else DepthNoise()


def _check_real_objects(real: str, category: str, split: str) -> None:
    """Refuse ``--real`` when its catalog holds no object of ``category`` in ``split`` (it would add nothing)."""
    from ..data.catalog import load_catalog

    catalog = load_catalog(None if real == "builtin" else real)
    if catalog.instances(category, split):
        return
    others = sorted({o.split for o in catalog.instances(category)})
    where = f"its {category} objects are all in the {' and '.join(others)} split" if others else f"it has no {category} object"
    raise ValueError(f"--real: the catalog {real!r} has no {category} object in the {split} split ({where}); "
                     "leave --real out for procedural frames only")


def _real_fraction(args) -> float:
    """``--real-fraction``, by default 0.5 with ``--real`` for a procedural category (0 without ``--real``; a category
    without a generator: left to the configuration, which shows its objects in every frame)."""
    from ..data.procedural import CATEGORIES

    if args.real_fraction is not None:
        if not args.real:
            raise ValueError("--real-fraction: needs --real CATALOG")
        return args.real_fraction
    return 0.5 if args.real and args.category in CATEGORIES else 0.0


def run_generate(args) -> int:
    from pathlib import Path

    from ..executors import WorkerLost
    from ._args import executor_from_args
    from ..data.generate import FrameRejected, GenerationConfig, generate_dataset
    from ..data.render import Intrinsics
    from ..data.sequences import SequenceMotion

    if args.real and args.category:
        _check_real_objects(args.real, args.category, args.split)
    executor = executor_from_args(args)
    config = GenerationConfig(
        category=args.category,
        split=args.split,
        urdf=args.urdf,
        real=args.real,
        real_fraction=_real_fraction(args),
        seed=args.seed,
        shard_size=args.shard_size,
        num_points=args.points,
        intrinsics=Intrinsics.kinect(args.width, args.height),
        noise=_noise_model(args),
        min_part_pixels=args.min_part_pixels,
        min_part_fraction=args.min_part_fraction,
        sequence=None if args.sequence_length is None else SequenceMotion(length=args.sequence_length, fps=args.fps),
    )
    split = config.split if config.urdf is None else "urdf"
    out = Path(args.out) if args.out else Path("data") / f"{config.name}_{split}"
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out: {out} is a file, not a folder: the dataset's shards go into a folder; give a "
                         "folder's path")
    try:
        report = generate_dataset(
            config, args.frames, out, executor=executor, progress=not args.quiet, overwrite=args.overwrite
        )
    except FrameRejected as exc:
        print(f"ancsh data generate: error: {exc}; complete shards are kept in {out}", file=sys.stderr)
        return 1
    except WorkerLost as exc:
        print(f"ancsh data generate: error: {exc}; complete shards are kept in {out}; run the same command again "
              "to resume", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"\ninterrupted: complete shards are kept in {out}; run the same command again to resume",
              file=sys.stderr)
        return 130
    except ConnectionError:  # a Ray cluster that does not answer: nothing was written
        raise
    except OSError as exc:  # no space left, read-only folder: complete shards stay valid
        where = exc.filename or out
        print(f"ancsh data generate: error: cannot write {where}: {exc.strerror or exc}; complete shards are kept in "
              f"{out}; free space (or choose another --out) and run the same command again to resume", file=sys.stderr)
        return 2
    for s, reason in report.replaced:
        print(f"regenerated shard {report.paths[s].name}: {reason}")
    rate = f" ({report.frames_per_second:.1f} frames/s)" if report.frames_generated else ""
    print(
        f"{out}: {len(report.paths)} shards, {report.frames_generated} frames generated in "
        f"{report.seconds:.1f} s{rate}; {len(report.skipped)} complete shards kept"
    )
    return 0


def run_import(args) -> int:
    import shlex
    from pathlib import Path

    from ..data.catalog import build_catalog, draw_preview_sheet, write_catalog
    from ..studies.catalog_reports import write_import_report
    from ..data.importer import load_overrides

    overrides = load_overrides(args.override) if args.override else None
    out = Path(args.out)
    words = list(args.paths) + (["--category", args.category] if args.category else []) + ["--out", args.out]
    words += ["--override", args.override] if args.override else []
    command = "ancsh data import " + " ".join(shlex.quote(str(w)) for w in words)
    catalog = build_catalog(args.paths, args.category, overrides=overrides, command=command,
                            progress=lambda name: print(f"importing {name}", file=sys.stderr))
    write_catalog(catalog, out / "catalog.json")
    write_import_report(catalog, out / "import_report.md")
    if args.previews:
        for cat in catalog.categories:
            draw_preview_sheet(catalog.instances(cat), out / "previews" / f"{cat}.png", title=f"{cat}: rest state and a moved state")
    print(f"{out}: {len(catalog.objects)} objects imported, {len(catalog.rejected)} rejected "
          f"(reasons in {out / 'import_report.md'})")
    return 0 if catalog.objects else 1  # every object rejected: the catalog holds nothing to use


def run_ranges(args) -> int:
    from pathlib import Path

    from ..data.catalog import load_catalog
    from ..studies.catalog_reports import ranges_report
    from ..outputs import write_bytes_atomically

    catalog = load_catalog(None if args.catalog == "builtin" else args.catalog)
    command = f"ancsh data ranges --catalog {args.catalog} --instances {args.instances} --out {args.out}"
    text = ranges_report(catalog, procedural_instances=args.instances, command=command)
    write_bytes_atomically(Path(args.out), text.encode())
    print(f"wrote {args.out}")
    return 0


def run_show(args) -> int:
    from ..data.dataset import FrameDataset
    from ..data.show import save_frame_figure

    ds = FrameDataset(args.file)
    if args.frame >= len(ds):
        raise ValueError(f"--frame: {args.frame} out of range; {args.file} holds {len(ds)} frames")
    out = save_frame_figure(ds[args.frame], args.out)
    print(f"wrote {out}")
    return 0
