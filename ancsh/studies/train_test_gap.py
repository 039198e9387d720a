"""``ancsh bench train-test-gap``: the shipped networks on the instances they trained on and on unseen ones.

What limits a network that misses its accuracy target? If it errs as much on new views of its
*training* instances as on the held-out test instances, it has not fitted even the objects it saw
(under-fitting: capacity, input or optimisation limit -- more data of the same kind would not help);
if it errs much less on them, it fits what it saw and fails to generalise (more or more varied data,
augmentation, regularisation would). Both rows are the same pipeline (network once per frame,
``exact_reduced`` fit), the same number of frames and the same frame seed, on the procedural split and,
where the shipped catalog has objects of the category, on the real one.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .report import utc_date, write_text

__all__ = ["gap_rows", "run_gap", "write_gap_report"]


def run_gap(categories, *, frames: int, real_frames: int, seed: int, progress: bool = True) -> list[dict]:
    """Evaluate ``exact_reduced`` on the training and the test instances of each category.

    Returns
    -------
    list of dict
        One ``{"category", "split", "instances", "settings", "summary"}`` per evaluated set (procedural
        test, procedural train, and real test / train where the shipped catalog has objects of both).
    """
    from ..data.catalog import load_catalog
    from .table1 import evaluate_category, summarize

    catalog = load_catalog()
    out = []
    for cat in categories:
        splits = [(None, frames)]
        if real_frames and catalog.instances(cat, "test") and catalog.instances(cat, "train"):
            splits.append(("builtin", real_frames))
        for real, n in splits:
            for instances in ("test", "train"):
                ev = evaluate_category(cat, frames=n, methods=("exact_reduced",), seed=seed, real=real,
                                       instances=instances, progress=progress)
                out.append({"category": cat, "split": ev["settings"]["split"], "instances": instances,
                            "settings": ev["settings"], "summary": summarize(ev)})
    return out


def _means(result: dict, metric: str) -> np.ndarray:
    """Means over frames of one per-part or per-joint metric (NaN where none): ``npcs_*`` of the NPCS error
    budget, the others of the ``exact_reduced`` fit."""
    s = result["summary"]
    src = s["budget"] if metric.startswith("npcs") else s["methods"]["exact_reduced"]
    return np.array([np.nan if v is None else v for v in src[metric]["mean"]], dtype=float)


def _fmt(values, spec: str) -> str:
    return " / ".join("-" if not np.isfinite(v) else format(v, spec) for v in values)


def gap_rows(results: list[dict]) -> list[str]:
    """Markdown rows: per category and split, the training instances, the test instances and their ratio."""
    rows = []
    by_key = {(r["category"], r["split"], r["instances"]): r for r in results}
    for (cat, split, inst), r in by_key.items():
        if inst != "test" or (cat, split, "train") not in by_key:
            continue
        tr = by_key[(cat, split, "train")]
        cells = {}
        for label, res in (("training instances", tr), ("test instances", r)):
            cells[label] = (_means(res, "rot_deg"), _means(res, "npcs_rot_deg"), _means(res, "axis_deg"), res["settings"])
        for label, (rot, npcs, axis, st) in cells.items():
            n_inst = len(st["real_instances"]) if split == "real" else st["test_instances"]
            rows.append(f"| {cat} | {split} | {label} ({n_inst}) | {st['frames']} | {_fmt(rot, '.2f')} | "
                        f"{_fmt(npcs, '.2f')} | {_fmt(axis, '.2f')} |")
        (rot_tr, npcs_tr, axis_tr, _), (rot_te, npcs_te, axis_te, _) = cells.values()
        with np.errstate(divide="ignore", invalid="ignore"):
            rows.append(f"| {cat} | {split} | **test / training** | | {_fmt(rot_te / rot_tr, '.2f')} | "
                        f"{_fmt(npcs_te / npcs_tr, '.2f')} | {_fmt(axis_te / axis_tr, '.2f')} |")
    return rows


def write_gap_report(results: list[dict], path, *, command: str) -> Path:
    """Write the markdown report (and ``.json`` of the summaries beside it)."""
    from .._machine import describe_machine, machine_facts

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    date = utc_date()
    first = results[0]["settings"] if results else {}
    lines = [
        "# The shipped networks on their training instances and on unseen ones",
        "",
        f"Command: `{command}`  ",
        f"Date: {date}  ",
        f"Machine: {describe_machine(machine_facts())}",
        "",
        "Same pipeline on both rows (shipped weights, the network once per frame, `exact_reduced` fit, frame seed "
        f"{first.get('seed', '-')} for both sets -- neither the training data's frames nor the evaluations'): "
        "**training instances** = new views of the objects the network was trained on (about 10 % of them were its "
        "run's validation instances), **test instances** = the held-out ones of every report. Per part (order of "
        "each category's report), means over frames: the fitted rotation error and the NPCS orientation error it "
        "inherits (`npcs_rot_deg` of `ancsh.studies.table1.npcs_error_budget`: the rotation of a similarity from "
        "the predicted onto the true NPCS on the part's true points, which no fit can remove); joint-axis error per "
        "joint. A test / training ratio near 1: the network errs as much on what it trained on -- under-fitted "
        "(capacity, input or optimisation), and more data of the same kind would not lower the error; well above "
        "1: it fits what it saw and generalises poorly (more varied data would).",
        "",
        "| category | split | instances (objects) | frames | ANCSH-exact rotation (°) | NPCS orientation error (°) "
        "| joint axis (°) |",
        "|---|---|---|---|---|---|---|",
        *gap_rows(results),
        "",
    ]
    write_text(path, "\n".join(lines))
    payload = {"command": command, "date": date, "results": [
        {k: r[k] for k in ("category", "split", "instances")} | {
            "frames": r["settings"]["frames"], "weights_sha256": r["settings"]["weights_sha256"],
            "rot_deg": _means(r, "rot_deg").tolist(), "npcs_rot_deg": _means(r, "npcs_rot_deg").tolist(),
            "axis_deg": r["summary"]["methods"]["exact_reduced"]["axis_deg"]["mean"],
            "state_err": r["summary"]["methods"]["exact_reduced"]["state_err"]["mean"]} for r in results]}
    write_text(path.with_suffix(".json"), json.dumps(payload, indent=1, default=float) + "\n")
    return path
