"""``ancsh bench learned-ablation``: held-out errors of training runs through the full pipeline (a loss ablation).

:func:`ablation` measures every run's checkpoints on the same rendered test frames; :func:`write_ablation_report`
writes ``learned_ablation.md`` / ``.json`` through the shared writer. The arguments are in :mod:`ancsh.cli.bench.learned`."""

from __future__ import annotations

import json
from pathlib import Path

from .report import utc_date, write_text


def ablation(runs: dict, *, frames: int = 300, seed: int = 0, checkpoints=("last.pt", "best.pt"),
             baseline: str | None = None) -> dict:
    """Held-out test errors of training runs (e.g. paper loss vs paper + pose loss) through the full pipeline.

    Parameters
    ----------
    runs : dict of str -> path
        Name -> run directory of ``ancsh train`` (``config.json``, ``history.csv``, checkpoints).
    frames : int
        Rendered test frames (held-out instances, :func:`ancsh.studies.table1.evaluate_category`).
    checkpoints : sequence of str
        Checkpoint files of each run to evaluate (missing ones are skipped).
    baseline : str, optional
        Weights the runs started from, evaluated first on the same frames as a row ``start``: ``"builtin"``
        (the shipped network of the runs' category) or a weights file / checkpoint. Fine-tunes are judged
        against it.

    Returns
    -------
    dict
        ``rows``: the baseline's row first (its training columns ``None``), then per run and checkpoint, its step, the run's training steps and training wall time,
        and means of the ``exact_reduced`` fit's per-part rotation error, joint-axis and joint-state
        errors and of the network's per-part NPCS orientation error (the error budget). ``curves``:
        per run, the pose validation of its history (``step``, ``pose_score`` = mean fitted rotation +
        joint-axis error in degrees on the run's validation instances, ``val_npcs_err``), for an
        equal-step comparison along training.
    """
    import csv

    from ..learned.network.config import TrainConfig
    from ..learned.network.weights import load_network
    from .table1 import evaluate_category, summarize

    rows, curves = [], {}
    if not runs:
        raise ValueError("runs: expected at least one NAME -> run directory")

    def row(name, category, weights, checkpoint, extra):
        ev = evaluate_category(category, frames=frames, methods=("exact_reduced",), weights=weights, seed=seed,
                               progress=False)
        sm = summarize(ev)
        m = sm["methods"]["exact_reduced"]
        rows.append({
            "run": name, **extra, "checkpoint": checkpoint, "category": category,
            "step": load_network(category if weights is None else weights).step,
            "frames": m["frames"], "failures": m["failures"], "rot_deg": m["rot_deg"]["mean"],
            "rot_deg_median": m["rot_deg"]["median"], "axis_deg": m["axis_deg"]["mean"], "state_err": m["state_err"]["mean"],
            "npcs_rot_deg": sm["budget"]["npcs_rot_deg"]["mean"],
        })
        print(json.dumps(rows[-1]), flush=True)

    if baseline is not None:
        category = TrainConfig.from_json(Path(next(iter(runs.values()))) / "config.json").category
        weights = None if baseline == "builtin" else Path(baseline)
        if weights is not None and not weights.is_file():
            raise ValueError(f"baseline: no weights file {weights}")
        row("start", category, weights, "shipped" if weights is None else weights.name,
            {"run_dir": None, "pose_weight": None, "augment_deg": None, "pose_start_step": None, "trained_steps": None,
             "train_wall_min": None})
    for name, run in runs.items():
        run = Path(run)
        config = TrainConfig.from_json(run / "config.json")
        with open(run / "history.csv", newline="") as f:
            hist = list(csv.DictReader(f))
        curves[name] = [{"step": int(float(h["step"])), "pose_score": float(h["pose_score"]),
                         "val_npcs_err": float(h["val_npcs_err"]) if h.get("val_npcs_err") else None}
                        for h in hist if h.get("pose_score")]
        for ck in checkpoints:
            if not (run / ck).is_file():
                continue
            row(name, config.category, run / ck, ck, {
                "run_dir": str(run), "pose_weight": config.pose_weight,
                "augment_deg": [config.augment_roll_deg, config.augment_tilt_deg], "pose_start_step": config.pose_start_step,
                "trained_steps": int(float(hist[-1]["step"])), "train_wall_min": float(hist[-1]["elapsed_s"]) / 60})
    return {"rows": rows, "curves": curves, "frames": frames, "seed": seed, "baseline": baseline}


def write_ablation_report(result: dict, path, *, command: str, commands=()) -> Path:
    """Write :func:`ablation` output as Markdown to ``path`` (JSON beside it); ``commands``: how the runs were made."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    date = utc_date()

    def fmt(v, spec=".2f"):
        return ", ".join("-" if x is None else format(x, spec) for x in v)

    lines = [
        "# Training ablation at equal training time (pose-aware loss, rotation augmentation)",
        "",
        f"Command: `{command}`  ",
        f"Date: {date}; {result['frames']} rendered test frames (held-out instances, seed {result['seed']}) per row, "
        "fit `exact_reduced`; means over frames (failed fits left out and counted).",
        "",
    ]
    if commands:
        lines += ["Training runs:", "", *[f"- `{c}`" for c in commands], ""]
    lines += [
        "| Run | pose weight | augmentation roll / tilt (°) | checkpoint (step) | steps trained | training wall (min) "
        "| rotation error per part (°) | median rotation (°) | joint axis (°) | joint state "
        "| NPCS orientation error per part (°) | failed fits |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    def opt(v, spec="g"):
        return "-" if v is None else format(v, spec)

    for r in result["rows"]:
        a = r.get("augment_deg", (0.0, 0.0))  # None: the baseline row (no training of its own)
        aug = "-" if a is None else f"{a[0]:g} / {a[1]:g}"
        lines.append(
            f"| {r['run']} | {opt(r['pose_weight'])} | {aug} | {r['checkpoint']} ({r['step']}) | {opt(r['trained_steps'])} "
            f"| {opt(r['train_wall_min'], '.1f')} | {fmt(r['rot_deg'])} | {fmt(r['rot_deg_median'])} | {fmt(r['axis_deg'])} "
            f"| {fmt(r['state_err'])} | {fmt(r['npcs_rot_deg'])} | {r['failures']}/{r['frames']} |")
    lines.append("")
    lines += _curve_table(result.get("curves") or {}, {r["run"]: r for r in result["rows"]})
    write_text(path, "\n".join(lines))
    write_text(path.with_suffix(".json"), json.dumps(result, indent=1) + "\n")
    return path


def _curve_table(curves: dict, rows: dict) -> list[str]:
    """Markdown: the runs' pose validation at equal steps (their histories), one column per run."""
    steps = sorted({c["step"] for curve in curves.values() for c in curve})
    if not steps:
        return []
    names = list(curves)

    def label(n):
        r = rows.get(n)
        return n if r is None else f"{n} (pose weight {r['pose_weight']:g} from step {r.get('pose_start_step', 0)})"

    lines = ["## Pose validation along training (equal steps)", "",
             "From each run's history: the pose score (mean fitted rotation + joint-axis error, degrees, `exact_reduced`, "
             "on frames of the run's own *validation* instances, the score that selects `best.pt`) and, in brackets, "
             "the validation NPCS error; runs that share a start share their first rows.", "",
             "| step | " + " | ".join(label(n) for n in names) + " |", "|---|" + "---|" * len(names)]
    for st in steps:
        cells = []
        for n in names:
            c = next((c for c in curves[n] if c["step"] == st), None)
            cells.append("" if c is None else f"{c['pose_score']:.2f}" + (
                "" if c["val_npcs_err"] is None else f" ({c['val_npcs_err']:.3f})"))
        lines.append(f"| {st} | " + " | ".join(cells) + " |")
    return lines + [""]
