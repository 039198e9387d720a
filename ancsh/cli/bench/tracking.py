"""``ancsh bench tracking``: the arguments of :mod:`ancsh.studies.tracking`."""

from __future__ import annotations

import json
import time

from ...outputs import output_flags
from .._args import changed_options, non_negative_int


def register(sub) -> None:
    """Add ``tracking`` to the ``ancsh bench`` sub-commands."""
    p = sub.add_parser("tracking", help="tracking vs independent per-frame fitting on generated sequences")
    p.add_argument("--categories", default="laptop,drawer,eyeglasses", help="procedural categories (comma-separated)")
    p.add_argument("--providers", default="learned,oracle", help="learned and/or oracle (comma-separated)")
    p.add_argument("--urdf", default="default",
                   help="URDF object for instance-level tracking ('default': the shared laptop_10101; 'none': skip)")
    p.add_argument("--sequences", type=int, default=2, help="sequences per object (default 2)")
    p.add_argument("--length", type=int, default=40, help="frames per sequence (default 40)")
    p.add_argument("--urdf-length", type=int, default=16, help="frames per URDF sequence (default 16)")
    p.add_argument("--urdf-sequences", type=int, default=1, help="URDF sequences (default 1)")
    p.add_argument("--gap", type=int, default=3, help="blank frames in the middle of each sequence (default 3)")
    p.add_argument("-k", "--network-every", type=int, default=3, help="network on every k-th tracked frame (default 3)")
    p.add_argument("--seed", type=non_negative_int, default=0)
    p.add_argument("--tracker", default=None, metavar="JSON",
                   help="TrackerConfig settings of the tracking side, a JSON object, e.g. '{\"temporal_weight\": 0.1}' "
                        "(default: TrackerConfig's defaults)")
    p.add_argument("--calibration-sequences", type=int, default=0,
                   help="first measure inflation maps of tracked frames' standard deviations on this many other "
                        "sequences per procedural object (default 0: none)")
    p.add_argument("--calibration-seed", type=non_negative_int, default=1001, help="frame seed of the calibration sequences (default 1001)")
    p.add_argument("--install", action="store_true",
                   help="install the measured maps in ancsh/weights/uncertainty_inflation.json before the benchmark's "
                        "sequences run (needs --calibration-sequences)")
    p.add_argument("--refiner", default=None, metavar="FILE",
                   help="with --tracker '{\"refine_network\": true}': the learned provider's refinement network "
                        "(default: the category's shipped one)")
    p.add_argument("--out", default=None, help="markdown report path (default: a fresh ancsh_results/bench-tracking-<time>/)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/tracking.md (when --out is not given)")
    p.set_defaults(func=run)


def _command(args) -> str:
    defaults = {"categories": "laptop,drawer,eyeglasses", "providers": "learned,oracle", "urdf": "default", "sequences": 2,
                "length": 40, "urdf_length": 16, "urdf_sequences": 1, "gap": 3, "network_every": 3, "seed": 0,
                "calibration_sequences": 0, "calibration_seed": 1001}
    parts = ["ancsh bench tracking", *changed_options(args, defaults)]
    if args.tracker:
        parts.append(f"--tracker '{json.dumps(_tracker_settings(args.tracker), sort_keys=True)}'")
    parts += changed_options(args, {"refiner": None})
    if args.install:
        parts.append("--install")
    parts += output_flags(args.out, update_docs=args.update_docs)
    return " ".join(parts)


def _tracker_settings(text: str | None) -> dict:
    """``--tracker``'s JSON object (``{}`` without it); unknown or invalid settings raise ``ValueError``."""
    from ...tracking.tracker import TrackerConfig

    if not text:
        return {}
    try:
        settings = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"--tracker: expected a JSON object, got {text!r} ({exc})") from None
    if not isinstance(settings, dict):
        raise ValueError(f"--tracker: expected a JSON object, got {text!r}")
    known = {f for f in TrackerConfig.__dataclass_fields__} - {"network_every", "fit"}
    unknown = sorted(set(settings) - known)
    if unknown:
        raise ValueError(f"--tracker: unknown setting(s) {unknown} (known: {sorted(known)}; -k sets network_every)")
    TrackerConfig(**settings)  # validates the values
    return settings


def run(args) -> int:
    from ...outputs import report_path
    from ...studies.tracking import BenchConfig, calibrate, default_urdf, run_benchmark, summarize, write_report

    urdf = default_urdf() if args.urdf == "default" else None if args.urdf == "none" else args.urdf
    if args.urdf == "default" and urdf is None:
        print("bench tracking: the shared laptop_10101 URDF is not available; the URDF rows are skipped")
    providers = tuple(p.strip() for p in args.providers.split(",") if p.strip())
    for p in providers:
        if p not in ("learned", "oracle"):
            raise ValueError(f"--providers: expected learned and/or oracle, got {p!r}")
    config = BenchConfig(categories=tuple(c.strip() for c in args.categories.split(",") if c.strip()), providers=providers,
                         urdf=urdf, sequences=args.sequences, urdf_sequences=args.urdf_sequences, length=args.length, urdf_length=args.urdf_length, gap=args.gap,
                         network_every=args.network_every, seed=args.seed, tracker=_tracker_settings(args.tracker),
                         calibration_sequences=args.calibration_sequences, calibration_seed=args.calibration_seed,
                         refiner=args.refiner)
    if args.refiner and not config.tracker.get("refine_network"):
        raise ValueError("--refiner: a refinement network is used with --tracker '{\"refine_network\": true}' only")
    if config.tracker.get("refine_network") and "oracle" in providers:
        raise ValueError("--tracker refine_network: the oracle provider has no refinement network (--providers learned)")
    if args.calibration_sequences < 0:
        raise ValueError(f"--calibration-sequences: expected an integer >= 0, got {args.calibration_sequences}")
    if args.install and not args.calibration_sequences:
        raise ValueError("--install: nothing to install without --calibration-sequences")
    command = _command(args)
    out = report_path(args.out, update_docs=args.update_docs, docs_name="tracking.md", command="bench-tracking")
    t0 = time.perf_counter()
    calibration = None
    if args.calibration_sequences:
        calibration = calibrate(config, progress=lambda s: print(s, flush=True))
        if args.install:
            from ...studies.uncertainty_calibration import CalibrationConfig, install
            from ...tracking.tracker import TrackerConfig

            tformulation = TrackerConfig(**config.tracker).formulation
            print(f"installed the maps of tracked frames in {install(calibration['summary'], CalibrationConfig(formulation=tformulation), command)}")
    report = run_benchmark(config, progress=lambda s: print(s, flush=True))
    summary = summarize(report)
    text = write_report(report, summary, out, command=command, calibration=calibration, installed=args.install)
    print(text)
    print(f"wrote {out} and {out.with_suffix('.json')} in {time.perf_counter() - t0:.0f} s")
    return 0
