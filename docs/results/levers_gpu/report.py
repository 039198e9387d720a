"""Tables of docs/results/levers_gpu.md from the GPU runs' histories and the CPU evaluations.

    python docs/results/levers_gpu/report.py EVAL_ROOT > tables.md

EVAL_ROOT holds one folder ``lev_eval_<run>`` per run: the --out folder of
``ancsh evaluate --category laptop --frames 300 --formulations exact_reduced --weights runs/levers_gpu/<run>_best.pt
--real builtin``. The tables are those of docs/results/capacity_gpu/report.py (whose functions this reuses), with
the paired comparisons against the run without a lever, and a summary of the seed replicates. A call's section is
printed when all of its runs' folders are in EVAL_ROOT (the first two calls' networks are not kept).
"""

import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "capacity_gpu"))

from report import curves, paired, table1  # noqa: E402  (docs/results/capacity_gpu/report.py)

RUNS = ("base", "normals", "roll30", "pose01", "pose1", "all")  # the first call: 5 minutes each, seed 40
REPLICATES = {"base": ("base_s41", "base_s42", "base_s43"), "pose1": ("pose1_s41", "pose1_s42", "pose1_s43")}  # 2.25 min
# the third call: equal CPU time (the normals cost 1.27x per CPU step), 12000 steps of `base`, 9450 of `normals`
LONG = {"base_long": ("base_long_s41", "base_long_s42", "base_long_s43"),
        "normals_long": ("normals_long_s41", "normals_long_s42", "normals_long_s43")}


def seed_summary(root: Path, replicates: dict, prefix="lev_eval", method="exact_reduced") -> list[str]:
    """Per configuration of ``replicates``: each seed's mean part rotation and joint axis, their mean and spread
    (the fits of ``method`` in the folders ``<prefix>_<run>``)."""
    out = ["| configuration | seeds | mean part rotation (°) per seed | mean | std over seeds | joint axis (°) per seed | mean |",
           "|---" * 7 + "|"]
    for config, runs in replicates.items():
        rot, axis = [], []
        for run in runs:
            m = json.loads((root / f"{prefix}_{run}" / "laptop.json").read_text())["summary"]["methods"][method]
            rot.append(float(np.mean(m["rot_deg"]["mean"])))
            axis.append(float(m["axis_deg"]["mean"][0]))
        out.append(f"| {config} | {len(runs)} | {', '.join(f'{v:.2f}' for v in rot)} | {np.mean(rot):.2f} | {np.std(rot, ddof=1):.2f} "
                   f"| {', '.join(f'{v:.2f}' for v in axis)} | {np.mean(axis):.2f} |")
    return out


def present(title: str, dirs) -> bool:
    """Whether every evaluation folder of a section exists; else a line on stderr naming the missing ones (each call's
    networks are evaluated on their own, so a section prints once all of its folders exist)."""
    missing = [d.name for d in dirs if not d.is_dir()]
    if missing:
        print(f"({title}: left out, no evaluation folder {', '.join(missing)} in {dirs[0].parent})", file=sys.stderr)
    return not missing


def against_shipped(title: str, dirs, methods=("exact_reduced", "network")) -> None:
    """A section of first stages beside the shipped one (``dirs[0]``), each fitted alone and followed by the shipped
    refiner (evaluated with ``--refine network``): per fit in ``methods``, the Table 1 rows and the paired comparison
    (``methods=("network",)`` for refiners behind one first stage)."""
    if not present(title, dirs):
        return
    print(f"### {title}\n")
    for method in methods:
        print("\n".join(table1(dirs, method=method)), end="\n\n")
        print("\n".join(paired(dirs, reference="shipped", method=method)), end="\n\n")


if __name__ == "__main__":
    root = Path(sys.argv[1])
    reps = [r for runs in REPLICATES.values() for r in runs]
    longs = [r for runs in LONG.values() for r in runs]
    for title, runs, here, ref, summary in (
            ("levers, 5 minutes each", RUNS, HERE, "base", None),
            ("seed replicates, 2.25 minutes each", reps, HERE / "replicates", reps[0], REPLICATES),
            ("seed replicates at equal CPU time (12000 / 9450 steps)", longs, HERE / "long", longs[0], LONG)):
        dirs = [root / f"lev_eval_{r}" for r in runs]
        if not present(title, dirs):
            continue
        print(f"### {title}\n")
        print("\n".join(curves(runs, here)), end="\n\n")
        print("\n".join(table1(dirs)), end="\n\n")
        print("\n".join(paired(dirs, reference=ref)), end="\n\n")
        if summary:
            print("\n".join(seed_summary(root, summary)), end="\n\n")
    # call 3's networks with the shipped refiner (`ancsh evaluate ... --refine network --weights <run>_best.pt --out
    # EVAL_ROOT/ref_eval_<run>`), beside the shipped first stage (`--refine network --out EVAL_ROOT/lev_eval_shipped`)
    title = "call 3's networks and the shipped first stage, each followed by the shipped refiner"
    dirs = [root / "lev_eval_shipped"] + [root / f"ref_eval_{r}" for r in longs]
    if present(title, dirs):
        print(f"### {title}\n")
        print("\n".join(table1(dirs, method="network")), end="\n\n")
        print("\n".join(paired(dirs, reference="shipped", method="network")), end="\n\n")
        print("\n".join(seed_summary(root, LONG, prefix="ref_eval", method="network")), end="\n\n")
    # the normals laptop fine-tuned on the CPU (`--weights docs/results/levers_gpu/laptop_normals_candidate/laptop.pt
    # --refine network --out EVAL_ROOT/ref_eval_laptop_normals_candidate`) against the shipped first stage
    against_shipped("the normals laptop candidate against the shipped first stage, both with the shipped refiner",
                    [root / "lev_eval_shipped", root / "ref_eval_laptop_normals_candidate"])
    # normals added to the shipped oven (`init_weights` builtin, their weights at zero) against the same fine-tune
    # without them, 50 minutes each (`ancsh export` of each run, then `ancsh evaluate --category oven --frames 300
    # --formulations exact_reduced --refine network --real builtin [--weights <export>] --out EVAL_ROOT/oven_<name>`)
    against_shipped("normals added to the shipped oven against the same fine-tune without them",
                    [root / "oven_shipped", root / "oven_grown", root / "oven_plain"])
    # the oven's normals first stage: from scratch (65 min, `oven_normals_scratch_config.json`) and that network after
    # 75 minutes of pose-aware fine-tune (`oven_normals_ft/config.json`), each exported by `ancsh export` and evaluated
    # as above (`--out EVAL_ROOT/oven_normals`, `EVAL_ROOT/oven_normals_ft`)
    against_shipped("the oven's normals first stage from scratch and after its pose-aware fine-tune",
                    [root / "oven_shipped", root / "oven_normals", root / "oven_normals_ft"])
    # the same for the drawer (2026-12-06): from scratch (`drawer_normals/config.json`, 9450 steps) and fine-tuned
    # (`drawer_normals/ft_config.json`), evaluated as above (`--category drawer ... --out EVAL_ROOT/drawer_<name>`)
    against_shipped("the drawer's normals first stage from scratch and after its pose-aware fine-tune",
                    [root / "drawer_shipped", root / "drawer_normals", root / "drawer_normals_ft"])
    # the same for the washing machine (2026-12-06): from scratch (`wm_normals/config.json`, 9450 steps) and fine-tuned
    # (`wm_normals/ft_config.json`), evaluated as above (`--category washing_machine ... --out EVAL_ROOT/wm_<name>`)
    against_shipped("the washing machine's normals first stage from scratch and after its pose-aware fine-tune",
                    [root / "wm_shipped", root / "wm_normals", root / "wm_normals_ft"])
    # the normals refiners (2026-12-06: `<category>_normals_refiner/config.json`, 15000 steps each; the drawer's and
    # the laptop's from their shipped normals first stages, the oven's and the washing machine's from theirs without
    # normals) against the shipped refiners, both behind the shipped first stage: `ancsh evaluate --category
    # <category> --frames 300 --formulations exact_reduced --refine network --real builtin [--refiner <export, or
    # best.pt where the export chose the shipped file>] --out EVAL_ROOT/<prefix>_<name>`; the oven's and the washing
    # machine's shipped rows are the evaluations of the first-stage sections above
    for category, shipped, normals in (("drawer", "drref_shipped", "drref_normals"),
                                       ("laptop", "ltref_shipped", "ltref_normals"),
                                       ("oven", "oven_shipped", "ovref_normals"),
                                       ("washing machine", "wm_shipped", "wmref_normals")):
        against_shipped(f"the {category}'s normals refiner against the shipped {category} refiner",
                        [root / shipped, root / normals], methods=("network",))
