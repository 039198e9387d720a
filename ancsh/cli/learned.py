"""``ancsh predict`` (one depth image -> poses, boxes, joints) and ``ancsh evaluate`` (Table 1/2 on test frames).

torch is imported only inside the command functions, so ``ancsh --help`` stays light.
"""

from __future__ import annotations

import argparse
import json
import shlex
from pathlib import Path

from ..outputs import output_flags, write_bytes_atomically
from ._args import category as category_arg
from ._args import category_as_given
from ._args import check_picture_path, non_negative_int, positive_int


def _add_refiner_arguments(p) -> None:
    """``--refiner`` and ``--refine-passes`` of ``predict`` and ``evaluate``."""
    p.add_argument("--refiner", type=Path, help="with --refine network: a refinement network's weights file instead of "
                   "the category's shipped <category>_refine.pt")
    p.add_argument("--refine-passes", type=positive_int,
                   help="with --refine network: passes of the refinement network (default: DEFAULT_PASSES of "
                   "ancsh.learned.inference.refine_network)")


def register(sub) -> None:
    from ._args import add_executor_arguments
    from ..learned.devices import add_device_argument

    p = sub.add_parser(
        "predict",
        help="one depth image -> per-part poses, amodal boxes, joint axes and states (learned ANCSH)",
        description="Back-project a depth image, run the category's shipped ANCSH network and fit the part poses and "
        "joints. Prints a summary; --out writes the JSON, --png a picture.",
    )
    p.add_argument("--depth", required=True, type=Path, help="16-bit PNG (millimetres by default) or .npy (metres); "
                   "a folder predicts every .png/.npy in it (--out and --png are then folders)")
    p.add_argument("--intrinsics", required=True, type=Path, help='JSON {"fx","fy","cx","cy","width","height"}')
    p.add_argument("--category", required=True, type=category_arg, help="object category, e.g. laptop, or a category spec file or built category folder")
    p.add_argument("--mask", type=Path, help="object mask (PNG or .npy, nonzero = object), same size as the depth; "
                   "without one the object is isolated automatically (planes removed, clusters, size + centrality)")
    p.add_argument("--pixel", metavar="U,V", help="isolation hint: a pixel on the object")
    p.add_argument("--box", metavar="U0,V0,U1,V1", help="isolation hint: a box around the object (pixels)")
    p.add_argument("--no-isolate", action="store_true", help="without --mask, use every valid pixel (no isolation)")
    p.add_argument("--max-objects", type=positive_int, metavar="N",
                   help="without --mask, --pixel or --box: report at most N objects of the category (default: every "
                   "one that passes the verification)")
    p.add_argument("--max-depth", type=float, help="drop pixels deeper than this (metres)")
    p.add_argument("--depth-scale", type=float, default=0.001, help="metres per PNG unit (default 0.001 = millimetres)")
    p.add_argument("--points", type=int, default=1024, help="points sampled from the valid pixels (default 1024)")
    p.add_argument("--formulation", default="exact_reduced",
                   help="fitting formulation: per_part, soft, exact_maximal, exact_reduced (default)")
    p.add_argument("--weights", type=Path, help="a weights file instead of the category's shipped weights")
    p.add_argument("--refine", choices=("auto", "template", "network", "none"), default="auto",
                   help="refine the fit: 'template' against the category template (articulated ICP, kept where its "
                   "score on the points is better), 'network' with the refinement network on the points in the fit's "
                   "NAOCS orientation, 'auto' (default) the one measured to help the category most, or none "
                   "(ancsh/data/templates/refine_defaults.json, `ancsh bench refine-defaults`)")
    _add_refiner_arguments(p)
    p.add_argument("--seed", type=non_negative_int, default=0, help="sampling / RANSAC seed (default 0)")
    p.add_argument("--hypotheses", type=positive_int, default=None, metavar="H",
                   help="independent tries per candidate whose consensus is the answer (default 3; 1: one seed's try)")
    p.add_argument("--out", type=Path, help="write the result JSON here")
    p.add_argument("--png", type=Path, help="write a picture here (boxes and axes on the depth image and the points)")
    p.add_argument("--rgb", type=Path, help="colour image registered to the depth: the picture draws over it")
    p.add_argument("--urdf", type=Path, metavar="DIR", help="write the fitted object as a URDF folder (of the 20 category "
                   "templates nearest to the fit, reshaped to it, the one that best explains the depth, the best 3 "
                   "aligned to it by articulated ICP; the base in the camera frame, the joint states in "
                   "joint_states.json); a failed fit writes none")
    p.add_argument("--overwrite", action="store_true", help="with --urdf: replace the files of an existing folder")
    p.add_argument("--urdf-align", type=non_negative_int, default=None, metavar="N",
                   help="with --urdf: align the best N templates to the depth by articulated ICP, each at its size and "
                   "4%% smaller and larger (default 3, about 2.7 s in all: the URDF's pose, joint states and size are then the "
                   "aligned model's, which explains the depth better; 0: the fit's own pose and joint states)")
    p.add_argument("--workers", type=positive_int, default=1, metavar="N",
                   help="with a folder --depth: predict its images in N processes, each loading the network once "
                   "(default 1); the results do not depend on N")
    add_device_argument(p)
    p.set_defaults(func=run_predict)
    p.epilog = "A failed status (too_few_points, implausible_size, too_few_inliers, ...) exits with code 1."

    e = sub.add_parser(
        "evaluate",
        help="the paper's Table 1/2 and occlusion analysis on held-out instances with the shipped weights",
        description="Render test frames of the held-out instances of a category, run the shipped ANCSH network once "
        "per frame and fit every method (NPCS, NAOCS, ANCSH-soft, ANCSH-exact); write <category>.md/.json and "
        "<category>_occlusion.png to --out.",
    )
    e.add_argument("--category", required=True, type=category_arg)
    e.add_argument("--formulations", nargs="+", metavar="METHOD",
                   help="methods (default all but the refinements): per_part (NPCS), naocs, soft, exact_reduced, "
                   "exact_maximal, template (= --refine template), network (= --refine network)")
    e.add_argument("--refine", nargs="+", choices=("template", "network"), help="also refine the exact_reduced fit: "
                   "'template' against the category template (the nearest training instance, articulated ICP; kept where "
                   "its score on the points is better), the 'ANCSH-exact + category template' row; 'network' with the "
                   "refinement network (the points in the fit's NAOCS orientation, --refine-passes passes), the "
                   "'ANCSH-exact + refinement network' row; both: both rows, on the same network output")
    _add_refiner_arguments(e)
    e.add_argument("--frames", type=int, help="test frames (default 3000, about the paper's count; 300 with --quick)")
    e.add_argument("--quick", action="store_true", help="a quick run: 300 frames (about a minute) unless --frames")
    e.add_argument("--time-limit-min", type=float, help="stop after this many minutes, keeping the frames done")
    e.add_argument("--seed", type=non_negative_int, default=0, help="base seed of the test frames (default 0)")
    e.add_argument("--weights", type=Path, help="ANCSH weights file instead of the shipped ones")
    e.add_argument("--direct-weights", type=Path, help="direct-voting weights (default: shipped, if any)")
    e.add_argument("--threads", type=int, default=1, help="torch threads per worker (default 1)")
    add_device_argument(e)
    add_executor_arguments(e, workers_default=1, workers_help="worker processes, each rendering, predicting and "
                           "fitting whole frames (default 1: in this process); the tables do not depend on it")
    e.add_argument("--real", default=None, metavar="CATALOG",
                   help="also evaluate the real test split of a catalog ('builtin' = the shipped one) and write "
                        "<category>_real.md beside the procedural report")
    e.add_argument("--real-all", action="store_true",
                   help="with --real: every imported object of the category (train and test; the training objects "
                        "were seen in training) instead of the real test split")
    e.add_argument("--out", type=Path, help="output folder (default: a fresh ancsh_results/evaluate-<category>-<time>/)")
    e.add_argument("--update-docs", action="store_true", help="write into the committed docs/results/ (when --out is not given)")
    e.add_argument("--no-progress", action="store_true")
    e.set_defaults(func=run_evaluate)
    from ..studies.confidence_calibration import MIN_FRAMES

    c = sub.add_parser(
        "calibrate",
        help="learn how far to trust a prediction: P(rotation errors < 10 deg) from the fit's evidence",
        description="Fit a seeded mix of good and hard cases (rendered held-out frames of a seed stream other than "
        "`ancsh evaluate`'s; stress scenes isolated without a mask, cropped and merged segments, perturbed network "
        "outputs, other categories' frames: ancsh.studies.confidence_calibration) and learn a logistic regression of "
        "whether every part's rotation error is below 10 deg on the fit's evidence; half the frames train it, the other "
        "half measure its reliability against the base rate as a constant (report and diagram). A constant model, or "
        "too few good or bad fits in a half, is an error. --install puts it beside the shipped weights, where "
        "`ancsh predict` uses it.",
    )
    c.add_argument("--category", required=True, type=category_arg)
    c.add_argument("--frames", type=int, default=300, help="example frames, half to fit, half to measure (default 300; "
                   f"at least {MIN_FRAMES}, with --object 8)")
    c.add_argument("--seed", type=non_negative_int, default=7, help="base seed of the frames (default 7; evaluate uses 0)")
    c.add_argument("--out", type=Path, help="report folder (default: a fresh ancsh_results/calibrate-<category>-<time>/)")
    c.add_argument("--update-docs", action="store_true", help="write the report into docs/results/ (when --out is not given)")
    c.add_argument("--install", action="store_true", help="write ancsh/weights/<category>_confidence.json "
                   f"(with --object: <category>_object.json); needs --frames of at least {MIN_INSTALL_FRAMES}")
    c.add_argument("--object", action="store_true", help="calibrate p_object instead: whether the fitted pixels are an "
                   "object of the category at all, against the other categories' objects and clutter "
                   "(ancsh.studies.object_evidence; --frames counts the category's frames, about as many others are added)")
    c.add_argument("--scenes", type=non_negative_int, default=0,
                   help="with --object only (an error without it): also this many rendered scenes, their candidate segments "
                   "isolated without a mask (the object's against the rest; default 0)")
    c.add_argument("--evidence", type=Path, metavar="NPZ",
                   help="with --object only: fit the model on the examples a run wrote (its <category>_object_evidence.npz) "
                   "instead of fitting frames again (--frames and --scenes are then not used)")
    c.add_argument("--no-progress", action="store_true")
    c.set_defaults(func=run_calibrate)
    register_weights(sub)


def register_weights(sub) -> None:
    w = sub.add_parser(
        "weights",
        help="list the shipped networks: category, kind, size, training steps and time, held-out scores",
        description="Summarise the network weights shipped in the package (ancsh/weights/). --out also writes the "
        "table as markdown with the command that made it.",
    )
    w.add_argument("--out", type=Path, help="write the markdown table here (e.g. docs/results/weights.md)")
    w.add_argument("--reports", type=Path, metavar="DIR",
                   help="also set the evaluation reports in DIR (<category>.json of `ancsh evaluate`, e.g. docs/results) "
                   "against the paper's Table 1: the learned-accuracy targets, per category")
    w.set_defaults(func=run_weights)


def run_weights(args: argparse.Namespace) -> int:
    from ..learned.network.weights import weights_summary
    from ..studies.report import Provenance
    from ..studies.weights import target_tables, weights_tables, write_weights_report

    rows = weights_summary()
    lines, curves, pose = weights_tables(rows)
    targets, limits = target_tables(args.reports, rows) if args.reports is not None else ([], [])
    print("\n".join(lines))
    print("\n".join(curves))
    if len(pose) > 2:
        print("\n".join(pose))
    if targets:
        print("\n".join(targets))
        print("\n".join(limits))
    if args.out is not None:
        cmd = _command(["weights", *(["--reports", str(args.reports)] if args.reports is not None else []),
                        "--out", str(args.out)])
        write_weights_report(args.out, rows, (lines, curves, pose), targets, limits, reports=args.reports,
                             provenance=Provenance(cmd))
        print(f"wrote {args.out}")
    return 0


def _command(argv_tail: list[str]) -> str:
    return "ancsh " + " ".join(shlex.quote(a) for a in argv_tail)


def _passes(args: argparse.Namespace) -> dict:
    """``refine_passes`` of ``--refine-passes`` (nothing when not given: the library's default)."""
    return {} if args.refine_passes is None else {"refine_passes": args.refine_passes}


def _hypotheses(args: argparse.Namespace) -> dict:
    """``predict_depth``'s ``hypotheses`` of ``--hypotheses`` (its default when not given)."""
    return {} if args.hypotheses is None else {"hypotheses": args.hypotheses}


def _device(args: argparse.Namespace):
    """The torch device of ``--device`` (a clear error naming the option when CUDA is asked for but absent)."""
    from ..learned.devices import resolve_device

    return resolve_device(args.device, argument="--device")


def run_predict(args: argparse.Namespace) -> int:
    from ..data.isolate import parse_hint
    from ..data.show import save_figure
    from ..data.images import read_rgb
    from ..learned.inference.predict import draw_prediction, predict_depth, read_depth, read_intrinsics, read_mask

    if args.points < 1:
        raise ValueError(f"--points: expected a positive number of points, got {args.points}")
    if args.refiner is not None and args.refine != "network":
        raise ValueError("--refiner: a refinement network is used with --refine network only")
    if args.refine_passes is not None and args.refine != "network":
        raise ValueError("--refine-passes: the refinement network's passes are used with --refine network only")
    if args.overwrite and args.urdf is None:
        raise ValueError("--overwrite: only with --urdf DIR")
    if args.max_objects is not None and (args.mask is not None or args.pixel is not None or args.box is not None):
        raise ValueError("--max-objects: a --mask, --pixel or --box selects one object; leave --max-objects out")
    if args.urdf_align is not None and args.urdf is None:
        raise ValueError("--urdf-align: only with --urdf DIR")
    if args.urdf is not None:  # before any work
        if args.depth.is_dir():
            raise ValueError("--urdf: one folder cannot hold the objects of a folder of depth images; predict each file")
        from ..model.urdf_export import check_urdf_folder

        check_urdf_folder(args.urdf, overwrite=args.overwrite, argument="--urdf", overwrite_hint="add --overwrite")
    if args.png is not None and not args.depth.is_dir():
        check_picture_path(args.png, "--png")
    _device(args)  # a missing CUDA device is the first thing to hear about
    hint = parse_hint(args.pixel, args.box)
    intr = read_intrinsics(args.intrinsics)
    if args.depth.is_dir():
        return _predict_folder(args, intr, hint)
    if args.workers != 1:
        raise ValueError("--workers: one image is predicted in one process; give a folder --depth to use workers")
    depth = read_depth(args.depth, depth_scale=args.depth_scale, shape=(intr.height, intr.width))
    mask = None if args.mask is None else read_mask(args.mask, depth.shape)
    rgb = None if args.rgb is None else read_rgb(args.rgb, depth.shape)
    pred = predict_depth(depth, intr, args.category, mask=mask, max_depth=args.max_depth, weights=args.weights,
                         formulation=args.formulation, num_points=args.points, seed=args.seed,
                         isolate=not args.no_isolate, hint=hint, refine=args.refine, refiner=args.refiner,
                         **_passes(args),
                         device=_device(args), max_objects=args.max_objects, **_hypotheses(args))
    data = pred.to_json()
    data["input"] = {"depth": str(args.depth), "intrinsics": intr.to_json(), "mask": None if args.mask is None else str(args.mask),
                     "depth_scale": args.depth_scale, "max_depth": args.max_depth, "seed": args.seed,
                     "pixel": args.pixel, "box": args.box, "isolate": not args.no_isolate}
    r = pred.result
    found = data["objects_found"]
    print(f"{args.category}: {found} object(s) found" + ("" if found else f" ({r.status.value})")
          + f", {r.formulation} fit (isolation {data['timings_ms']['isolate']:.0f} ms, verification "
          f"{data['timings_ms']['verify']:.0f} ms, total {data['timings_ms']['total']:.0f} ms)")
    for note in pred.notes[:1] if pred.isolation is not None else ():
        print(f"  note: {note}")
    for obj, o in zip(pred.objects or (pred,), data["objects"]):
        _print_object(obj, o, skip_notes=1 if pred.isolation is not None else 0)
    if args.out is not None:
        write_bytes_atomically(args.out, (json.dumps(data, indent=1) + "\n").encode())
        print(f"  result: {args.out}")
    if args.png is not None:
        print(f"  picture: {save_figure(draw_prediction(depth, pred, intr, rgb=rgb), args.png)}")
    if args.urdf is not None:
        if r.ok:
            from ..learned.inference.predict import URDF_ALIGN
            from ..solvers.twin import ObservedDepth

            object_mask = mask if mask is not None else pred.object_mask(depth.shape)
            observed = None if object_mask is None else ObservedDepth(depth, intr, object_mask)
            align = URDF_ALIGN if args.urdf_align is None else args.urdf_align
            path, twin = pred.export_urdf(args.urdf, overwrite=args.overwrite, observed=observed, align=align,
                                          rng=args.seed)
            from ..solvers.twin import FIT_CAD_INIT

            print(f"  URDF: {path} (joint states in {args.urdf / 'joint_states.json'}; its pose for fit-cad --init in "
                  f"{args.urdf / FIT_CAD_INIT})")
            print(f"    model: template {twin.template}" + ("" if twin.median_residual_m is None else
                  f", {'aligned to the depth' if twin.aligned else 'at the fitted pose and states'}, median |depth "
                  f"residual| {1e3 * twin.median_residual_m:.1f} mm on the object's pixels"))
        else:
            print(f"  URDF: none (the fit failed: {r.status.value})")
    return 0 if r.ok else 1


def _print_object(pred, data: dict, *, skip_notes: int = 0) -> None:
    """The summary lines of one object of ``ancsh predict`` (``data``: its :meth:`DepthPrediction.object_json`)."""
    box = (data["mask"] or {}).get("bbox")
    p_obj = data["confidence"]["p_object"]
    print(f"object {data['id']}: {data['status']}, {data['points']} of {data['valid_pixels']} valid pixels"
          + ("" if box is None else f", pixels {box[0]}..{box[2]} x {box[1]}..{box[3]}")
          + ("" if p_obj is None else f", p_object {p_obj:.2f}")
          + f" (network {data['timings_ms']['network']:.0f} ms, fit {data['timings_ms']['fit']:.0f} ms)")
    if not data["ok"]:
        print(f"  {data['message']}")
    for note in pred.notes[skip_notes:]:
        print(f"  note: {note}")
    for part in data["parts"]:
        if part["pose"] is not None:
            t = part["pose"]["translation"]
            ext = part["box"]["extents"] if part["box"] else None
            q = part["quality"] or {}
            evidence = ("" if q.get("inlier_ratio") is None or q.get("residual_m") is None else
                        f"  inliers {100 * q['inlier_ratio']:.0f}%, residual {1e3 * q['residual_m']:.1f} mm")
            print(f"  part {part['name']:12s} {part['points']:5d} pts  t = [{t[0]:+.3f} {t[1]:+.3f} {t[2]:+.3f}] m"
                  + (f"  box {ext[0]:.3f} x {ext[1]:.3f} x {ext[2]:.3f} m" if ext else "") + evidence)
    for j in data["joints"]:
        if j["state"] is not None:
            f, unit = (57.29577951308232, "deg") if j["type"] == "revolute" else (1.0, "m")
            absolute = "" if j["state_abs"] is None else f", absolute {j['state_abs'] * f:.1f} {unit}"
            print(f"  joint {j['name']:12s} ({j['type']}) state {j['state'] * f:.1f} {unit} relative to rest{absolute}")


def _predict_folder(args: argparse.Namespace, intr, hint) -> int:
    """``ancsh predict --depth DIR``: every depth image of a folder, one JSON (and picture) each, a progress bar;
    ``--workers N`` processes, each loading the network once."""
    from tqdm import tqdm

    from ..executors import LocalExecutor
    from ..learned.inference.folder import FolderOptions, predict_folder
    from ..outputs import fresh_output_dir

    files = sorted(p for p in args.depth.iterdir() if p.suffix.lower() in (".png", ".npy") and not p.is_dir())
    if not files:
        raise ValueError(f"--depth: the folder {args.depth} holds no .png or .npy depth image")
    if args.rgb is not None:
        raise ValueError("--rgb: one colour image cannot serve a folder of depth images; predict each file")
    if args.mask is not None:
        raise ValueError("--mask: one mask cannot serve a folder of depth images; leave it out (isolation) or predict each file")
    out = args.out if args.out is not None else fresh_output_dir(f"predict-{args.category}")
    out.mkdir(parents=True, exist_ok=True)
    if args.png is not None:
        args.png.mkdir(parents=True, exist_ok=True)
    provider = dict(seed=args.seed, refine=args.refine, refiner=None if args.refiner is None else str(args.refiner),
                    device=str(_device(args)), **_passes(args), **({"num_threads": 1} if args.workers > 1 else {}))
    options = FolderOptions(
        category=args.category, intrinsics=intr, depth_scale=args.depth_scale,
        weights=None if args.weights is None else str(args.weights), provider=provider,
        predict=dict(max_depth=args.max_depth, formulation=args.formulation, num_points=args.points, seed=args.seed,
                     isolate=not args.no_isolate, hint=hint, max_objects=args.max_objects, **_hypotheses(args)),
        input={"max_depth": args.max_depth, "seed": args.seed, "pixel": args.pixel, "box": args.box,
               "isolate": not args.no_isolate})
    with tqdm(total=len(files), desc=f"predict {args.category}", unit="image", dynamic_ncols=True) as bar:
        statuses = predict_folder(files, options, out, args.png, executor=LocalExecutor(workers=args.workers),
                                  progress=lambda: bar.update(1))
    for name, status in statuses.items():
        print(f"  {name}: {status}")
    good = sum(s == "success" for s in statuses.values())
    print(f"{good} of {len(files)} images: success; results in {out}")
    return 0 if good == len(files) else 1


#: ``ancsh calibrate --install`` (either calibration) needs at least this many frames: half fit the model, half check
#: it, and a model from a handful of frames (one outcome, or a regression on noise) must not replace the shipped one.
#: (``p_good`` needs :data:`ancsh.studies.confidence_calibration.MIN_FRAMES` with or without ``--install``.)
MIN_INSTALL_FRAMES = 40


def run_calibrate(args: argparse.Namespace) -> int:
    import numpy as np

    from ..outputs import file_sha256
    from ..learned.inference.confidence import calibration_path
    from ..studies.confidence_calibration import (MIN_FRAMES, MIN_FRAMES_PER_OUTCOME, calibrate_and_check,
                                                  check_informative, collect, fitting_half, source_table, write_report)
    from ..learned.network.weights import weights_path

    if args.scenes and not args.object:  # before any work: p_good's examples hold their scenes already
        raise ValueError(f"--scenes: only with --object (p_object's scenes); p_good's examples include stress scenes "
                         f"already (one frame in eight of --frames), got --scenes {args.scenes} without --object")
    if args.evidence is not None and not args.object:
        raise ValueError(f"--evidence: only with --object (p_object's examples), got --evidence {args.evidence}")
    if not args.object and args.frames < MIN_FRAMES:  # before any work, whether or not --install is given
        raise ValueError(f"--frames: a p_good calibration needs at least {MIN_FRAMES} frames (half fit it, half check "
                         f"it, each half with {MIN_FRAMES_PER_OUTCOME} good and bad fits), got --frames {args.frames}")
    if args.frames < 4:
        raise ValueError(f"--frames: expected at least 4 frames, got {args.frames}")
    if args.install and args.frames < MIN_INSTALL_FRAMES:  # before any work: it would replace the shipped calibration
        raise ValueError(f"--install: a calibration from --frames {args.frames} would replace the shipped one; installing "
                         f"needs at least {MIN_INSTALL_FRAMES} frames (half fit it, half check it)")
    if not weights_path(args.category).is_file():
        from ..learned.network.weights import missing_weights_error

        raise missing_weights_error(args.category)
    if args.object:
        return _run_calibrate_object(args)
    data = collect(args.category, args.frames, seed=args.seed, progress=not args.no_progress)
    fit_half = fitting_half(data["frame"])
    try:
        calibration, rel = calibrate_and_check(data["X"][fit_half], data["good"][fit_half], data["X"][~fit_half],
                                               data["good"][~fit_half])
    except ValueError as e:  # too few good or bad fits in a half: more frames
        raise ValueError(f"--frames: {args.frames} frames gave too few good or bad fits ({e}); raise --frames") from None
    check_informative(calibration)
    calibration["weights_sha256"] = file_sha256(weights_path(args.category))  # it holds for these weights only
    calibration["example_frames"] = int(args.frames)
    calibration["source_frames"] = data["source_frames"]
    out, command = _calibrate_output(args)
    paths = write_report(args.category, calibration, rel, out, command=command, sources=source_table(calibration, data))
    b = calibration["brier_check"]
    print(f"good fits {100 * rel['good_rate']:.0f}% of {rel['frames']} check fits, logistic Brier {b['logistic']:.4f} "
          f"(constant {b['constant']:.4f}{'' if b['logistic'] < b['constant'] else ': NOT beaten'}), "
          f"AUC {calibration['auc_check']:.3f}; wrote {paths['md']}, {paths['png']}")
    _install_calibration(args, paths["json"], calibration_path(args.category))
    return 0


def _calibrate_output(args: argparse.Namespace) -> tuple:
    """``ancsh calibrate``'s report folder and the command line that reproduces the run."""
    from ..outputs import DOCS_RESULTS, fresh_output_dir

    out = args.out if args.out is not None else DOCS_RESULTS if args.update_docs else fresh_output_dir(f"calibrate-{args.category}")
    parts = ["calibrate", "--category", category_as_given(args.category)] + (["--object"] if args.object else []) + ["--frames", str(args.frames)]
    parts += ["--seed", str(args.seed)] if args.seed != 7 else []
    parts += ["--scenes", str(args.scenes)] if args.object and args.scenes else []
    parts += ["--evidence", str(args.evidence)] if args.evidence is not None else []
    parts += output_flags(args.out, update_docs=args.update_docs)
    parts += ["--install"] if args.install else []
    return out, _command(parts)


def _install_calibration(args: argparse.Namespace, report_json, target) -> None:
    """With ``--install``, the calibration the report wrote becomes the shipped one beside the weights."""
    if args.install:
        write_bytes_atomically(target, report_json.read_bytes())
        print(f"installed {target}")


def _installed_object_calibration(category: str, weights_sha256: str) -> dict | None:
    """The shipped ``p_object`` model of ``category`` where it was calibrated for these weights and features."""
    import json

    from ..learned.inference.confidence import OBJECT_FEATURES, object_calibration_path

    path = object_calibration_path(category)
    if not path.is_file():
        return None
    calibration = json.loads(path.read_text())
    if calibration.get("weights_sha256") != weights_sha256 or calibration.get("features") != list(OBJECT_FEATURES):
        return None
    return calibration


def _run_calibrate_object(args: argparse.Namespace) -> int:
    import numpy as np

    from ..learned.inference.confidence import object_calibration_path
    from ..learned.inference.predict import MIN_P_OBJECT
    from ..learned.network.weights import weights_path
    from ..outputs import file_sha256
    from ..learned.inference.confidence import object_model
    from ..studies.object_evidence import (collect_object_evidence, fit_object_calibrator, is_scene_source, load_evidence,
                                           measure, save_evidence, write_object_report)

    if args.frames < 8:
        raise ValueError(f"--frames: expected at least 8 frames with --object, got {args.frames}")
    if args.evidence is not None:
        try:
            data = load_evidence(args.evidence)
        except ValueError as e:
            raise ValueError(f"--{e}") from None
        frames = len(np.unique(data["frame"]))
        if args.install and frames < MIN_INSTALL_FRAMES:
            raise ValueError(f"--install: --evidence {args.evidence} holds {frames} frames; installing needs at least "
                             f"{MIN_INSTALL_FRAMES} (half fit it, half check it)")
    else:
        data = collect_object_evidence(args.category, args.frames, seed=args.seed, progress=not args.no_progress,
                                       scenes=args.scenes)
    half = data["frame"] % 2 == 0  # a frame's fits (one per refinement) on one side
    masked = ~np.array([is_scene_source(s) for s in data["source"]], dtype=bool)
    calibration = fit_object_calibrator(data["X"][half & masked], data["is_object"][half & masked])
    calibration["weights_sha256"] = file_sha256(weights_path(args.category))
    calibration["refinements"] = data["refinements"]
    if not masked.all():  # scenes: a second model for the segments found without a mask, on every example
        segments = fit_object_calibrator(data["X"][half], data["is_object"][half])
        calibration["segments"] = {k: segments[k] for k in ("mean", "scale", "coef", "intercept", "frames", "object_rate")}

    def checked(model, rows):
        source = [s for s, r in zip(data["source"], rows) if r]
        refinement = [r for r, k in zip(data["refinement"], rows) if k]
        return measure(model, data["X"][rows], data["is_object"][rows], source, MIN_P_OBJECT, refinement)

    check = checked(calibration, ~half & masked)
    check_segments = checked(object_model(calibration, segmented=True), ~half) if "segments" in calibration else None
    installed = _installed_object_calibration(args.category, calibration["weights_sha256"])
    before = None if installed is None else checked(installed, ~half & masked)
    out, command = _calibrate_output(args)
    paths = write_object_report(args.category, calibration, check, data, out, command=command, threshold=MIN_P_OBJECT,
                                installed=before, check_segments=check_segments)
    if args.evidence is None:  # the examples, to fit the model again without the frames (--evidence)
        save_evidence(data, Path(out) / f"{args.category}_object_evidence.npz")
    print(f"{args.category}: {100 * check['_all']['true_accept']:.0f}% of its objects accepted, "
          f"{100 * check['_all']['false_accept']:.0f}% of other things" + (
              "" if check_segments is None else f"; segments found without a mask: "
              f"{100 * check_segments['_all']['true_accept']:.0f}% of the objects accepted, "
              f"{100 * check_segments['_all']['false_accept']:.0f}% of the rest") + f"; wrote {paths['md']}")
    _install_calibration(args, paths["json"], object_calibration_path(args.category))
    return 0


def run_evaluate(args: argparse.Namespace) -> int:
    from ..studies.table1 import DEFAULT_METHODS, evaluate_category, summarize, write_report

    from ..outputs import DOCS_RESULTS, fresh_output_dir

    methods = tuple(args.formulations) if args.formulations else DEFAULT_METHODS
    frames = args.frames if args.frames is not None else (300 if args.quick else 3000)
    if frames < 1:
        raise ValueError(f"--frames: expected a positive number of frames, got {frames}")
    if args.threads < 1:
        raise ValueError(f"--threads: expected a positive number of threads, got {args.threads}")
    if args.refiner is not None and "network" not in (args.refine or ()):
        raise ValueError("--refiner: a refinement network is evaluated with --refine network only")
    if args.refine_passes is not None and "network" not in (args.refine or ()):
        raise ValueError("--refine-passes: the refinement network's passes are evaluated with --refine network only")
    if args.time_limit_min is not None and not args.time_limit_min > 0:
        raise ValueError(f"--time-limit-min: expected a positive number of minutes, got {args.time_limit_min}")
    if args.real_all and not args.real:
        raise ValueError("--real-all: only with --real CATALOG")
    real_split = "all" if args.real_all else None
    if args.real:  # checked before the procedural evaluation, not after it
        from ..data.generate import FrameGenerator, GenerationConfig

        gen = FrameGenerator(GenerationConfig(category=args.category, split="test", seed=args.seed, real=args.real,
                                              real_fraction=1.0, real_split=real_split))
        if not gen.real_instances:
            which = "imported" if args.real_all else "test"
            raise ValueError(f"--real: the catalog {args.real!r} has no real {which} object of {args.category!r}")
    from ._args import executor_from_args

    executor = executor_from_args(args)
    common = dict(
        frames=frames, methods=methods, seed=args.seed, weights=args.weights, direct_weights=args.direct_weights,
        time_limit_s=None if args.time_limit_min is None else 60.0 * args.time_limit_min,
        num_threads=args.threads, progress=not args.no_progress, refine=args.refine, refiner=args.refiner, executor=executor,
        device=_device(args), refine_passes=args.refine_passes,
    )
    with executor.session():  # one Ray connection for both splits
        ev = evaluate_category(args.category, **common)
        out = args.out if args.out is not None else DOCS_RESULTS if args.update_docs else fresh_output_dir(f"evaluate-{args.category}")
        summary = summarize(ev)
        real = None
        if args.real:  # the real split is evaluated first so that <category>.md can show both splits
            real_ev = evaluate_category(args.category, real=args.real, real_split=real_split, **common)
            real = (real_ev, summarize(real_ev))
        paths = write_report(ev, summary, out, command=_rebuild(args), real=real)
        print(f"{ev['settings']['frames']} frames; wrote {paths['md']}, {paths['json']}, {paths['png']}")
        if real is not None:
            from ..studies.table1 import write_real_report

            path = write_real_report(ev, summary, real[0], real[1], out, command=_rebuild(args))
            print(f"{real[0]['settings']['frames']} real frames; wrote {path}")
    return 0


def _rebuild(args: argparse.Namespace) -> str:
    """The command line, rebuilt from the parsed arguments (defaults left out)."""
    parts = ["evaluate", "--category", category_as_given(args.category)]
    if args.formulations:
        parts += ["--formulations", *args.formulations]
    for flag, value in (("--frames", args.frames), ("--time-limit-min", args.time_limit_min), ("--weights", args.weights),
                        ("--direct-weights", args.direct_weights), ("--refiner", args.refiner), ("--out", args.out)):
        if value is not None:
            parts += [flag, str(value)]
    if args.quick:
        parts.append("--quick")
    if args.real:
        parts += ["--real", args.real]
    if args.real_all:
        parts.append("--real-all")
    if args.refine:
        parts += ["--refine", *dict.fromkeys(args.refine)]
    if args.refine_passes is not None:
        parts += ["--refine-passes", str(args.refine_passes)]
    if args.update_docs and args.out is None:
        parts.append("--update-docs")
    if args.seed:
        parts += ["--seed", str(args.seed)]
    if args.threads != 1:
        parts += ["--threads", str(args.threads)]
    if args.workers != 1:
        parts += ["--workers", str(args.workers)]
    if args.executor != "local":
        parts += ["--executor", args.executor] + (["--ray-address", args.ray_address] if args.ray_address else [])
    if args.device != "auto":
        parts += ["--device", args.device]
    return _command(parts)
