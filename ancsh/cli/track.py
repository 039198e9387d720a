"""``ancsh track``: track an articulated object through a folder of depth frames."""

from __future__ import annotations

import sys

from ._args import category as category_arg
from ._args import non_negative_int, positive_int

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser("track", help="track an articulated object through a folder of depth frames (one JSON line a frame)")
    p.add_argument("--depth", required=True, help="folder of depth frames (16-bit PNG millimetres / .npy metres), "
                                                  "in natural name order")
    p.add_argument("--intrinsics", required=True, help="intrinsics JSON of every frame ({fx, fy, cx, cy, width, height})")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--category", type=category_arg, help="category level: the shipped network of this category")
    src.add_argument("--urdf", help="instance level: a known URDF model (warm-started articulated ICP)")
    p.add_argument("--out", default=None, help="JSON-lines output, one line a frame, written as it goes "
                                               "(default: a fresh ancsh_results/track-<time>/track.jsonl); never overwritten")
    p.add_argument("-k", "--network-every", type=int, default=3, help="run the network on every k-th frame (default 3)")
    p.add_argument("--no-template", dest="template", action="store_false",
                   help="never carry the category template (default: the categories of TrackerConfig.template_categories, "
                        "the laptop, are refined against it at every (re-)initialisation, seconds, and tracked on it)")
    p.add_argument("--weights", default=None, help="a weights file instead of the shipped one (--category)")
    p.add_argument("--refine-network", action="store_true",
                   help="network frames through the category's refinement network, the points rotated into the "
                        "predicted orientation (TrackerConfig.refine_network; the shipped <category>_refine.pt or "
                        "--refiner)")
    p.add_argument("--refiner", default=None, help="with --refine-network: a refinement network's weights file")
    p.add_argument("--single", action="store_true",
                   help="--category: follow one object (the first one isolated in each frame; schema ancsh.track/1) "
                        "instead of every object of the category (the default with isolation: one track per object, "
                        "schema ancsh.track/2)")
    p.add_argument("--max-objects", type=positive_int, default=None, help="at most this many tracks (default: every "
                   "verified object)")
    p.add_argument("--detect-every", type=positive_int, default=None,
                   help="frames between detections (predict's object list) while every track is measured "
                        "(default: MultiTrackerConfig.detect_every)")
    p.add_argument("--png-dir", default=None, help="every object: a picture of each frame (the depth with every "
                   "track's boxes, id and opening) and states.png (each track's joint states over time) in this folder")
    p.add_argument("--mask-dir", default=None, help="object masks named like the frames (skip isolation; one object)")
    p.add_argument("--no-isolate", dest="isolate", action="store_false", help="use every valid pixel (no isolation)")
    p.add_argument("--max-depth", type=float, default=None, help="ignore pixels deeper than this (metres)")
    p.add_argument("--points", type=positive_int, default=1024, help="points sampled per frame (default 1024)")
    p.add_argument("--seed", type=non_negative_int, default=0)
    p.add_argument("--quiet", action="store_true", help="no per-frame line on the terminal")
    p.set_defaults(func=run)


def run(args) -> int:
    from pathlib import Path

    from ..data.images import read_intrinsics
    from ..outputs import fresh_output_dir
    from ..tracking.stream import JsonLinesWriter, depth_files, track_files

    files = depth_files(args.depth)
    intrinsics = read_intrinsics(args.intrinsics)
    _check_first_frame(files, intrinsics)
    category = args.category
    if args.urdf is not None:
        from ..data.urdf import load_urdf
        from ..tracking.instance import InstanceTracker

        model = load_urdf(args.urdf)
        tracker = InstanceTracker(model, rng=args.seed)
        category = model.category
        num_joints = model.num_joints
        if args.isolate and args.mask_dir is None and category is None:
            raise ValueError(f"urdf: {args.urdf} names no category to isolate the object by; give --mask-dir or --no-isolate")
    else:
        from ..learned.inference.provider import LearnedProvider
        from ..learned.network.weights import weights_path
        from ..tracking.tracker import CategoryTracker, TrackerConfig

        if args.weights is None and not weights_path(category).is_file():
            from ..learned.network.weights import missing_weights_error

            raise missing_weights_error(category)
        if args.refiner is not None and not args.refine_network:
            raise ValueError("--refiner: a refinement network is used with --refine-network only")
        refine = {"refine": "network", "refiner": args.refiner} if args.refine_network else {}
        provider = LearnedProvider(category if args.weights is None else args.weights, seed=args.seed, **refine)
        settings = {} if args.template else {"template_categories": ()}
        if args.refine_network:
            settings["refine_network"] = True
        multi = not args.single and args.mask_dir is None and args.isolate
        if not multi and (args.max_objects is not None or args.detect_every is not None or args.png_dir is not None):
            raise ValueError("--max-objects / --detect-every / --png-dir: for every object of the category (without "
                             "--single, --mask-dir or --no-isolate)")
        if multi:
            return _run_multi(args, files, intrinsics, provider, settings)
        tracker = CategoryTracker(provider, TrackerConfig(network_every=args.network_every, **settings), category=category,
                                  rng=args.seed)
        num_joints = provider.num_joints
    out = Path(args.out) if args.out else fresh_output_dir("track") / "track.jsonl"

    def show(rec):
        if not args.quiet:
            states = ", ".join("-" if v is None else f"{v:.3f}" for v in rec["joint_states"])
            print(f"{rec['frame']:5d} {rec['file']}: {rec['status']:13s} [{states}] {rec['time_ms']:.0f} ms"
                  + (f"  ({rec['message']})" if rec["status"] in ("lost", "reinitialised") else ""), flush=True)

    with JsonLinesWriter(out) as writer:
        records = track_files(files, intrinsics, tracker, writer, category=category, mask_dir=args.mask_dir,
                              isolate=args.isolate, max_depth=args.max_depth, num_points=args.points, seed=args.seed,
                              num_joints=num_joints, progress=show)
    counts = {s: sum(r["status"] == s for r in records) for s in ("initialised", "tracked", "reinitialised", "lost")}
    print(f"wrote {out}: {len(records)} frames, " + ", ".join(f"{v} {k}" for k, v in counts.items()), file=sys.stderr)
    return 0 if counts["lost"] == 0 else 1


def _run_multi(args, files, intrinsics, provider, settings: dict) -> int:
    """Every object of the category (:class:`~ancsh.tracking.multi.MultiObjectTracker`), one ``ancsh.track/2`` line a
    frame; exit 1 when no object was tracked on any frame."""
    from pathlib import Path

    from ..outputs import fresh_output_dir
    from ..tracking.multi import MultiObjectTracker, MultiTrackerConfig
    from ..tracking.stream import JsonLinesWriter, track_files_multi
    from ..tracking.tracker import TrackerConfig

    if args.points < 16:
        raise ValueError(f"--points: at least 16 points a track, got {args.points}")
    options = {"tracker": TrackerConfig(network_every=args.network_every, **{"template_categories": (), **settings}),
               "num_points": args.points, "max_objects": args.max_objects}
    if args.detect_every is not None:
        options["detect_every"] = args.detect_every
    tracker = MultiObjectTracker(provider, intrinsics, args.category, MultiTrackerConfig(**options), seed=args.seed)
    out = Path(args.out) if args.out else fresh_output_dir("track") / "track.jsonl"

    def show(rec):
        if not args.quiet:
            tracks = "  ".join(f"#{t['id']} {t['status']} [" + ", ".join("-" if v is None else f"{v:.3f}"
                                                                         for v in t["joint_states"]) + "]"
                               for t in rec["tracks"])
            print(f"{rec['frame']:5d} {rec['file']}: {tracks or rec.get('error') or 'no object'} {rec['time_ms']:.0f} ms"
                  + (f"  (ended {rec['ended']})" if rec["ended"] else ""), flush=True)

    png = Path(args.png_dir) if args.png_dir else None
    types = tracker.joint_types
    if png is not None:
        png.mkdir(parents=True, exist_ok=True)

    def on_frame(i, depth, stepped):
        from ..tracking.pictures import draw_tracks

        draw_tracks(depth, intrinsics, stepped, png / f"{Path(files[i]).stem}.png", types)

    with JsonLinesWriter(out) as writer:
        records = track_files_multi(files, intrinsics, tracker, writer, progress=show,
                                    on_frame=on_frame if png is not None else None)
    if png is not None:
        from ..tracking.pictures import draw_states

        print(f"wrote {len(records)} pictures and {draw_states(records, png / 'states.png', types)}", file=sys.stderr)
    ids = {t["id"] for r in records for t in r["tracks"]}
    print(f"wrote {out}: {len(records)} frames, {len(ids)} track(s)", file=sys.stderr)
    return 0 if ids else 1


def _check_first_frame(files, intrinsics) -> None:
    """A clear error when the first readable frame's size differs from the intrinsics (a mismatched file)."""
    from ..data.images import read_depth

    for path in files:
        try:
            d = read_depth(path)
        except ValueError:
            continue
        if d.shape != (intrinsics.height, intrinsics.width):
            raise ValueError(f"intrinsics: {intrinsics.width}x{intrinsics.height} pixels, but the frames are "
                             f"{d.shape[1]}x{d.shape[0]} ({path.name}); is it the intrinsics file of this camera?")
        return
