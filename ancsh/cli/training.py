"""``ancsh train``: train the ANCSH network (or the direct-voting baseline) for one category;
``ancsh export``: ship a run's network, the checkpoint confirmed on all its validation frames
(:mod:`ancsh.learned.training.select`).

torch is imported inside :func:`run`, so ``ancsh --help`` stays light.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from ._args import category as category_arg
from ._args import positive_float


def register(sub) -> None:
    p = sub.add_parser(
        "train",
        help="train the ANCSH network for a category (resumable, checkpoints, curves)",
        description="Train the ANCSH network (or the direct joint-voting baseline) on HDF5 shards made by "
        "`ancsh data generate`. A run directory keeps config.json, last.pt, best.pt, history.csv, curves.png. "
        "Distributed (DDP, one process per core or GPU): torchrun --nproc_per_node N -m ancsh train ...; the "
        "config's batch_size is the global batch and must divide by N.",
    )
    p.add_argument("--category", required=True, type=category_arg, help="object category, e.g. laptop, or a category spec file or built category folder")
    p.add_argument("--config", type=Path, help="TrainConfig JSON (unknown keys are an error)")
    p.add_argument("--kind", choices=("ancsh", "direct_voting"), help="network (default: the config's, else ancsh)")
    p.add_argument("--resume", action="store_true", help="continue from RUN/last.pt")
    p.add_argument("--data", type=Path, help="training shards (default data_out/<category>_train, else data/<category>_train)")
    p.add_argument("--out", type=Path, help="run directory (default runs/<category>_<kind>)")
    p.add_argument("--max-steps", type=int, help="override config.max_steps (e.g. to extend a finished run)")
    p.add_argument("--compile", action=argparse.BooleanOptionalAction, default=None,
                   help="override config.compile: train with torch.compile (same function, fewer CPU-seconds per step "
                   "after a one-off compilation; needs a C++ compiler); --no-compile switches it off")
    p.add_argument("--time-limit-min", type=positive_float, help="stop (with a checkpoint) after this many minutes")
    p.add_argument("--test-data", type=Path, help="held-out test shards: evaluate best.pt against trivial baselines")
    p.add_argument("--export", type=Path, help="write compact weights of best.pt here after training, with the "
                   "run's config, history and curves beside it (<stem>_config.json, _history.csv, _curves.png)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    from ..learned.devices import add_device_argument

    add_device_argument(p)
    p.set_defaults(func=run)

    e = sub.add_parser(
        "export",
        help="ship a run's network: confirm best.pt against last.pt on all validation frames, export the better",
        description="Score a training run's checkpoints through the full pipeline (network, RANSAC, exact_reduced fit) "
        "on every frame of the run's validation instances -- the split re-created from the run's config.json and its "
        "training shards -- and export the lowest pose score (mean part rotation + joint-axis error, degrees) as a "
        "weights file with the run's config, history and curves beside it. The scores go into the weights file's "
        "metrics and <stem>_test_metrics.json under 'selection'.",
    )
    e.add_argument("--run", required=True, type=Path, help="run directory of `ancsh train` (config.json, best.pt, last.pt)")
    e.add_argument("--data", required=True, type=Path, help="the run's training shards (its validation split is made from them)")
    e.add_argument("--out", required=True, type=Path, help="weights file to write, e.g. ancsh/weights/laptop.pt")
    e.add_argument("--checkpoints", nargs="+", type=Path, metavar="PT",
                   help="candidates (default: the run's best.pt and last.pt, where present); a weights file among them "
                   "(e.g. the network the run was fine-tuned from) is scored too, and when it scores best nothing is "
                   "exported")
    e.add_argument("--frames", type=int, help="score this many evenly spaced validation frames (default: all)")
    e.add_argument("--test-data", type=Path, help="held-out test shards: the chosen network's scores against trivial "
                   "baselines, stored with the weights (as `ancsh train --test-data`)")
    e.add_argument("--overwrite", action="store_true", help="replace an existing weights file --out and the files "
                   "beside it (<stem>_config.json, ...); without it they are kept and nothing is scored")
    e.set_defaults(func=run_export)


def run(args: argparse.Namespace) -> int:
    from ..learned.distributed import init_distributed, shutdown_distributed

    context = init_distributed(args.device)  # a single process unless started by torchrun
    try:
        return _run(args, context)
    finally:
        shutdown_distributed(context)


def _run(args: argparse.Namespace, context) -> int:
    import json

    from ..learned.network.config import TrainConfig

    say = print if context.is_main else (lambda *a, **k: None)  # rank 0 speaks for a distributed run

    overrides = {"category": args.category, "kind": args.kind, "max_steps": args.max_steps, "compile": args.compile}
    config = None if args.config is None else TrainConfig.from_json(args.config, **overrides)
    kind = config.kind if config is not None else args.kind or "ancsh"
    out = args.out or Path("runs") / f"{args.category}_{kind}"
    last = out / "last.pt"
    if config is None and args.resume and (out / "config.json").is_file():
        config = TrainConfig.from_json(out / "config.json", **overrides)
    elif config is None:
        config = TrainConfig.from_dict({}, **overrides)
    if last.is_file() and not args.resume:
        raise ValueError(f"--out: {out} already holds a checkpoint; pass --resume to continue or choose another --out")
    if args.resume and not last.is_file():
        raise FileNotFoundError(f"--resume: no checkpoint {last}")
    if args.resume and (out / "config.json").is_file():
        try:
            saved = json.loads((out / "config.json").read_text()).get("category")
        except (json.JSONDecodeError, UnicodeDecodeError, AttributeError):
            raise ValueError(f"--resume: {out / 'config.json'} is not a valid run configuration") from None
        if saved != args.category:
            raise ValueError(f"--category: the run in {out} trains {saved!r}, not {args.category!r}; "
                             "resume it with --category " + str(saved) + " or choose another --out")

    from ..learned.training.data import arrays_from_dataset
    from ..learned.training.train import Trainer, split_by_instance

    data = args.data
    if data is None:  # where `ancsh data generate --out data_out/...` or its default put the shards
        candidates = [Path("data_out") / f"{args.category}_train", Path("data") / f"{args.category}_train"]
        data = next((c for c in candidates if c.is_dir()), candidates[0])
    shards = _check_shards(data, args.category)
    arrays = arrays_from_dataset(shards, config.num_points, seed=config.seed)
    train, val = split_by_instance(arrays, config.val_fraction, config.seed)
    say(f"{len(train)} training frames, {0 if val is None else len(val)} validation frames "
        f"({len(set(arrays.instance.tolist()))} instances) from {data}"
        + (f"; {context.world_size} processes on {context.device.type}" if context.active else f" on {context.device}"))
    if len(train) and config.batch_size % context.world_size:
        raise ValueError(f"--config: batch_size {config.batch_size} does not split evenly over {context.world_size} "
                         "processes; use a batch size divisible by the number of processes")
    pose_val = None
    if config.pose_val_every and val is not None and context.is_main:
        import numpy as np

        from ..learned.training.train import PoseValidation

        from ..learned.training.select import validation_frame_indices

        picks = validation_frame_indices(arrays.instance, np.unique(val.instance), config.pose_val_frames)
        pose_val = PoseValidation.from_dataset(data, picks, seed=config.seed)
        say(f"pose validation: {len(picks)} frames of the validation instances, every {config.pose_val_every} steps")
    trainer = Trainer(config, train, val, out, progress=not args.no_progress and context.is_main, pose_val=pose_val,
                      distributed=context)
    if args.resume:
        trainer.load_checkpoint(last)
        say(f"resumed {last} at step {trainer.step} ({trainer.elapsed_s / 60:.1f} min trained)")
    time_limit = None if args.time_limit_min is None else 60.0 * args.time_limit_min
    try:
        trainer.fit(time_limit_s=time_limit)
    except KeyboardInterrupt:
        say(f"\ninterrupted at step {trainer.step}: checkpoint {last} saved; run the same command with --resume "
            "to continue", file=sys.stderr)
        return 130
    if not context.is_main:  # rank 0 evaluates and exports
        return 0
    if trainer.history:
        row = trainer.history[-1]
        print("last:", ", ".join(f"{k}={v:.4g}" for k, v in row.items() if isinstance(v, float)))
    best = out / "best.pt" if (out / "best.pt").is_file() else last
    metrics = {}
    if args.test_data is not None:
        metrics = evaluate_checkpoint(best, args.test_data, config)
        (out / "test_metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
        print("test:", json.dumps(metrics, indent=1))
    if args.export is not None:
        from ..learned.network.weights import export_weights

        path = export_weights(best, args.export, metrics=metrics)
        print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB)")
        copy_training_log(out, path, metrics)
    return 0


def run_export(args: argparse.Namespace) -> int:
    import json

    from ..learned.network.config import TrainConfig
    from ..learned.training.select import choose, confirm_checkpoints
    from ..learned.network.weights import export_weights

    config_path = args.run / "config.json"
    if not config_path.is_file():
        raise FileNotFoundError(f"--run: no run configuration {config_path}")
    config = TrainConfig.from_json(config_path)
    existing = [p for p in exported_paths(args.run, args.out) if p.exists() or p.is_symlink()]
    if existing and not args.overwrite:  # before the scoring, which takes minutes
        raise ValueError(f"--out: {', '.join(map(str, existing))} exist(s); choose another --out or add --overwrite "
                         "to replace the exported files")
    candidates = args.checkpoints or [c for c in (args.run / "best.pt", args.run / "last.pt") if c.is_file()]
    if not candidates:
        raise FileNotFoundError(f"--run: {args.run} holds neither best.pt nor last.pt")
    shards = _check_shards(args.data, config.category)
    rows = confirm_checkpoints(candidates, shards, config, frames=args.frames)
    chosen = choose(rows)
    print(f"{'checkpoint':<40} {'step':>6} {'frames':>6} {'rotation':>9} {'axis':>7} {'state':>7} {'score':>7} failed")
    for r in rows:
        mark = "  <- export" if r is chosen else ""
        print(f"{Path(r['checkpoint']).name:<40} {r['step']:>6} {r['frames']:>6} {r['pose_rot_deg']:>9.3f} "
              f"{r['pose_axis_deg']:>7.3f} {r['pose_state_err']:>7.3f} {r['pose_score']:>7.3f} "
              f"{int(r['pose_failures'])}{mark}")
    from ..learned.network.weights import read_torch_file

    command = ["export", "--run", args.run, "--data", args.data, "--out", args.out]
    command += (["--checkpoints", *args.checkpoints] if args.checkpoints else [])
    command += (["--frames", args.frames] if args.frames is not None else [])
    command += (["--test-data", args.test_data] if args.test_data is not None else [])
    selection = {"chosen": chosen["checkpoint"], "candidates": rows,
                 "command": "ancsh " + shlex.join(str(a) for a in command)}
    # the scores are written whichever candidate won: a run that lost to a weights file is a measurement too
    (args.run / "selection.json").write_text(json.dumps(selection, indent=2) + "\n")
    if "model" not in read_torch_file(chosen["checkpoint"], argument="--checkpoints"):
        print(f"the best candidate, {chosen['checkpoint']}, is a weights file, not a training checkpoint: "
              f"nothing exported (keep it; the scores are in {args.run / 'selection.json'})")
        return 0
    metrics = {}
    if args.test_data is not None:
        metrics = evaluate_checkpoint(chosen["checkpoint"], args.test_data, config)
    metrics["selection"] = selection
    path = export_weights(chosen["checkpoint"], args.out, metrics=metrics)
    copy_training_log(args.run, path, metrics)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB), step {chosen['step']}, pose score "
          f"{chosen['pose_score']:.3f} on {chosen['frames']} validation frames")
    return 0


def _check_shards(data, category: str) -> list:
    """The intact shards of ``data`` (damaged ones are named on stderr and left out).

    Refuses shards of another procedural category or another part count than ``category``'s, and
    data without a single intact shard.
    """
    from ..data.dataset import FrameDataset
    from ..data.conventions import CONVENTIONS

    info = CONVENTIONS.get(category)
    ds = FrameDataset(data, skip_corrupt=True)
    for path, reason in ds.verify():
        print(f"note: left out the damaged shard {path}: {reason}", file=sys.stderr)
    if not ds.readers:
        raise ValueError(f"--data: no intact shard in {data}")
    for reader in ds.readers:
        path = reader.path
        if category is not None and reader.category in CONVENTIONS and reader.category != category:
            raise ValueError(f"--data: shard {path} holds {reader.category!r} frames, not {category!r}")
        parts = len(reader.part_names)
        if info is not None and parts != info.num_parts:
            raise ValueError(f"--data: shard {path} holds objects of {parts} parts; {category!r} has {info.num_parts}")
    return [r.path for r in ds.readers]


def evaluate_checkpoint(checkpoint, test_data, config) -> dict:
    """Metrics of ``checkpoint`` on held-out test shards, beside trivial baselines."""
    from ..learned.training.data import arrays_from_dataset
    from ..learned.training.train import evaluate_arrays, trivial_baselines
    from ..learned.network.weights import load_network

    net = load_network(checkpoint)
    arrays = arrays_from_dataset(test_data, config.num_points, seed=config.seed + 1)
    scores = evaluate_arrays(net.model, arrays, net.config)
    return {"checkpoint": str(checkpoint), "test_frames": len(arrays), **scores, **trivial_baselines(arrays)}


#: The run's files :func:`copy_training_log` puts beside an exported weights file: ``(run file, suffix of the copy)``.
_TRAINING_LOG = (("config.json", "_config.json"), ("history.csv", "_history.csv"), ("curves.png", "_curves.png"))
_TEST_METRICS_SUFFIX = "_test_metrics.json"


def exported_paths(run_dir, weights) -> list:
    """The files an export of ``run_dir`` to ``weights`` writes: the weights file, the copies of the run's config,
    history and curves that the run has (:func:`copy_training_log`) and the test metrics, as ``Path`` s."""
    run_dir, weights = Path(run_dir), Path(weights)
    logs = [weights.with_name(weights.stem + suffix) for name, suffix in _TRAINING_LOG if (run_dir / name).is_file()]
    return [weights, *logs, weights.with_name(weights.stem + _TEST_METRICS_SUFFIX)]


def copy_training_log(run_dir, weights, metrics: dict) -> None:
    """Put the run's config, history, curves (and test metrics) beside an exported weights file."""
    import json
    import shutil

    run_dir, weights = Path(run_dir), Path(weights)
    for name, suffix in _TRAINING_LOG:
        if (run_dir / name).is_file():
            shutil.copy(run_dir / name, weights.with_name(weights.stem + suffix))
    if metrics:
        weights.with_name(weights.stem + _TEST_METRICS_SUFFIX).write_text(json.dumps(metrics, indent=2) + "\n")
