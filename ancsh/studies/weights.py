"""``ancsh weights``: the report of the shipped networks -- sizes, training, held-out scores, learning curves, pose
validations and, from the evaluation reports, the paper's Table 1 targets and what limits them.

:func:`weights_tables` and :func:`target_tables` build the markdown tables from
:func:`ancsh.learned.network.weights.weights_summary` rows (and a folder of ``ancsh evaluate`` reports, through
:mod:`ancsh.studies.targets`); :func:`write_weights_report` writes them with their explanations through the shared
writer. The command's arguments are in :mod:`ancsh.cli.learned`.
"""

from __future__ import annotations

from pathlib import Path

from .report import Provenance, write_text
from .targets import TRAINING_BUDGET_MIN

__all__ = ["target_tables", "training_settings", "weights_tables", "write_weights_report"]


def _f(v, spec):
    return "-" if v is None or (isinstance(v, float) and v != v) else format(v, spec)


def weights_tables(rows: list[dict]) -> tuple[list[str], list[str], list[str]]:
    """The markdown tables of the shipped networks: ``(weights, learning curves, pose validations)``; ``pose`` holds
    only its header when no run had pose validations."""

    def train_minutes(r):  # "parent + own" for a fine-tuned file
        own = _f(r["train_min"], ".0f")
        return own if not r["parent_min"] else f"{r['parent_min']:.0f} + {own} (fine-tuned from step {r['parent_step']})"

    lines = [
        "| weights | kind | parts | size (MB) | step shipped / trained | training (min) | test frames | seg. acc. "
        "(majority) | NPCS error (all-zero) | assoc. acc. | joint-axis error (°) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| `{r['name']}.pt` | {r['kind']}{' (refiner)' if r.get('refiner') else ''} | {r['parts']} | {r['size_mb']:.1f} | {_f(r['step'], 'd')} / "
            f"{_f(r['trained_steps'], 'd')} | {train_minutes(r)} | {_f(r['test_frames'], 'd')} | "
            f"{_f(r['seg_acc'], '.3f')} ({_f(r['seg_acc_majority'], '.3f')}) | {_f(r['npcs_err'], '.4f')} "
            f"({_f(r['npcs_err_zero'], '.3f')}) | {_f(r['assoc_acc'], '.3f')} | {_f(r['axis_err_deg'], '.2f')} |"
        )
    curves = [
        "| weights | training (min) | validation NPCS error, last | power-law exponent | training time for 2x lower "
        "error | for 5x lower error |",
        "|---|---|---|---|---|---|",
    ]

    def hours(factor, minutes, cap=1000.0):  # beyond cap x the run's time a power law says only "flat"
        if factor == float("inf"):
            return "not reached (flat curve)"
        if factor > cap:
            return f"> {cap * minutes / 60:.0f} h (> {cap:.0f}x: flat curve)"
        return f"{factor * minutes / 60:.0f} h ({factor:.0f}x)"

    for r in rows:
        c = r["curve"]
        if c is not None:
            curves.append(
                f"| `{r['name']}.pt` | {_f(r['train_min'], '.0f')} | {c['fitted_final']:.4f} | {c['exponent']:.2f} | "
                f"{hours(c['time_factor_2x'], r['train_min'])} | {hours(c['time_factor_5x'], r['train_min'])} |"
            )
    pose = [
        "| weights | pose validations (step: rotation + joint axis, °) | best (step) | last / best |",
        "|---|---|---|---|",
    ]
    for r in rows:
        pc = r["pose_curve"]
        if pc:
            best = min(pc, key=lambda p: p["score"])
            history = ", ".join(f"{p['step']}: {p['score']:.1f}" for p in pc)
            pose.append(f"| `{r['name']}.pt` | {history} | "
                        f"{best['score']:.1f} ({best['step']}) | {_f(pc[-1]['score'] / best['score'], '.2f')} |")
    return lines, curves, pose


def target_tables(reports, rows: list[dict]) -> tuple[list[str], list[str]]:
    """The Table 1 targets and their limits (markdown lines) from the ``ancsh evaluate`` reports in ``reports``."""
    from .targets import (budget_projection, collect_targets, limit_lines, refiner_minutes, refiner_roots, roll_gains,
                          target_lines, train_test_ratios, unshipped_minutes)

    reports = Path(reports)
    target_rows, missing = collect_targets(reports)
    ancsh_rows = {r["category"]: r for r in rows if r["kind"] == "ancsh" and not r.get("refiner")}
    refiner_min = refiner_minutes(rows, refiner_roots())
    minutes = {c: (r["train_min"], r["parent_min"], refiner_min.get(c, 0.0)) for c, r in ancsh_rows.items()}
    targets = target_lines(target_rows, missing, minutes)
    gains = roll_gains(reports / "roll_equivariance.json")
    unshipped = unshipped_minutes()
    gaps = train_test_ratios(reports / "train_test_gap.json")
    limits = limit_lines([budget_projection(t, ancsh_rows[t.category], gains.get(t.category, float("nan")),
                                            unshipped.get(t.category, 0.0), gaps.get(t.category, float("nan")),
                                            refiner_min.get(t.category, 0.0))
                          for t in target_rows if t.category in ancsh_rows])
    return targets, limits


def write_weights_report(path, rows: list[dict], tables, targets: list[str], limits: list[str], *, reports,
                         provenance: Provenance) -> Path:
    """``weights.md``: the tables of :func:`weights_tables` / :func:`target_tables` with their explanations."""
    lines, curves, pose = tables
    date, cmd = provenance.date, provenance.command
    text = [
        "# Shipped networks", "",
        f"Generated {date} by `{cmd}`.", "",
        "Held-out scores are those stored in each weights file at export (the test split's instances, never "
        "seen in training), beside trivial baselines in parentheses. NPCS error: mean distance in NPCS units "
        "(unit part diagonal). Joint-axis error: the network's per-point axis votes in NAOCS (direct voting: "
        f"in the camera frame). {training_settings(rows)} Training times are the wall times recorded in each "
        "run's history on the machine that trained it, not measured here. "
        "Each file's config, history (CSV), curves (PNG) and test metrics ship beside it in `ancsh/weights/`.",
        "", *lines, "",
        "## Learning curves: what more training time would buy", "",
        "A power law `err = a·t^b` fitted (least squares in log-log) to the validation NPCS error of the "
        "second half of each run's history (`ancsh.learned.network.weights.learning_curve_fit`), and the training "
        "time it projects for a 2x and a 5x lower error at the same settings and on the same machine. 'last' is the "
        "fit at the end of the run. Extrapolating this far is an order-of-magnitude guide only (curves "
        "usually flatten, so the projections are optimistic). The NPCS error is only a proxy for the pose: "
        "the fitted part rotations follow the network's NPCS *orientation* error (see *Where the rotation "
        "error comes from* in each `docs/results/<category>.md`), which a lower mean NPCS error does not "
        "guarantee (eyeglasses, 50 -> 90 min: NPCS error 0.044 -> 0.040, exact-fit rotation errors up).", "",
        *curves, "",
    ]
    if len(pose) > 2:
        text += [
            "## Pose validation: the quantity users get, during training", "",
            "Runs with a pose validation (`TrainConfig.pose_val_every`) fit every few hundred steps the validation "
            "instances' frames (64, never test instances) through the full pipeline and record the mean fitted "
            "part rotation error plus joint-axis error (`pose_score`, the number `best.pt` minimises). The shipped "
            "file is the best row. Its frame-to-frame noise is about ±1°, so only differences beyond that mean "
            "anything; a last/best ratio near 1 with no trend says that more steps of the same training buy "
            "little.", "",
            *pose, "",
        ]
    if targets:
        text += [
            f"## Table 1 targets: the shipped networks through the full pipeline (reports in `{reports}`)", "",
            "Read back from each category's `ancsh evaluate` report (`ancsh.studies.targets`), not re-measured: "
            "per part, the mean ANCSH-exact (reduced) rotation error on the procedural test split beside the "
            "paper's Table 1 ANCSH row (its CAD datasets, not our instances), the joint-axis error beside the "
            "paper's, and the real test split's rotation error over the procedural one (goal: at most 1.25x per "
            "part), and the same fits refined against the category template where the report has that row "
            "(`ancsh evaluate --refine template`, an option of the learned provider). Training: minutes of one core spent on the shipped network, + those of the network it was "
            "fine-tuned from (+ those of the shipped refinement network's lineage beyond it), against issue 32's budget of "
            f"{TRAINING_BUDGET_MIN / 60:.0f} core-hours ({TRAINING_BUDGET_MIN:.0f} min) per category. A report marked stale evaluated "
            "other weights than the shipped file, or frames of an older generator.", "",
            *targets, "",
            "## What limits the targets: more of the same training within the budget", "",
            "Per category (`ancsh.studies.targets.budget_projection`): the factor by which the worst part's "
            f"rotation error must fall to meet the paper's; the training minutes left of the {TRAINING_BUDGET_MIN:.0f} (the shipped "
            "lineage's, the shipped refiner's and the runs not shipped, `ancsh/weights/unshipped_training.json`); and what a power "
            "law fitted to the shipped run's own history projects at the budget's end, as a multiple of today's "
            "error -- from the validation NPCS error (the learning-curve table above) and from the pose "
            "validations (the quantity judged; exponent >= 0: no longer falling, projected 1.00). The power "
            "laws are extrapolations (optimistic: curves flatten), the NPCS error is only a proxy, and the pose "
            "validations carry about ±1° of noise each. Roll gain: how far the fitted rotation follows a camera "
            "roll (1 = the network reads the orientation from the shape; `roll_equivariance.md` in the reports "
            "folder, shipped weights only; '-' when not measured on them). Rotation, test / training "
            "instances: the mean fitted rotation error on the held-out test instances over that on new views "
            "of the training instances, averaged over parts (`train_test_gap.md` in the reports folder, "
            "`ancsh bench train-test-gap`): near 1, the network errs as much on the objects it trained on -- "
            "under-fitted, and more data of the same kind would not help. A category projected not to reach "
            "its target needs another lever than more steps of the same training.", "",
            *limits, "",
        ]
    return write_text(path, "\n".join(text))


def training_settings(rows: list[dict]) -> str:
    """The training settings stored in the weights files (:func:`~ancsh.learned.network.weights.weights_summary` rows),
    as a sentence: one clause per distinct setting, naming its files when they differ."""
    groups: dict[tuple, list[str]] = {}
    for r in rows:
        groups.setdefault((r["num_threads"], r["batch_size"], r["num_points"]), []).append(f"`{r['name']}.pt`")
    clauses = [f"{t} torch thread(s), steps of batch {b}, {p} points" for t, b, p in groups]
    if len(groups) <= 1:
        return f"Trained (each file's config) with {clauses[0]}." if groups else ""
    return "Trained (each file's config) with " + "; ".join(
        f"{c} ({', '.join(names)})" for c, names in zip(clauses, groups.values())) + "."
