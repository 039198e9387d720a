"""``ancsh demo``: the README's main job, the full pipeline on built-in data.

For each of the paper's five categories it renders a depth frame of a held-out (test)
procedural instance, turns the observed points into ANCSH correspondences — with the
shipped network weights of the category when there are any, otherwise with the oracle
provider at its ``realistic`` corruption preset (clearly labelled) — fits the per-part
NPCS baseline and the exact kinematically constrained formulation, prints the per-part
and per-joint errors against ground truth, and draws each fit to ``--out``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from ._args import non_negative_int


def register(sub) -> None:
    p = sub.add_parser("demo", help="full pipeline on built-in data: render, predict, fit, per-part error table, pictures")
    p.add_argument("--categories", default="all", help="comma-separated procedural categories (default: all = the paper's five)")
    p.add_argument("--frame", type=int, default=0, help="frame index of the held-out test stream (default 0)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="base seed of the test frames (default 0)")
    p.add_argument("--provider", choices=("auto", "learned", "oracle"), default="auto",
                   help="correspondences: shipped network weights, oracle (corrupted ground truth), "
                        "or auto = learned where weights are shipped (default)")
    p.add_argument("--out", default="demo_out", help="folder for the pictures (default demo_out/)")
    p.set_defaults(func=run)


def _provider(category: str, choice: str, frame, limits, seed: int):
    """(provider, label) for one frame."""
    from ..solvers.providers.oracle import OracleProvider

    if choice != "oracle":
        from ..learned.network.weights import available_weights

        if category in available_weights():
            from ..learned.inference.provider import LearnedProvider

            return LearnedProvider(category, seed=seed), "learned (shipped weights)"
        if choice == "learned":
            raise ValueError(f"provider: no shipped weights for {category!r} (have: {available_weights()})")
    return OracleProvider(frame, "realistic", rng=seed, joint_limits=limits), "oracle, 'realistic' corruption"


def _fmt(x: float, spec: str) -> str:
    return "   -" if x != x else format(x, spec)


def _part_cell(p) -> str:
    """One :class:`~ancsh.evaluation.PartErrors` as a table cell."""
    return f"{_fmt(p.rot_deg, '8.2f')} {_fmt(p.trans, '.4f')} {_fmt(100 * p.iou, '6.1f')}      "


def _joint_cell(jr) -> str:
    """One :class:`~ancsh.evaluation.JointErrors` as a table cell."""
    unit = "deg" if jr.type == "revolute" else "obj"
    return f"state {_fmt(jr.state_err, '.3f')} {unit} axis {_fmt(jr.axis_deg, '.2f')} line {_fmt(jr.line_dist, '.3f')}"


def _row(label: str, per_method: list, index: int, cell) -> str:
    """One table line: ``cell`` of entry ``index`` for each method (``failed`` when a fit gave no entries)."""
    return f"   {label}" + "".join(f" | {cell(entries[index])}" if entries else f" | {'failed':28s}" for entries in per_method)


def run(args) -> int:
    import numpy as np

    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.procedural import CATEGORIES, PAPER_CATEGORIES
    from ..data.show import draw_fit, save_figure
    from ..evaluation import evaluate_fit
    from ..solvers import Observation, fit
    from ..solvers.formulations import provider_fit_config

    categories = PAPER_CATEGORIES if args.categories == "all" else tuple(c.strip() for c in args.categories.split(","))
    unknown = [c for c in categories if c not in CATEGORIES]
    if unknown:
        raise ValueError(f"categories: unknown {unknown}; known: {', '.join(CATEGORIES)}")
    if args.frame < 0:
        raise ValueError(f"--frame: expected a frame index >= 0, got {args.frame}")
    out = Path(args.out)
    failed = []
    methods = (("NPCS (per part)", "per_part"), ("ANCSH exact", "exact_reduced"))
    for category in categories:
        gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=args.seed))
        frame = gen.frame(args.frame)
        model, _ = gen.instance(frame.instance_index)
        rest = model.rest_states
        limits = np.stack([model.lower_limits - rest, model.upper_limits - rest], axis=1)
        provider, label = _provider(category, args.provider, frame, limits, args.seed)
        obs = Observation(frame.points)
        t0 = time.perf_counter()
        corr = provider.correspond(obs)
        t_corr = time.perf_counter() - t0
        print(f"\n== {category}: held-out instance {frame.instance}, {obs.num_points} points; "
              f"correspondences: {label} ({1e3 * t_corr:.0f} ms)")
        records = {}
        for name, formulation in methods:
            result = fit(obs, corr, formulation, config=provider_fit_config(provider), rng=args.seed)
            records[name] = (result, evaluate_fit(result, frame.gt, frame.part_names, frame.joint_names))
            print(f"   {name:16s} status {result.status.value:8s} {1e3 * result.time_s:6.1f} ms")
        print(f"   {'part':14s}" + "".join(f" | {n:^28s}" for n, _ in methods))
        print(f"   {'':14s}" + " | rot(deg) trans   IoU(%)     " * len(methods))
        for j, part in enumerate(frame.part_names):
            print(_row(f"{part:14s}", [records[n][1].parts for n, _ in methods], j, _part_cell))
        for k, jname in enumerate(frame.joint_names):
            print(_row(f"joint {jname:8s}", [records[n][1].joints for n, _ in methods], k, _joint_cell))
        result = records["ANCSH exact"][0]
        if not result.ok:
            failed.append(f"{category}: {result.status.value} ({result.message})")
        if result.ok:
            fig = draw_fit(frame.points, result, frame.intrinsics, labels=corr.part_labels, gt=frame.gt,
                           title=f"{category} / {frame.instance}: ANCSH exact fit ({label})")
            print(f"   picture: {save_figure(fig, out / f'{category}.png')}")
    print("\nErrors: rotation in degrees, translation and line distance in object units (metres / object size), "
          "IoU of the amodal part boxes; joint state in degrees (revolute) or object units (prismatic).")
    if failed:
        print("ANCSH exact fit failed: " + "; ".join(failed), file=sys.stderr)
        return 1
    return 0
