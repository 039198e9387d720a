"""Tables of docs/results/capacity_gpu.md from the GPU run's histories and the CPU evaluations.

    python docs/results/capacity_gpu/report.py EVAL_DIR [EVAL_DIR ...] > tables.md

Each EVAL_DIR is the --out folder of one `ancsh evaluate --category laptop ... --real builtin` (its
laptop.json; the tables serve any category's folders); the label of a row is the weights file's stem (``shipped``
for the shipped network).
"""

import csv
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RUNS = {"w05": "width 0.5, 256/64 centres, 32/32 neighbours, 1 backbone (the shipped layout)",
        "w10ref": "width 1.0, 512/128 centres, 32/64 neighbours (the paper's sampling), 1 backbone",
        "w10ref2": "width 1.0, the paper's sampling, 2 backbones (the paper's layout)"}
STEPS = (2000, 5000, 7000, 10000)


def history(run, here=HERE):
    with open(Path(here) / f"history_{run}.csv") as f:
        return list(csv.DictReader(f))


def curves(runs=tuple(RUNS), here=HERE) -> list[str]:
    """Learning-curve table of the runs whose ``history_<run>.csv`` lie in ``here``."""
    out = ["| run | steps | s / step | " + " | ".join(f"step {s}: NPCS err / axis (°) / val loss" for s in STEPS)
           + " | last: NPCS err / seg acc / assoc acc |", "|---" * (4 + len(STEPS)) + "|"]
    for run in runs:
        rows = history(run, here)
        by_step = {int(r["step"]): r for r in rows}
        last = rows[-1]
        cells = []
        for s in STEPS:
            r = by_step.get(s)
            cells.append("-" if r is None else
                         f"{float(r['val_npcs_err']):.4f} / {float(r['val_axis_err_deg']):.3f} / {float(r['val_total']):.4f}")
        out.append(f"| {run} | {last['step']} | {float(last['elapsed_s']) / int(last['step']):.3f} | " + " | ".join(cells)
                   + f" | {float(last['val_npcs_err']):.4f} / {float(last['val_seg_acc']):.4f} / {float(last['val_assoc_acc']):.4f} |")
    return out


def _shipped_file(path: Path) -> bool:
    """Whether ``path`` lies in the package's weights folder (``ancsh/weights/``)."""
    return path.parent.name == "weights" and path.parent.parent.name == "ancsh"


def network_name(weights: str, category: str = "laptop") -> str:
    """A table's name of an evaluated weights file: ``shipped`` for the shipped ``ancsh/weights/<category>.pt``, else
    the file's stem without ``_best``, or its folder's name where the stem is only the category's (an exported
    candidate)."""
    path = Path(weights)
    if path.stem == category:
        return "shipped" if _shipped_file(path) else path.parent.name
    return path.stem.replace("_best", "")


def load_report(folder) -> dict:
    """The ``ancsh evaluate`` report of an evaluation folder (its one ``<category>.json``)."""
    found = sorted(Path(folder).glob("*.json"))
    if len(found) != 1:
        raise ValueError(f"{folder}: expected one <category>.json of ancsh evaluate, found {[f.name for f in found]}")
    return json.loads(found[0].read_text())


def report_name(rep: dict) -> str:
    """:func:`network_name` of a report's weights; ``+ <refiner>`` where it ran a refiner other than the file shipped
    when it was measured (its file's stem without ``_best``, or its folder's name for a run's ``best.pt`` /
    ``last.pt`` or an exported ``<category>_refine.pt``)."""
    s = rep["settings"]
    name = network_name(s["weights"], s["category"])
    refiner = Path(s.get("refiner") or f"ancsh/weights/{s['category']}_refine.pt")
    if _shipped_file(refiner):
        return name
    by_folder = refiner.stem in ("best", "last", f"{s['category']}_refine")
    return f"{name} + {refiner.parent.name if by_folder else refiner.stem.replace('_best', '')}"


def _pair(values, fmt):
    return ", ".join(format(v, fmt) for v in values)


def table1(dirs, method="exact_reduced") -> list[str]:
    """Table 1 rows of each evaluation folder's ``method`` (``exact_reduced``, or a refinement: ``network``)."""
    out = ["| network | step | procedural: rotation (°) mean | median | translation | joint axis (°) | state (°) "
           "| real split: rotation (°) mean | joint axis (°) | state (°) |", "|---" * 10 + "|"]
    for d in dirs:
        rep = load_report(d)
        s = rep["settings"]
        name = report_name(rep)
        m = rep["summary"]["methods"][method]
        r = rep["real"]["summary"]["methods"][method]
        out.append(f"| {name} | {s['weights_step']} | {_pair(m['rot_deg']['mean'], '.2f')} | {_pair(m['rot_deg']['median'], '.2f')} "
                   f"| {_pair(m['trans']['mean'], '.3f')} | {m['axis_deg']['mean'][0]:.2f} | {m['state_err']['mean'][0]:.2f} "
                   f"| {_pair(r['rot_deg']['mean'], '.2f')} | {r['axis_deg']['mean'][0]:.2f} | {r['state_err']['mean'][0]:.2f} |")
    return out


def paired(dirs, reference="w05", seed=0, draws=2000, method="exact_reduced") -> list[str]:
    """Each network against ``reference`` on the same frames: mean part rotation, share of frames lower, and a 95 %
    interval of the mean difference by resampling the test instances (the errors are per-instance biases); the fits
    of ``method`` (``exact_reduced``, or a refinement: ``network``)."""
    import numpy as np

    reps = {}
    for d in dirs:
        rep = load_report(d)
        reps[report_name(rep)] = rep
    ref = reps[reference]
    inst = np.array(ref["per_frame"]["instance"])
    names = np.unique(inst)
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, len(names), (draws, len(names)))
    out = [f"| network | mean part rotation (°) | minus {reference} | 95 % interval (instances resampled) "
           f"| frames lower than {reference} |", "|---" * 5 + "|"]
    def frame_rotation(rep):  # mean over parts per frame; NaN where the fit failed (no errors recorded)
        return np.array([np.nan if e is None else np.mean(e) for e in rep["per_frame"][method]["rot_deg"]])

    r0 = frame_rotation(ref)
    for name, rep in reps.items():
        if list(rep["per_frame"]["instance"]) != list(inst):
            raise ValueError(f"{name}: not the frames of {reference}")
        r = frame_rotation(rep)
        if np.isnan(r).any() or np.isnan(r0).any():  # compare on the frames both fitted
            keep = ~(np.isnan(r) | np.isnan(r0))
            out_name = f"{name} ({(~keep).sum()} failed fits left out)"
        else:
            keep, out_name = np.ones(len(r), bool), name
        r, r_ref, frame_inst = r[keep], r0[keep], inst[keep]
        diff = r - r_ref
        per_inst = np.array([diff[frame_inst == n].mean() if (frame_inst == n).any() else 0.0 for n in names])
        counts = np.array([(frame_inst == n).sum() for n in names])
        boot = (per_inst[picks] * counts[picks]).sum(axis=1) / counts[picks].sum(axis=1)
        lo, hi = np.percentile(boot, [2.5, 97.5])
        out.append(f"| {out_name} | {r.mean():.2f} | {diff.mean():+.2f} | [{lo:+.2f}, {hi:+.2f}] | {np.mean(diff < 0):.0%} |")
    return out


if __name__ == "__main__":
    print("\n".join(curves()))
    print()
    print("\n".join(table1(sys.argv[1:])))
    print()
    print("\n".join(paired(sys.argv[1:])))
