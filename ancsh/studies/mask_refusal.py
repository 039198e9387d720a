"""``ancsh bench mask-refusal``: when may a fit under the user's own mask be refused as not the category?

A mask (or a hint) is the user saying the object is there, so ``ancsh predict`` judges the fit under it by its own
evidence (inliers, size, residual, joint range) and lets ``p_object`` refuse it only below
:data:`ancsh.learned.inference.checks.MIN_P_OBJECT_MASKED` (a segment found without a mask is refused below
:data:`~ancsh.learned.inference.checks.MIN_P_OBJECT`). This study measures what each threshold refuses, on fresh
renders made like the ``p_object`` calibration's (:func:`ancsh.studies.object_evidence.collect_object_evidence`, at a
seed the calibrations were not fitted on): masked, noisy renders of the category's held-out instances (objects; a
refusal is a correct fit refused) against the other categories' held-out instances and clutter of the category's
size under a mask (not objects; a refusal is right). A fit that fails its plausibility checks is refused at every
threshold and counts so on both sides.
"""

from __future__ import annotations

import numpy as np

from ..learned.inference.checks import MIN_P_OBJECT
from .report import Provenance, write_json, write_text

__all__ = ["THRESHOLDS", "measure_mask_refusal", "write_mask_refusal_report"]

#: The ``p_object`` thresholds measured.
THRESHOLDS = (0.5, 0.3, 0.2, 0.1, 0.05, 0.02, 0.01)


def measure_mask_refusal(categories, frames: int = 40, *, seed: int = 29, progress: bool = True) -> dict:
    """Per category: the fits' ``p_object`` (the shipped object calibration) and whether each is the category's object.

    Returns ``{"categories": {name: {"p_object": [...], "is_object": [...], "source": [...], "failed_objects": n,
    "failed_others": n}}, "settings": {...}}``; categories without an object calibration for their shipped weights are
    left out (``"skipped"``).
    """
    import json

    from ..learned.inference.confidence import object_calibration_path, probability_good
    from ..learned.network.weights import load_network, weights_path
    from .object_evidence import collect_object_evidence

    out, skipped = {}, []
    for category in categories:
        path = object_calibration_path(category)
        if not path.is_file() or not weights_path(category).is_file():
            skipped.append(category)
            continue
        calibration = json.loads(path.read_text())
        if calibration.get("weights_sha256") != getattr(load_network(category), "sha256", None):
            skipped.append(category)
            continue
        data = collect_object_evidence(category, frames, seed=seed, progress=progress)
        p = [float(probability_good(calibration, x)) for x in data["X"]]
        failed = data["failed"]
        out[category] = {"p_object": p, "is_object": [bool(v) for v in data["is_object"]], "source": list(data["source"]),
                         "failed_objects": int(failed.get(category, 0)),
                         "failed_others": int(sum(v for k, v in failed.items() if k != category))}
    return {"categories": out, "skipped": skipped, "settings": {"frames": int(frames), "seed": int(seed),
                                                                 "thresholds": list(THRESHOLDS)}}


def refusal_shares(record: dict, threshold: float) -> tuple[float, float]:
    """``(objects refused, others refused)`` at ``threshold``: shares of all fits tried on each side (a fit that
    failed its plausibility checks is refused)."""
    p = np.asarray(record["p_object"], dtype=np.float64)
    y = np.asarray(record["is_object"], dtype=bool)
    n_obj = int(y.sum()) + record["failed_objects"]
    n_other = int((~y).sum()) + record["failed_others"]
    obj = (np.count_nonzero(p[y] < threshold) + record["failed_objects"]) / max(n_obj, 1)
    other = (np.count_nonzero(p[~y] < threshold) + record["failed_others"]) / max(n_other, 1)
    return float(obj), float(other)


def write_mask_refusal_report(results: dict, path, provenance: Provenance, *, chosen: float) -> object:
    """The markdown table (and the JSON of the records beside it) of :func:`measure_mask_refusal`'s results."""
    from pathlib import Path

    path = Path(path)
    cats = results["categories"]
    lines = ["# Refusing a fit under the user's mask: what each `p_object` threshold refuses", "",
             f"Command: `{provenance.command}`  ", f"Date: {provenance.date}; machine: {provenance.machine_text}  ",
             "Study: `ancsh.studies.mask_refusal`", "",
             __doc__.split("\n\n", 1)[1].strip().replace("\n", " "), "",
             f"`ancsh predict` with a mask or hint refuses below **{chosen}** (`MIN_P_OBJECT_MASKED`); without one, "
             f"below {MIN_P_OBJECT} (`MIN_P_OBJECT`, by the calibration's segment model). Cells: share of correct fits "
             "refused / share of other things refused (fits tried: objects, others).", "",
             "| category | fits (objects, others) | " + " | ".join(f"< {t}" for t in THRESHOLDS) + " |",
             "|---|---|" + "---|" * len(THRESHOLDS)]
    pooled = {t: [0.0, 0.0, 0, 0] for t in THRESHOLDS}
    for name, rec in cats.items():
        y = np.asarray(rec["is_object"], dtype=bool)
        n_obj, n_other = int(y.sum()) + rec["failed_objects"], int((~y).sum()) + rec["failed_others"]
        cells = []
        for t in THRESHOLDS:
            a, b = refusal_shares(rec, t)
            cells.append(f"{100 * a:.0f} % / {100 * b:.0f} %")
            pooled[t][0] += a * n_obj
            pooled[t][1] += b * n_other
            pooled[t][2] += n_obj
            pooled[t][3] += n_other
        lines.append(f"| {name} | {n_obj}, {n_other} | " + " | ".join(cells) + " |")
    if cats:
        lines.append("| **all** | " + f"{pooled[THRESHOLDS[0]][2]}, {pooled[THRESHOLDS[0]][3]} | " + " | ".join(
            f"**{100 * v[0] / max(v[2], 1):.0f} % / {100 * v[1] / max(v[3], 1):.0f} %**" for v in pooled.values()) + " |")
    if results.get("skipped"):
        lines += ["", "No object calibration for the shipped weights (not measured): " + ", ".join(results["skipped"])]
    write_text(path, "\n".join(lines) + "\n")
    write_json(path.with_suffix(".json"), {"command": provenance.command, "date": provenance.date,
                                           "machine": provenance.machine, "chosen": chosen, **results}, indent=1)
    return path
